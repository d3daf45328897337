//! Array selection, Algorithm 1 of the paper (ALGORITHMS.md §9).
//!
//! Keep the arrays whose smoothed azimuth variance is under the threshold; with more than
//! three, take as initial set the triple with the largest product of its three distances
//! d_pq·d_ps·d_qs (TDoA is more precise from spread-out arrays), then add the remaining array
//! with the most stable DoA (smallest variance). With exactly three the triple is the set; with
//! fewer, the caller falls back to single elements of two arrays (paper §VI-A).
//!
//! The variance to feed is that around the DoA trend (e.g. the square of
//! [`crate::doa::DoaState::erratic_rad`]), so that a drone moving across an array's view is not
//! taken for an unstable array.

use crate::observation::distance;

/// One array, as Algorithm 1 sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Array id.
    pub id: u16,
    /// Array centre, world m.
    pub position: [f64; 3],
    /// Smoothed azimuth variance, rad².
    pub azimuth_variance_rad2: f64,
}

/// The arrays chosen.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The initial triple (in id order), then the added array, if any.
    pub arrays: Vec<u16>,
    /// The triple's arrays lie (nearly) on one line: the area of their triangle is below
    /// [`COLLINEAR_RATIO`] times its longest side squared. Multilateration from them needs a
    /// prior or single elements (paper §VI-A).
    pub collinear: bool,
}

/// Why no triple could be chosen.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SelectionError {
    /// Fewer than three arrays with a stable DoA; the stable ones, most stable first.
    #[error("only {} arrays with a stable DoA", .0.len())]
    TooFew(Vec<u16>),
}

/// A triangle flatter than this (area / longest side²) counts as collinear.
pub const COLLINEAR_RATIO: f64 = 0.01;

/// Area of the triangle abc divided by its longest side squared.
fn flatness(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    let area = 0.5 * (cross[0].powi(2) + cross[1].powi(2) + cross[2].powi(2)).sqrt();
    let longest = distance(a, b).max(distance(a, c)).max(distance(b, c));
    if longest > 0.0 {
        area / (longest * longest)
    } else {
        0.0
    }
}

/// Algorithm 1 over `candidates` with variance threshold `max_variance_rad2` (rad²). Ties go to
/// the lower ids; non-finite variances count as unstable.
pub fn select_arrays(
    candidates: &[Candidate],
    max_variance_rad2: f64,
) -> Result<Selection, SelectionError> {
    let mut stable: Vec<Candidate> = candidates
        .iter()
        .copied()
        .filter(|c| {
            c.azimuth_variance_rad2.is_finite() && c.azimuth_variance_rad2 < max_variance_rad2
        })
        .collect();
    stable.sort_by_key(|c| c.id);
    if stable.len() < 3 {
        let mut ids = stable.clone();
        ids.sort_by(|a, b| a.azimuth_variance_rad2.total_cmp(&b.azimuth_variance_rad2));
        return Err(SelectionError::TooFew(ids.iter().map(|c| c.id).collect()));
    }
    let n = stable.len();
    let mut best: Option<(f64, [usize; 3])> = None;
    for p in 0..n {
        for q in p + 1..n {
            for s in q + 1..n {
                let (a, b, c) = (stable[p].position, stable[q].position, stable[s].position);
                let product = distance(a, b) * distance(a, c) * distance(b, c);
                if best.is_none_or(|(m, _)| product > m) {
                    best = Some((product, [p, q, s]));
                }
            }
        }
    }
    let (_, triple) = best.expect("three or more candidates");
    let [p, q, s] = triple;
    let collinear =
        flatness(stable[p].position, stable[q].position, stable[s].position) < COLLINEAR_RATIO;
    let mut arrays: Vec<u16> = triple.iter().map(|&i| stable[i].id).collect();
    let added = (0..n).filter(|i| !triple.contains(i)).min_by(|&i, &j| {
        stable[i].azimuth_variance_rad2.total_cmp(&stable[j].azimuth_variance_rad2)
    });
    if let Some(i) = added {
        arrays.push(stable[i].id);
    }
    Ok(Selection { arrays, collinear })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(id: u16, x: f64, y: f64, var_deg: f64) -> Candidate {
        Candidate { id, position: [x, y, 2.0], azimuth_variance_rad2: var_deg.to_radians().powi(2) }
    }

    const THRESHOLD: f64 = 0.0012; // (2°)²

    /// Six arrays on a 20 m × 10 m grid: the unstable corner (array 3) is left out, the widest
    /// triple of the rest is the three remaining corners, the most stable middle array is added.
    #[test]
    fn picks_the_widest_stable_triple_and_the_steadiest_fourth() {
        let arrays = [
            c(1, 0.0, 0.0, 1.0),
            c(2, 10.0, 0.0, 0.5),
            c(3, 21.0, 0.0, 5.0),
            c(4, 0.0, 10.0, 1.5),
            c(5, 10.0, 10.0, 0.8),
            c(6, 20.0, 10.0, 1.0),
        ];
        let s = select_arrays(&arrays, THRESHOLD).unwrap();
        // Triples of {1, 2, 4, 5, 6}: (1, 4, 6) has 10·22.36·20 = 4472, (2, 4, 6)
        // 14.14·14.14·20 = 4000, (1, 2, 6) and (1, 5, 6) 3162, the others less.
        assert_eq!(s.arrays, vec![1, 4, 6, 2]);
        assert!(!s.collinear);
        // With array 3 stable it takes part: (1, 3, 4) has 21·10·23.26 = 4884, (1, 3, 6) 4719,
        // (3, 4, 6) 4675; the steadiest rest is array 2.
        let mut all = arrays;
        all[2].azimuth_variance_rad2 = 0.0;
        assert_eq!(select_arrays(&all, THRESHOLD).unwrap().arrays, vec![1, 3, 4, 2]);
    }

    #[test]
    fn three_are_the_set_and_fewer_are_too_few() {
        let arrays =
            [c(7, 0.0, 0.0, 1.0), c(8, 5.0, 0.0, 0.2), c(9, 0.0, 5.0, 1.9), c(10, 5.0, 5.0, 3.0)];
        let s = select_arrays(&arrays, THRESHOLD).unwrap();
        assert_eq!(s.arrays, vec![7, 8, 9]);
        let e = select_arrays(&arrays[1..], THRESHOLD).unwrap_err();
        assert_eq!(e, SelectionError::TooFew(vec![8, 9]));
        let nan = Candidate { azimuth_variance_rad2: f64::NAN, ..arrays[0] };
        assert_eq!(
            select_arrays(&[nan, arrays[1], arrays[2]], THRESHOLD).unwrap_err(),
            SelectionError::TooFew(vec![8, 9])
        );
    }

    #[test]
    fn arrays_on_a_line_are_flagged() {
        let arrays =
            [c(1, 0.0, 0.0, 1.0), c(2, 4.0, 0.0, 1.0), c(3, 9.0, 0.05, 1.0), c(4, 15.0, 0.0, 1.0)];
        let s = select_arrays(&arrays, THRESHOLD).unwrap();
        assert!(s.collinear, "{s:?}");
        // Widest: 1, 3, 4 (9·15·6 = 810) against 1, 2, 4 (4·15·11 = 660).
        assert_eq!(s.arrays, vec![1, 3, 4, 2]);
    }
}
