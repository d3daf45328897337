//! Sine and cosine as `const fn`, for tables built at compile time (no trigonometry code in
//! the image for them).

/// cos and sin of `x` (rad, |x| ≤ π) in f64 by their Taylor series to x³³: the truncation error
/// is below 10⁻¹⁶ for |x| ≤ π and the rounding error of the sum about 10⁻¹⁵ (the largest term,
/// π⁴/4! ≈ 4, times the f64 epsilon).
pub const fn cos_sin(x: f64) -> (f64, f64) {
    let (mut c, mut s) = (0.0, 0.0);
    let mut term = 1.0; // xⁿ / n!
    let mut n = 0;
    while n < 34 {
        match n % 4 {
            0 => c += term,
            1 => s += term,
            2 => c -= term,
            _ => s -= term,
        }
        n += 1;
        term = term * x / n as f64;
    }
    (c, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_library_within_its_stated_error() {
        for i in -1000..=1000 {
            let x = core::f64::consts::PI * i as f64 / 1000.0;
            let (c, s) = cos_sin(x);
            assert!((c - x.cos()).abs() < 2e-15, "cos {x}");
            assert!((s - x.sin()).abs() < 2e-15, "sin {x}");
        }
    }
}
