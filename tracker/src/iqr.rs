//! The interquartile-range outlier rule (paper §V-B, ALGORITHMS.md §7).
//!
//! Keep the values inside [Q1 − 1.5·IQR, Q3 + 1.5·IQR]; quartiles by linear interpolation
//! between order statistics (the usual "type 7" definition: position (n − 1)·p).

/// The `p` quantile (0 ≤ p ≤ 1) of already sorted values by linear interpolation.
/// Returns NaN for an empty slice.
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = (sorted.len() - 1) as f64 * p.clamp(0.0, 1.0);
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

/// Inclusive bounds [Q1 − k·IQR, Q3 + k·IQR] of the values (k = 1.5 in the paper).
/// Returns `None` for an empty slice or one holding NaN.
pub fn iqr_bounds(values: &[f64], k: f64) -> Option<(f64, f64)> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let q1 = quantile_sorted(&sorted, 0.25);
    let q3 = quantile_sorted(&sorted, 0.75);
    let iqr = q3 - q1;
    Some((q1 - k * iqr, q3 + k * iqr))
}

/// A mask of the values inside the IQR bounds (k = 1.5). All false for invalid input.
pub fn iqr_inliers(values: &[f64]) -> Vec<bool> {
    match iqr_bounds(values, 1.5) {
        Some((lo, hi)) => values.iter().map(|v| *v >= lo && *v <= hi).collect(),
        None => vec![false; values.len()],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_vector() {
        // Sorted: 1 2 3 4 5 6 7 8 9 40 (n = 10).
        // Q1 at position 9·0.25 = 2.25 → 3 + 0.25·(4 − 3) = 3.25.
        // Q3 at position 9·0.75 = 6.75 → 7 + 0.75·(8 − 7) = 7.75.
        // IQR = 4.5; bounds = [3.25 − 6.75, 7.75 + 6.75] = [−3.5, 14.5]: only 40 is out.
        let v = [5.0, 40.0, 1.0, 3.0, 2.0, 4.0, 9.0, 6.0, 8.0, 7.0];
        let (lo, hi) = iqr_bounds(&v, 1.5).unwrap();
        assert!((lo + 3.5).abs() < 1e-12, "{lo}");
        assert!((hi - 14.5).abs() < 1e-12, "{hi}");
        let mask = iqr_inliers(&v);
        assert_eq!(mask, v.iter().map(|&x| x != 40.0).collect::<Vec<_>>());
    }

    #[test]
    fn degenerate_inputs() {
        assert!(iqr_bounds(&[], 1.5).is_none());
        assert!(iqr_bounds(&[1.0, f64::NAN], 1.5).is_none());
        assert_eq!(iqr_bounds(&[2.0], 1.5), Some((2.0, 2.0)));
        assert!(quantile_sorted(&[], 0.5).is_nan());
    }
}
