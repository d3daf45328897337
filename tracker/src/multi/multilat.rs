//! Range-difference multilateration (ALGORITHMS.md §9, paper eqs. 8–9 with the corrected
//! hyperboloid).
//!
//! Each pair of arrays p, q with an inter-array delay T_pq on the common clock gives one range
//! difference |S − A_p| − |S − A_q| = c·T_pq; the source S is the weighted least-squares
//! solution, found by Gauss–Newton (with step halving) from the single-array estimate. Its
//! covariance is (Jᵀ W J + P⁻¹)⁻¹ at the solution (P: the optional prior's covariance).
//!
//! Rank: the differences of n arrays hold at most n − 1 independent equations, so three arrays
//! fix only two directions of S; arrays on one line leave S free to turn about the line. Without
//! a prior such data is refused ([`MultilatError::Degenerate`]); with the single-array estimate
//! as prior the missing direction comes from it, and [`MultilatFix::data_rank`] says so. Pairs
//! that share an array have correlated errors; pass independent pairs (each array against one
//! reference array) or accept that they are treated as independent.

use crate::observation::distance;

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// One range difference: |S − p| − |S − q| = `metres`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeDifference {
    /// Position of array p, world m.
    pub p: [f64; 3],
    /// Position of array q, world m.
    pub q: [f64; 3],
    /// c·T_pq: how much farther S is from p than from q, m.
    pub metres: f64,
    /// Standard deviation of `metres`, m (> 0).
    pub sigma_m: f64,
}

impl RangeDifference {
    /// |s − p| − |s − q| at `s`, m.
    pub fn predicted(&self, s: [f64; 3]) -> f64 {
        distance(s, self.p) - distance(s, self.q)
    }

    /// Gradient of [`RangeDifference::predicted`] at `s` (difference of the two unit vectors).
    fn gradient(&self, s: [f64; 3]) -> Vector3<f64> {
        let unit = |a: [f64; 3]| {
            let v = Vector3::new(s[0] - a[0], s[1] - a[1], s[2] - a[2]);
            v / v.norm().max(1e-9)
        };
        unit(self.p) - unit(self.q)
    }
}

/// A Gaussian prior on the position (the single-array estimate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prior {
    /// Mean, world m.
    pub position: [f64; 3],
    /// Covariance, m² (positive definite).
    pub covariance: Matrix3<f64>,
}

/// Tunables of the solver.
#[derive(Clone, Debug, PartialEq)]
pub struct MultilatConfig {
    /// Most Gauss–Newton iterations.
    pub max_iterations: usize,
    /// Converged when a step is shorter than this, m.
    pub tolerance_m: f64,
    /// Diverged when the estimate moves farther than this from the initial guess, m.
    pub max_distance_m: f64,
    /// An eigenvalue of the data's information below this fraction of the largest counts as
    /// missing (rank).
    pub rank_ratio: f64,
}

impl Default for MultilatConfig {
    fn default() -> Self {
        Self { max_iterations: 30, tolerance_m: 1e-6, max_distance_m: 100.0, rank_ratio: 1e-8 }
    }
}

/// A multilateration fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultilatFix {
    /// Position, world m.
    pub position: [f64; 3],
    /// Covariance of the position, m² ((Jᵀ W J + P⁻¹)⁻¹).
    pub covariance: Matrix3<f64>,
    /// Iterations used.
    pub iterations: usize,
    /// Rms of the range-difference residuals, m.
    pub rms_residual_m: f64,
    /// Directions the range differences alone fix (3 without help; less when a prior fills in).
    pub data_rank: usize,
}

/// Why there is no fix.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum MultilatError {
    /// Fewer pairs than needed, or a non-finite or non-positive input.
    #[error("{0} usable range differences: too few or invalid")]
    TooFewPairs(usize),
    /// The range differences fix only `rank` directions and there is no prior (three arrays,
    /// arrays on one line).
    #[error("degenerate geometry: the range differences fix {rank} of 3 directions")]
    Degenerate {
        /// Directions fixed.
        rank: usize,
    },
    /// The estimate ran away from the initial guess or the cost could not be lowered.
    #[error("Gauss-Newton diverged")]
    Diverged,
    /// Not converged within the iteration cap.
    #[error("Gauss-Newton did not converge in {0} iterations")]
    NotConverged(usize),
}

/// Σ w gᵀg of the range differences at `s` (the data's information), and the cost and gradient
/// side Σ w g·(m − f).
fn normal_equations(pairs: &[RangeDifference], s: [f64; 3]) -> (Matrix3<f64>, Vector3<f64>) {
    let mut h = Matrix3::zeros();
    let mut g = Vector3::zeros();
    for d in pairs {
        let w = 1.0 / (d.sigma_m * d.sigma_m);
        let j = d.gradient(s);
        h += w * j * j.transpose();
        g += w * j * (d.metres - d.predicted(s));
    }
    (h, g)
}

fn cost(
    pairs: &[RangeDifference],
    prior: Option<&(Vector3<f64>, Matrix3<f64>)>,
    s: [f64; 3],
) -> f64 {
    let data: f64 = pairs.iter().map(|d| ((d.metres - d.predicted(s)) / d.sigma_m).powi(2)).sum();
    let prior = prior.map_or(0.0, |(m, info)| {
        let e = Vector3::from(s) - m;
        (e.transpose() * info * e)[0]
    });
    data + prior
}

/// Number of eigenvalues of the symmetric `h` above `ratio` times the largest.
fn rank(h: &Matrix3<f64>, ratio: f64) -> usize {
    let e = SymmetricEigen::new(*h).eigenvalues;
    let max = e.amax();
    if max <= 0.0 {
        return 0;
    }
    e.iter().filter(|&&l| l > ratio * max).count()
}

/// Solves |S − A_p| − |S − A_q| = c·T_pq over `pairs` by Gauss–Newton from `initial` (world m),
/// with an optional `prior`.
pub fn multilaterate(
    pairs: &[RangeDifference],
    initial: [f64; 3],
    prior: Option<&Prior>,
    config: &MultilatConfig,
) -> Result<MultilatFix, MultilatError> {
    let valid = |d: &RangeDifference| {
        d.p.iter().chain(&d.q).all(|v| v.is_finite())
            && d.metres.is_finite()
            && d.sigma_m.is_finite()
            && d.sigma_m > 0.0
    };
    if pairs.is_empty()
        || !pairs.iter().all(valid)
        || !initial.iter().all(|v| v.is_finite())
        || (prior.is_none() && pairs.len() < 3)
    {
        return Err(MultilatError::TooFewPairs(pairs.len()));
    }
    let prior = match prior {
        Some(p) => Some((
            Vector3::from(p.position),
            p.covariance.try_inverse().ok_or(MultilatError::TooFewPairs(pairs.len()))?,
        )),
        None => None,
    };
    let check_rank = |s: [f64; 3]| {
        let r = rank(&normal_equations(pairs, s).0, config.rank_ratio);
        if prior.is_none() && r < 3 {
            Err(MultilatError::Degenerate { rank: r })
        } else {
            Ok(r)
        }
    };
    check_rank(initial)?;
    let mut s = initial;
    let mut c = cost(pairs, prior.as_ref(), s);
    for iteration in 1..=config.max_iterations {
        let (mut h, mut g) = normal_equations(pairs, s);
        if let Some((m, info)) = &prior {
            h += info;
            g += info * (m - Vector3::from(s));
        }
        let step = h.cholesky().ok_or(MultilatError::Diverged)?.solve(&g);
        let mut lambda = 1.0;
        let mut accepted = None;
        for _ in 0..20 {
            let trial: [f64; 3] = (Vector3::from(s) + lambda * step).into();
            let tc = cost(pairs, prior.as_ref(), trial);
            if tc <= c {
                accepted = Some((trial, tc));
                break;
            }
            lambda *= 0.5;
        }
        let moved = lambda * step.norm();
        match accepted {
            Some((trial, tc)) => {
                s = trial;
                c = tc;
            }
            // No lower cost along the step: at the minimum to rounding, or lost.
            None if step.norm() < 1e3 * config.tolerance_m => {}
            None => return Err(MultilatError::Diverged),
        }
        if distance(s, initial) > config.max_distance_m {
            return Err(MultilatError::Diverged);
        }
        if moved < config.tolerance_m || accepted.is_none() {
            let data_rank = check_rank(s)?;
            let (mut h, _) = normal_equations(pairs, s);
            if let Some((_, info)) = &prior {
                h += info;
            }
            let covariance =
                h.try_inverse().ok_or(MultilatError::Degenerate { rank: data_rank })?;
            let ss: f64 = pairs.iter().map(|d| (d.metres - d.predicted(s)).powi(2)).sum();
            return Ok(MultilatFix {
                position: s,
                covariance: crate::linalg::symmetrized(&covariance),
                iterations: iteration,
                rms_residual_m: (ss / pairs.len() as f64).sqrt(),
                data_rank,
            });
        }
    }
    Err(MultilatError::NotConverged(config.max_iterations))
}

/// The hyperboloid of eq. 8 of one pair: in the pair's frame (origin at the midpoint of A_p A_q,
/// x from A_p towards A_q) x²/a² − (y² + z²)/b² = 1 with a = |c·T_pq|/2 and
/// b² = (d/2)² − a² (d = |A_p A_q|; the paper's b = √(½d² − a²) misplaces the half). The sign of
/// T_pq picks the sheet: a source farther from p than from q (T_pq > 0) lies on the sheet x > 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hyperboloid {
    /// Midpoint of the pair, world m.
    pub centre: [f64; 3],
    /// Unit vector from A_p towards A_q (the pair frame's x).
    pub axis: [f64; 3],
    /// Semi-major axis a, m.
    pub a_m: f64,
    /// Semi-minor axis b, m.
    pub b_m: f64,
    /// Sign of the range difference: +1 the sheet towards q, −1 towards p.
    pub sign: f64,
}

impl Hyperboloid {
    /// The hyperboloid of |S − p| − |S − q| = `range_difference_m` (m); `None` if the arrays
    /// coincide, the difference is zero (the surface is the bisecting plane) or not shorter
    /// than the baseline (no surface).
    pub fn new(p: [f64; 3], q: [f64; 3], range_difference_m: f64) -> Option<Self> {
        let d = distance(p, q);
        let a = range_difference_m.abs() / 2.0;
        if !(d > 0.0 && a > 0.0 && a < d / 2.0) {
            return None;
        }
        Some(Self {
            centre: [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0],
            axis: [(q[0] - p[0]) / d, (q[1] - p[1]) / d, (q[2] - p[2]) / d],
            a_m: a,
            b_m: ((d / 2.0).powi(2) - a * a).sqrt(),
            sign: range_difference_m.signum(),
        })
    }

    /// `point` (world m) in the pair frame: x along the axis, and the distance ρ = √(y² + z²)
    /// from it (the surface is symmetric about the axis), m.
    pub fn pair_frame(&self, point: [f64; 3]) -> (f64, f64) {
        let v = [point[0] - self.centre[0], point[1] - self.centre[1], point[2] - self.centre[2]];
        let x = v[0] * self.axis[0] + v[1] * self.axis[1] + v[2] * self.axis[2];
        let rho2 = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - x * x).max(0.0);
        (x, rho2.sqrt())
    }

    /// F of eq. 8 at `point` (world m): x²/a² − (y² + z²)/b² − 1 (zero on the surface).
    pub fn value(&self, point: [f64; 3]) -> f64 {
        let (x, rho) = self.pair_frame(point);
        x * x / (self.a_m * self.a_m) - rho * rho / (self.b_m * self.b_m) - 1.0
    }

    /// Whether `point` lies on the half-space of this difference's sheet.
    pub fn on_sheet(&self, point: [f64; 3]) -> bool {
        self.pair_frame(point).0 * self.sign > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    /// Five arrays at several heights around a 10 m room.
    const ARRAYS: [[f64; 3]; 5] =
        [[0.0, 0.0, 0.3], [10.0, 0.0, 2.5], [10.0, 10.0, 0.4], [0.0, 10.0, 2.8], [5.0, 5.0, 3.0]];
    const SOURCE: [f64; 3] = [3.2, 6.1, 1.7];

    /// Each array against array 0 (independent pairs), with noise `sigma` (m).
    fn pairs(source: [f64; 3], sigma: f64, rng: &mut Rng) -> Vec<RangeDifference> {
        (1..ARRAYS.len())
            .map(|k| {
                let (p, q) = (ARRAYS[k], ARRAYS[0]);
                let metres = distance(source, p) - distance(source, q) + sigma * rng.normal();
                RangeDifference { p, q, metres, sigma_m: sigma }
            })
            .collect()
    }

    #[test]
    fn noiseless_differences_give_the_source_on_every_hyperboloid() {
        let mut rng = Rng::new(1);
        let d = pairs(SOURCE, 0.0, &mut rng)
            .into_iter()
            .map(|d| RangeDifference { sigma_m: 0.01, ..d })
            .collect::<Vec<_>>();
        let fix = multilaterate(&d, [5.0, 5.0, 1.0], None, &MultilatConfig::default()).unwrap();
        assert!(distance(fix.position, SOURCE) < 1e-6, "{fix:?}");
        assert_eq!(fix.data_rank, 3);
        // Eq. 8: the solution lies on every pair's hyperboloid, on the sheet of its sign
        // (also for the pairs not used in the solve).
        for (p, &ap) in ARRAYS.iter().enumerate() {
            for (q, &aq) in ARRAYS.iter().enumerate() {
                if p == q {
                    continue;
                }
                let rd = distance(SOURCE, ap) - distance(SOURCE, aq);
                let h = Hyperboloid::new(ap, aq, rd).unwrap();
                assert!(h.value(fix.position).abs() < 1e-5, "{p}{q}: {}", h.value(fix.position));
                assert!(h.on_sheet(fix.position), "{p}{q}");
                // The mirror sheet is also F = 0, but on the other side: the sign matters.
                let (x, rho) = h.pair_frame(fix.position);
                let mirror = [
                    h.centre[0] - 2.0 * x * h.axis[0] + (fix.position[0] - h.centre[0]),
                    h.centre[1] - 2.0 * x * h.axis[1] + (fix.position[1] - h.centre[1]),
                    h.centre[2] - 2.0 * x * h.axis[2] + (fix.position[2] - h.centre[2]),
                ];
                assert!(h.value(mirror).abs() < 1e-5 && !h.on_sheet(mirror), "{rho}");
                let flipped = distance(mirror, ap) - distance(mirror, aq);
                assert!((flipped + rd).abs() < 1e-9);
            }
        }
        // The paper's b = √(½d² − a²) would not hold the source.
        let (p, q) = (ARRAYS[1], ARRAYS[2]);
        let rd = distance(SOURCE, p) - distance(SOURCE, q);
        let h = Hyperboloid::new(p, q, rd).unwrap();
        let d2 = distance(p, q).powi(2);
        let paper = Hyperboloid { b_m: (0.5 * d2 - h.a_m * h.a_m).sqrt(), ..h };
        assert!(paper.value(SOURCE).abs() > 0.1, "{}", paper.value(SOURCE));
        assert!(Hyperboloid::new(p, q, 0.0).is_none() && Hyperboloid::new(p, q, 20.0).is_none());
    }

    /// 4000 noisy solves (σ = 2 cm): the scatter's covariance matches the predicted one and the
    /// mean squared Mahalanobis distance is 3 (χ² with 3 degrees of freedom).
    #[test]
    fn scatter_matches_the_covariance() {
        let mut rng = Rng::new(7);
        let n = 4000;
        let mut errors = Vec::with_capacity(n);
        let mut predicted = Matrix3::zeros();
        let mut mahalanobis = 0.0;
        for _ in 0..n {
            let d = pairs(SOURCE, 0.02, &mut rng);
            let fix = multilaterate(&d, [4.0, 5.0, 1.0], None, &MultilatConfig::default()).unwrap();
            let e = Vector3::from(fix.position) - Vector3::from(SOURCE);
            mahalanobis += (e.transpose() * fix.covariance.try_inverse().unwrap() * e)[0];
            predicted += fix.covariance;
            errors.push(e);
        }
        predicted /= n as f64;
        let mean = errors.iter().sum::<Vector3<f64>>() / n as f64;
        let scatter =
            errors.iter().map(|e| (e - mean) * (e - mean).transpose()).sum::<Matrix3<f64>>()
                / (n - 1) as f64;
        for i in 0..3 {
            let ratio = scatter[(i, i)] / predicted[(i, i)];
            assert!((0.9..1.1).contains(&ratio), "axis {i}: {ratio}");
            assert!(mean[i].abs() < 4.0 * (predicted[(i, i)] / n as f64).sqrt(), "bias {mean}");
        }
        let m = mahalanobis / n as f64;
        assert!((m - 3.0).abs() < 0.2, "{m}");
    }

    /// Arrays on one line leave the source free to turn about it: refused without a prior;
    /// with the single-array estimate as prior the fix is that of the prior along the missing
    /// direction and the data's rank says 2. Three arrays (two independent differences) likewise.
    #[test]
    fn degenerate_geometry_is_reported() {
        let line = [[0.0, 0.0, 1.0], [4.0, 0.0, 1.0], [7.0, 0.0, 1.0], [10.0, 0.0, 1.0]];
        let source = [5.5, 3.0, 1.8];
        let d: Vec<RangeDifference> = (1..4)
            .map(|k| RangeDifference {
                p: line[k],
                q: line[0],
                metres: distance(source, line[k]) - distance(source, line[0]),
                sigma_m: 0.01,
            })
            .collect();
        let config = MultilatConfig::default();
        let initial = [5.0, 2.5, 1.5];
        assert_eq!(
            multilaterate(&d, initial, None, &config),
            Err(MultilatError::Degenerate { rank: 2 })
        );
        let prior = Prior { position: [5.6, 3.1, 1.8], covariance: Matrix3::identity() * 0.25 };
        let fix = multilaterate(&d, initial, Some(&prior), &config).unwrap();
        assert_eq!(fix.data_rank, 2);
        // On the circle about the line through the source: the range differences hold.
        for r in &d {
            assert!((r.predicted(fix.position) - r.metres).abs() < 1e-3);
        }
        // Three arrays: rank 2 as well.
        let mut rng = Rng::new(2);
        let three: Vec<RangeDifference> = pairs(SOURCE, 0.0, &mut rng)
            .into_iter()
            .take(2)
            .map(|d| RangeDifference { sigma_m: 0.01, ..d })
            .collect();
        assert_eq!(
            multilaterate(&three, SOURCE, None, &config),
            Err(MultilatError::TooFewPairs(2))
        );
        let mut dup = three.clone();
        dup.push(RangeDifference {
            p: ARRAYS[1],
            q: ARRAYS[2],
            metres: distance(SOURCE, ARRAYS[1]) - distance(SOURCE, ARRAYS[2]),
            sigma_m: 0.01,
        });
        assert_eq!(
            multilaterate(&dup, [4.0, 5.0, 1.0], None, &config),
            Err(MultilatError::Degenerate { rank: 2 })
        );
    }

    /// A source far outside the arrays (range differences of a point 190 m away) drives the
    /// estimate past `max_distance_m`: reported, not returned; so is the iteration cap; invalid
    /// input is refused.
    #[test]
    fn divergence_and_invalid_input_are_reported() {
        let mut rng = Rng::new(4);
        let d = pairs([150.0, 120.0, 2.0], 0.0, &mut rng)
            .into_iter()
            .map(|d| RangeDifference { sigma_m: 0.01, ..d })
            .collect::<Vec<_>>();
        let config = MultilatConfig::default();
        let r = multilaterate(&d, [5.0, 5.0, 1.5], None, &config);
        assert!(
            matches!(r, Err(MultilatError::Diverged | MultilatError::NotConverged(_))),
            "{r:?}"
        );
        let near = pairs(SOURCE, 0.0, &mut rng)
            .into_iter()
            .map(|d| RangeDifference { sigma_m: 0.01, ..d })
            .collect::<Vec<_>>();
        let one = MultilatConfig { max_iterations: 1, ..MultilatConfig::default() };
        assert_eq!(
            multilaterate(&near, [8.0, 2.0, 2.5], None, &one),
            Err(MultilatError::NotConverged(1))
        );
        let nan = RangeDifference { metres: f64::NAN, ..near[0] };
        assert_eq!(
            multilaterate(&[nan, near[1], near[2]], SOURCE, None, &config),
            Err(MultilatError::TooFewPairs(3))
        );
    }
}
