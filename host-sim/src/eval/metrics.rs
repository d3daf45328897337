//! The track against the truth: position error, availability and motion-class accuracy.

use aim_tracker::motion::MotionClass;
use aim_tracker::observation::wrap_pi;
use aim_tracker::tracker::Fix;

use crate::truth::Truth;

/// Speed from which the truth counts as moving, m/s.
pub const MOVING_MPS: f64 = 0.2;
/// Yaw rate from which the truth counts as yawing, rad/s.
pub const YAWING_RAD_S: f64 = 0.2;
/// Time the tracker may take after its first frame before fixes are due, s.
pub const WARM_UP_S: f64 = 0.25;
/// χ² of three degrees of freedom at 95 %: a fix's error lies inside its own 95 % ellipsoid
/// when `eᵀ C⁻¹ e` is at most this (C its position covariance).
pub const CHI2_3DOF_95: f64 = 7.814_727_903_251_178;
/// Error bound of a *good* fix, m: [`Summary::good_availability`] counts the due output
/// instants whose fix is within it (the NLoS target is 2.0 m).
pub const GOOD_FIX_M: f64 = 2.0;

/// Truth position, velocity and yaw rate at time `t` (linear interpolation), or `None`
/// outside the truth's time span.
pub fn truth_at(truth: &Truth, t: f64) -> Option<([f64; 3], [f64; 3], f64)> {
    let rows = &truth.rows;
    let i = rows.partition_point(|r| r.t_s <= t);
    if i == 0 || i >= rows.len() {
        return None;
    }
    let (a, b) = (&rows[i - 1], &rows[i]);
    let dt = b.t_s - a.t_s;
    let w = if dt > 0.0 { (t - a.t_s) / dt } else { 0.0 };
    let lerp = |x: [f64; 3], y: [f64; 3]| {
        [x[0] + w * (y[0] - x[0]), x[1] + w * (y[1] - x[1]), x[2] + w * (y[2] - x[2])]
    };
    let yaw_rate = if dt > 0.0 { wrap_pi(b.yaw_rad - a.yaw_rad) / dt } else { 0.0 };
    Some((lerp(a.position, b.position), lerp(a.velocity, b.velocity), yaw_rate))
}

/// The motion class of the truth at time `t`.
pub fn truth_class(truth: &Truth, t: f64) -> Option<MotionClass> {
    truth_at(truth, t).map(|(_, v, w)| MotionClass::of_kinematics(v, w, MOVING_MPS, YAWING_RAD_S))
}

/// Error statistics of one track.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Mean 3-D position error, m.
    pub mean_m: f64,
    /// Median error, m.
    pub median_m: f64,
    /// 90th percentile of the error, m.
    pub p90_m: f64,
    /// Fraction of due output instants that have a fix.
    pub availability: f64,
    /// Fraction of due output instants that have a fix within [`GOOD_FIX_M`] of the truth.
    pub good_availability: f64,
    /// Mean error against where the drone is when the fix becomes available (its `available`
    /// time, the reorder and span latency included): what a live user sees, m.
    pub live_mean_m: f64,
    /// Fixes compared with the truth.
    pub fixes: usize,
    /// Output instants due.
    pub due: usize,
    /// Fraction of fixes whose motion class equals the truth's.
    pub motion_accuracy: f64,
    /// Fraction of fixes whose LoS flag equals the truth's (None without LoS truth).
    pub los_accuracy: Option<f64>,
    /// Fraction of fixes whose error lies inside the fix's own 95 % ellipsoid
    /// (`eᵀ C⁻¹ e ≤` [`CHI2_3DOF_95`]): 0.95 when the reported covariance is honest, less
    /// when it is overconfident. A singular covariance counts as outside.
    pub coverage_95: f64,
    /// The motion-class confusion counts: `class_counts[truth][reported]` fixes, classes in
    /// [`CLASSES`] order (hover, yaw, horizontal, vertical).
    pub class_counts: [[usize; 4]; 4],
}

/// The motion classes in the order of [`Summary::class_counts`].
pub const CLASSES: [MotionClass; 4] =
    [MotionClass::Hover, MotionClass::Yaw, MotionClass::Horizontal, MotionClass::Vertical];

/// Index of a class in [`CLASSES`].
pub fn class_index(c: MotionClass) -> usize {
    match c {
        MotionClass::Hover => 0,
        MotionClass::Yaw => 1,
        MotionClass::Horizontal => 2,
        MotionClass::Vertical => 3,
    }
}

impl Summary {
    /// Of the fixes at instants whose true class is `truth`, the fraction that name it
    /// (`None` when no fix falls in that class).
    pub fn class_recall(&self, truth: MotionClass) -> Option<f64> {
        recall(&self.class_counts, truth)
    }
}

/// The recall of one true class from confusion counts (`None` without fixes in that class).
pub fn recall(counts: &[[usize; 4]; 4], truth: MotionClass) -> Option<f64> {
    let i = class_index(truth);
    let n: usize = counts[i].iter().sum();
    (n > 0).then(|| counts[i][i] as f64 / n as f64)
}

/// The normalised estimation error squared `eᵀ C⁻¹ e` (dimensionless), or `None` when `c`
/// is singular or not finite.
pub fn nees(e: [f64; 3], c: &[[f64; 3]; 3]) -> Option<f64> {
    let m = nalgebra::Matrix3::from_fn(|i, j| c[i][j]);
    let v = nalgebra::Vector3::from(e);
    let x = m.cholesky()?.solve(&v);
    let q = v.dot(&x);
    q.is_finite().then_some(q)
}

/// The `p` quantile of sorted values (linear interpolation).
fn quantile(sorted: &[f64], p: f64) -> f64 {
    aim_tracker::iqr::quantile_sorted(sorted, p)
}

/// Compares fixes with the truth. Output instants are due every `period_s` from `WARM_UP_S`
/// after `first_input_t` to `last_input_t` (both s, on the tracked array's clock, as the fixes'
/// times are); `array_index` picks that array's clock (to find the truth at true time) and its
/// LoS column.
pub fn evaluate(
    fixes: &[Fix],
    truth: &Truth,
    period_s: f64,
    first_input_t: f64,
    last_input_t: f64,
    array_index: usize,
) -> Summary {
    let start = first_input_t + WARM_UP_S;
    let first_k = (start / period_s - 1e-9).ceil() as i64;
    let last_k = (last_input_t / period_s + 1e-9).floor() as i64;
    let due = (last_k - first_k + 1).max(0) as usize;
    let mut errors = Vec::new();
    let mut live_errors = Vec::new();
    let mut class_counts = [[0usize; 4]; 4];
    let mut los_right = 0;
    let mut los_known = 0;
    let mut counted = 0;
    let mut covered = 0;
    for f in fixes.iter().filter(|f| f.t >= start - 1e-9 && f.t <= last_input_t + 1e-9) {
        let t = truth.true_time(array_index, f.t);
        let Some((p, v, w)) = truth_at(truth, t) else { continue };
        counted += 1;
        let distance = |q: [f64; 3]| {
            ((f.position[0] - q[0]).powi(2)
                + (f.position[1] - q[1]).powi(2)
                + (f.position[2] - q[2]).powi(2))
            .sqrt()
        };
        errors.push(distance(p));
        let e = [f.position[0] - p[0], f.position[1] - p[1], f.position[2] - p[2]];
        if nees(e, &f.covariance).is_some_and(|q| q <= CHI2_3DOF_95) {
            covered += 1;
        }
        // Past the truth's end the drone has landed where the truth ends.
        let live_t = truth.true_time(array_index, f.available);
        let live = truth_at(truth, live_t)
            .map_or_else(|| truth.rows.last().map_or(p, |r| r.position), |(q, _, _)| q);
        live_errors.push(distance(live));
        let truth_class = MotionClass::of_kinematics(v, w, MOVING_MPS, YAWING_RAD_S);
        class_counts[class_index(truth_class)][class_index(f.motion)] += 1;
        let i = truth.rows.partition_point(|r| r.t_s <= t).min(truth.rows.len().saturating_sub(1));
        if let Some(&los) = truth.rows.get(i).and_then(|r| r.los.get(array_index)) {
            los_known += 1;
            if los == f.los {
                los_right += 1;
            }
        }
    }
    let good = errors.iter().filter(|&&e| e <= GOOD_FIX_M).count();
    errors.sort_by(f64::total_cmp);
    let n = errors.len().max(1) as f64;
    Summary {
        mean_m: errors.iter().sum::<f64>() / n,
        median_m: quantile(&errors, 0.5),
        p90_m: quantile(&errors, 0.9),
        availability: if due > 0 { counted.min(due) as f64 / due as f64 } else { 0.0 },
        good_availability: if due > 0 { good.min(due) as f64 / due as f64 } else { 0.0 },
        live_mean_m: live_errors.iter().sum::<f64>() / n,
        fixes: counted,
        due,
        motion_accuracy: (0..4).map(|i| class_counts[i][i]).sum::<usize>() as f64 / n,
        los_accuracy: (los_known > 0).then(|| los_right as f64 / los_known as f64),
        coverage_95: covered as f64 / n,
        class_counts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::TruthRow;

    fn row(t: f64, x: f64, vx: f64) -> TruthRow {
        TruthRow {
            t_s: t,
            position: [x, 0.0, 2.0],
            velocity: [vx, 0.0, 0.0],
            acceleration: [0.0; 3],
            yaw_rad: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            rotor_hz: vec![],
            los: vec![true],
        }
    }

    #[test]
    fn errors_availability_and_classes() {
        // Truth: 1 m/s along x for 2 s.
        let truth = Truth {
            blades: 2,
            array_ids: vec![1],
            clocks: vec![],
            airframe: None,
            rows: (0..=200).map(|k| row(k as f64 * 0.01, k as f64 * 0.01, 1.0)).collect(),
        };
        // Fixes every 0.1 s from 0.3 s to 1.9 s, each 0.5 m off in y, one missing (1.0 s),
        // available 0.3 s after the instant they describe (the drone is 0.3 m further on by
        // then), the last three 3 m off in y with σ_y 2 m (inside their 95 % ellipsoid: 9 / 4
        // ≤ 7.81), the others 0.5 m off with σ 0.1 m (outside: 25).
        let fixes: Vec<Fix> = (3..=19)
            .filter(|&k| k != 10)
            .map(|k| {
                let t = k as f64 * 0.1;
                Fix {
                    t,
                    available: t + 0.3,
                    position: [t, if k >= 17 { 3.0 } else { 0.5 }, 2.0],
                    velocity: [1.0, 0.0, 0.0],
                    sigma: [0.1, if k >= 17 { 2.0 } else { 0.1 }, 0.1],
                    covariance: [
                        [0.01, 0.0, 0.0],
                        [0.0, if k >= 17 { 4.0 } else { 0.01 }, 0.0],
                        [0.0, 0.0, 0.01],
                    ],
                    resets: 0,
                    motion: if k < 6 { MotionClass::Hover } else { MotionClass::Horizontal },
                    los: true,
                    drone: None,
                    heard: true,
                }
            })
            .collect();
        let s = evaluate(&fixes, &truth, 0.1, 0.0, 1.9, 0);
        assert_eq!(s.due, 17); // 0.3 … 1.9 s
        assert_eq!(s.fixes, 16);
        assert!((s.availability - 16.0 / 17.0).abs() < 1e-12);
        assert!((s.mean_m - (13.0 * 0.5 + 3.0 * 3.0) / 16.0).abs() < 1e-9);
        assert!((s.median_m - 0.5).abs() < 1e-9);
        // 13 of 17 due instants have a fix within 2 m.
        assert!((s.good_availability - 13.0 / 17.0).abs() < 1e-12);
        // Live: 0.3 m behind along x besides the y offset; the last fix's available time
        // (2.2 s) is past the truth (2.0 s), where the drone stays at x = 2.0.
        let live = |t: f64, y: f64| ((t - (t + 0.3).min(2.0)).powi(2) + y * y).sqrt();
        let expected: f64 = (3..=19)
            .filter(|&k| k != 10)
            .map(|k| live(k as f64 * 0.1, if k >= 17 { 3.0 } else { 0.5 }))
            .sum::<f64>()
            / 16.0;
        assert!((s.live_mean_m - expected).abs() < 1e-9, "{} vs {expected}", s.live_mean_m);
        assert!((s.motion_accuracy - 13.0 / 16.0).abs() < 1e-12, "{}", s.motion_accuracy);
        // The truth moves throughout: 13 fixes say horizontal, the first 3 hover.
        let mut counts = [[0; 4]; 4];
        counts[2] = [3, 0, 13, 0];
        assert_eq!(s.class_counts, counts);
        assert_eq!(s.class_recall(MotionClass::Horizontal), Some(13.0 / 16.0));
        assert_eq!(s.class_recall(MotionClass::Hover), None);
        assert_eq!(s.los_accuracy, Some(1.0));
        assert!((s.coverage_95 - 3.0 / 16.0).abs() < 1e-12, "{}", s.coverage_95);
    }

    /// `eᵀ C⁻¹ e` against a hand inversion: C = [[2, 1, 0], [1, 2, 0], [0, 0, 4]] has
    /// C⁻¹ = [[2/3, −1/3, 0], [−1/3, 2/3, 0], [0, 0, 1/4]]; e = (1, 0, 2) gives 2/3 + 1 = 5/3.
    /// A singular covariance has none.
    #[test]
    fn nees_against_a_hand_inversion() {
        let c = [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 4.0]];
        let q = nees([1.0, 0.0, 2.0], &c).unwrap();
        assert!((q - 5.0 / 3.0).abs() < 1e-12, "{q}");
        assert_eq!(
            nees([1.0, 0.0, 0.0], &[[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
            None
        );
    }
}
