//! One extended Kalman filter on [x y z vx vy vz b d] (world ENU, m and m/s; b the zenith bias of
//! the array's DoA, rad; d the log of the drone's emitted BPF against a reference, the nuisance
//! of the Doppler cue, see [`crate::doppler`]), white-acceleration process noise, Joseph-form
//! updates that keep the covariance symmetric positive definite.
//!
//! The bias state exists because a planar array's zenith near grazing incidence is biased by
//! coherent reflections of the tonal rotor sound (the ceiling and wall images pull |u_xy|
//! inwards): the error is not white but a slowly varying offset of several degrees. Modelled as
//! a first-order Gauss–Markov process it lets zenith *changes* inform the track while the
//! absolute zenith only counts within the bias's spread.

use nalgebra::{Const, DimMin, SMatrix, SVector};

use crate::linalg::{diagonal, symmetrized};
use crate::observation::{angles_of, wrap_pi};
use crate::site::ArrayPose;

/// Length of the state vector.
pub const STATE: usize = 9;

/// Index of the zenith bias in the state.
pub const ZENITH_BIAS: usize = 6;

/// Index of the log emitted BPF, ln(f_rest / f_ref), in the state.
pub const LN_REST: usize = 7;

/// Index of the wake-split gain in the state: the relative front/rear BPF split of cruise per
/// m/s of horizontal airspeed (dimensionless per m/s), learned online ([`Ekf::update_wake_split`]).
pub const WAKE_GAIN: usize = 8;

/// A covariance of the state, 9×9.
pub type StateCov = SMatrix<f64, STATE, STATE>;

/// State and covariance of one constant-velocity EKF.
#[derive(Clone, Debug)]
pub struct Ekf {
    /// State [x y z vx vy vz b d k]: position m, velocity m/s, zenith bias rad, log emitted BPF
    /// against the reference (dimensionless), wake-split gain (per m/s).
    pub x: [f64; STATE],
    /// Covariance, 9×9.
    pub p: StateCov,
}

/// Which components of an innovation are angles (wrapped to (−π, π]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Residual {
    /// Plain differences.
    Linear,
    /// The first component is an azimuth.
    AzimuthFirst,
}

impl Ekf {
    /// A filter at `x` with covariance `p`.
    pub fn new(x: [f64; STATE], p: StateCov) -> Self {
        Self { x, p }
    }

    /// Position.
    pub fn position(&self) -> [f64; 3] {
        [self.x[0], self.x[1], self.x[2]]
    }

    /// Velocity.
    pub fn velocity(&self) -> [f64; 3] {
        [self.x[3], self.x[4], self.x[5]]
    }

    /// Constant-velocity prediction over `dt` seconds with white-acceleration spectral
    /// densities `q` (per axis, m²/s³); the zenith bias relaxes towards zero with time constant
    /// `bias_tau_s` (s) and stationary standard deviation `bias_sigma` (rad).
    pub fn predict(&mut self, dt: f64, q: [f64; 3], bias_tau_s: f64, bias_sigma: f64) {
        if dt <= 0.0 {
            return;
        }
        let mut f = StateCov::identity();
        for i in 0..3 {
            f[(i, i + 3)] = dt;
            self.x[i] += dt * self.x[i + 3];
        }
        let decay = (-dt / bias_tau_s.max(1e-3)).exp();
        f[(ZENITH_BIAS, ZENITH_BIAS)] = decay;
        self.x[ZENITH_BIAS] *= decay;
        let mut qm = StateCov::zeros();
        qm[(ZENITH_BIAS, ZENITH_BIAS)] = bias_sigma * bias_sigma * (1.0 - decay * decay);
        for (i, qi) in q.iter().enumerate() {
            qm[(i, i)] = qi * dt.powi(3) / 3.0;
            qm[(i, i + 3)] = qi * dt.powi(2) / 2.0;
            qm[(i + 3, i)] = qi * dt.powi(2) / 2.0;
            qm[(i + 3, i + 3)] = qi * dt;
        }
        self.p = symmetrized(&(f * self.p * f.transpose() + qm));
    }

    /// Lets the emitted BPF wander: adds `variance` to the variance of its log (a random walk;
    /// the controller changes the rotor speeds with thrust and wake).
    pub fn diffuse_rest(&mut self, variance: f64) {
        if variance.is_finite() && variance > 0.0 {
            self.p[(LN_REST, LN_REST)] += variance;
        }
    }

    /// Doppler update: a BPF heard at `ln_ratio` = ln(f_obs / f_ref) with standard deviation
    /// `sigma`, from a source at the state's position and velocity, the sound travelling at
    /// `speed_of_sound` m/s to the array's centre ([`crate::doppler::observed_ln_ratio`]).
    /// Skipped (None) with the drone on the array.
    pub fn update_doppler(
        &mut self,
        array: &ArrayPose,
        ln_ratio: f64,
        sigma: f64,
        speed_of_sound: f64,
    ) -> Option<f64> {
        let rel = [
            self.x[0] - array.position[0],
            self.x[1] - array.position[1],
            self.x[2] - array.position[2],
        ];
        let r = crate::observation::norm(rel);
        if !(r > 0.1 && ln_ratio.is_finite() && sigma > 0.0) {
            return None;
        }
        let u = [rel[0] / r, rel[1] / r, rel[2] / r];
        let v = self.velocity();
        let w = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let predicted = crate::doppler::observed_ln_ratio(self.x[LN_REST], rel, v, speed_of_sound)?;
        // ∂/∂w of −ln(1 + w/c) is −1/(c + w); w = v·u, ∂w/∂v = u, ∂w/∂p = (v − w u)/r.
        let dw = -1.0 / (speed_of_sound + w);
        let mut h = SMatrix::<f64, 1, STATE>::zeros();
        for i in 0..3 {
            h[(0, i)] = dw * (v[i] - w * u[i]) / r;
            h[(0, 3 + i)] = dw * u[i];
        }
        h[(0, LN_REST)] = 1.0;
        let r_noise = diagonal([sigma * sigma]);
        self.update(&[ln_ratio], &[predicted], &h, &r_noise, Residual::Linear)
    }

    /// Update with measurement `z`, prediction `hx`, Jacobian `h` (M×9) and noise `r` (M×M).
    /// Returns the log-likelihood of the innovation, or `None` (no update) if the innovation
    /// covariance is singular.
    pub fn update<const M: usize>(
        &mut self,
        z: &[f64; M],
        hx: &[f64; M],
        h: &SMatrix<f64, M, STATE>,
        r: &SMatrix<f64, M, M>,
        kind: Residual,
    ) -> Option<f64>
    where
        Const<M>: DimMin<Const<M>, Output = Const<M>>,
    {
        let (maha, det) = self.innovate(z, hx, h, r, kind, f64::INFINITY)?;
        Some(-0.5 * (maha + det.ln() + M as f64 * (std::f64::consts::TAU).ln()))
    }

    /// [`Self::update`] unless the innovation's Mahalanobis distance is beyond `gate` (then
    /// the state stays); returns the squared distance and the determinant of the innovation
    /// covariance, or `None` (no update) if that is singular.
    fn innovate<const M: usize>(
        &mut self,
        z: &[f64; M],
        hx: &[f64; M],
        h: &SMatrix<f64, M, STATE>,
        r: &SMatrix<f64, M, M>,
        kind: Residual,
        gate: f64,
    ) -> Option<(f64, f64)>
    where
        Const<M>: DimMin<Const<M>, Output = Const<M>>,
    {
        let mut y = SVector::<f64, M>::from_fn(|i, _| z[i] - hx[i]);
        if kind == Residual::AzimuthFirst {
            y[0] = wrap_pi(y[0]);
        }
        let pht = self.p * h.transpose();
        let s = symmetrized(&(h * pht + r));
        let s_inv = s.try_inverse()?;
        let det = s.determinant();
        if det <= 0.0 {
            return None;
        }
        let maha = (y.transpose() * s_inv * y)[(0, 0)];
        if maha > gate * gate {
            return Some((maha, det));
        }
        let k = pht * s_inv;
        let dx = k * y;
        for i in 0..STATE {
            self.x[i] += dx[i];
        }
        let i_kh = StateCov::identity() - k * h;
        self.p = symmetrized(&(i_kh * self.p * i_kh.transpose() + k * r * k.transpose()));
        Some((maha, det))
    }

    /// The predicted bearing (azimuth, zenith without the bias, rad, array frame) and its
    /// Jacobian with respect to the position (central differences, 2×3).
    fn predicted_bearing(&self, array: &ArrayPose) -> ((f64, f64), [[f64; 3]; 2]) {
        self.predicted_bearing_at(array, self.position())
    }

    /// [`Self::predicted_bearing`] of the position `pos` (the state's, or where it was).
    fn predicted_bearing_at(
        &self,
        array: &ArrayPose,
        pos: [f64; 3],
    ) -> ((f64, f64), [[f64; 3]; 2]) {
        let angles = |pos: [f64; 3]| {
            let rel = [
                pos[0] - array.position[0],
                pos[1] - array.position[1],
                pos[2] - array.position[2],
            ];
            angles_of(array.to_array(rel))
        };
        let range = crate::observation::norm([
            pos[0] - array.position[0],
            pos[1] - array.position[1],
            pos[2] - array.position[2],
        ]);
        let eps = 1e-4 * (1.0 + range);
        let mut jacobian = [[0.0; 3]; 2];
        for i in 0..3 {
            let mut plus = pos;
            let mut minus = pos;
            plus[i] += eps;
            minus[i] -= eps;
            let (ap, zp) = angles(plus);
            let (am, zm) = angles(minus);
            jacobian[0][i] = wrap_pi(ap - am) / (2.0 * eps);
            jacobian[1][i] = (zp - zm) / (2.0 * eps);
        }
        (angles(pos), jacobian)
    }

    /// Bearing update: measured azimuth and zenith (rad, array frame) with standard deviations
    /// of their white parts; the measured zenith is the true one plus the bias state.
    pub fn update_bearing(
        &mut self,
        array: &ArrayPose,
        azimuth: f64,
        zenith: f64,
        sigma_az: f64,
        sigma_zen: f64,
    ) -> Option<f64> {
        let (hx, h, r) = self.bearing_model(array, 0.0, (sigma_az, sigma_zen));
        self.update(&[azimuth, zenith], &hx, &h, &r, Residual::AzimuthFirst)
    }

    /// The bearing of `array` as the state predicts it `lag_s` before its time (from
    /// `x − v·lag_s`; the measured zenith is the true one plus the bias state): the prediction
    /// (azimuth, zenith, rad), its Jacobian and the noise of standard deviations `sigma`
    /// (azimuth, zenith, rad).
    fn bearing_model(
        &self,
        array: &ArrayPose,
        lag_s: f64,
        (sigma_az, sigma_zen): (f64, f64),
    ) -> ([f64; 2], SMatrix<f64, 2, STATE>, SMatrix<f64, 2, 2>) {
        let (p, v) = (self.position(), self.velocity());
        let then = if lag_s == 0.0 { p } else { [0, 1, 2].map(|i| p[i] - v[i] * lag_s) };
        let ((az0, zen0), jacobian) = self.predicted_bearing_at(array, then);
        let mut h = SMatrix::<f64, 2, STATE>::zeros();
        for i in 0..3 {
            h[(0, i)] = jacobian[0][i];
            h[(1, i)] = jacobian[1][i];
            if lag_s != 0.0 {
                h[(0, 3 + i)] = -lag_s * jacobian[0][i];
                h[(1, 3 + i)] = -lag_s * jacobian[1][i];
            }
        }
        h[(1, ZENITH_BIAS)] = 1.0;
        let r = diagonal([sigma_az * sigma_az, sigma_zen * sigma_zen]);
        ([az0, zen0 + self.x[ZENITH_BIAS]], h, r)
    }

    /// Bearing update from another array than the tracked one (rad, that array's frame),
    /// measured `lag_s` before the state's time: predicted from where the constant-velocity
    /// state was then, `x − v·lag_s`. The zenith bias state is shared by every array (all
    /// hear the same ceiling; the arrays' different distances tell the bias from the height).
    /// Returns the bearing's log-likelihood under a Gaussian with outliers: with probability
    /// `outlier` a bearing is a reflection or another source, uniform in the angles, so
    /// one far off costs every hypothesis the same and a diffuse hypothesis gains nothing.
    /// A bearing whose Mahalanobis distance is beyond `gate` updates nothing; None (no update)
    /// if the innovation covariance is singular.
    pub fn update_bearing_other(
        &mut self,
        array: &ArrayPose,
        (azimuth, zenith): (f64, f64),
        sigma: (f64, f64),
        lag_s: f64,
        (gate, outlier): (f64, f64),
    ) -> Option<f64> {
        let (hx, h, r) = self.bearing_model(array, lag_s, sigma);
        let z = [azimuth, zenith];
        let (maha, det) = self.innovate(&z, &hx, &h, &r, Residual::AzimuthFirst, gate)?;
        // Density of the bearing in (azimuth, zenith): Gaussian with probability 1 − ε, else
        // uniform over the angles a planar array reports (2π of azimuth × π/2 of zenith).
        let outlier = outlier.clamp(1e-9, 1.0);
        let gaussian = (-0.5 * maha).exp() / (std::f64::consts::TAU * det.sqrt());
        let uniform = 1.0 / (std::f64::consts::PI * std::f64::consts::PI);
        Some(((1.0 - outlier) * gaussian + outlier * uniform).ln())
    }

    /// Range-difference update from an inter-array delay (ALGORITHMS.md §9, eq. 9): the
    /// drone was `range_difference_m` (m) farther from microphone point `p` than from `q`
    /// (world m), ± `sigma_m`, `lag_s` before the state's time (predicted from
    /// `x − v·lag_s`). Returns the log-likelihood under a Gaussian with outliers (probability
    /// `outlier` that the delay is a wrong correlation peak, uniform over ±`span_m`, the
    /// prior window it was searched in); a delay beyond a Mahalanobis distance `gate` and more
    /// than `gate_floor_m` (m) from the prediction updates nothing; None if the innovation
    /// covariance is singular.
    #[allow(clippy::too_many_arguments)]
    pub fn update_range_difference(
        &mut self,
        p: [f64; 3],
        q: [f64; 3],
        range_difference_m: f64,
        sigma_m: f64,
        lag_s: f64,
        (gate, outlier, span_m, gate_floor_m): (f64, f64, f64, f64),
    ) -> Option<f64> {
        let (x, v) = (self.position(), self.velocity());
        let then = [0, 1, 2].map(|i| x[i] - v[i] * lag_s);
        let dp = [then[0] - p[0], then[1] - p[1], then[2] - p[2]];
        let dq = [then[0] - q[0], then[1] - q[1], then[2] - q[2]];
        let (rp, rq) = (crate::observation::norm(dp), crate::observation::norm(dq));
        if rp < 1e-6 || rq < 1e-6 {
            return None;
        }
        let mut h = SMatrix::<f64, 1, STATE>::zeros();
        for i in 0..3 {
            let g = dp[i] / rp - dq[i] / rq;
            h[(0, i)] = g;
            h[(0, 3 + i)] = -lag_s * g;
        }
        let r = diagonal([sigma_m * sigma_m]);
        // The gate is at least `gate_floor_m` wide, whatever the filter believes.
        let s = (h * self.p * h.transpose())[(0, 0)] + sigma_m * sigma_m;
        let gate = gate.max(gate_floor_m / s.max(1e-12).sqrt());
        let (maha, det) =
            self.innovate(&[range_difference_m], &[rp - rq], &h, &r, Residual::Linear, gate)?;
        let outlier = outlier.clamp(1e-9, 1.0);
        let gaussian = (-0.5 * maha).exp() / (std::f64::consts::TAU * det).sqrt();
        let uniform = 1.0 / (2.0 * span_m.max(1e-3));
        Some(((1.0 - outlier) * gaussian + outlier * uniform).ln())
    }

    /// Azimuth-only update (rad, array frame, standard deviation `sigma`).
    pub fn update_azimuth(&mut self, array: &ArrayPose, azimuth: f64, sigma: f64) -> Option<f64> {
        let ((az0, _), jacobian) = self.predicted_bearing(array);
        let mut h = SMatrix::<f64, 1, STATE>::zeros();
        for i in 0..3 {
            h[(0, i)] = jacobian[0][i];
        }
        let r = diagonal([sigma * sigma]);
        self.update(&[azimuth], &[az0], &h, &r, Residual::AzimuthFirst)
    }

    /// Horizontal speed update |v_xy| = `speed` ± `sigma`; skipped (None) while the predicted
    /// speed is too small for a direction.
    pub fn update_horizontal_speed(&mut self, speed: f64, sigma: f64) -> Option<f64> {
        let s = self.x[3].hypot(self.x[4]);
        if s < 0.05 {
            return None;
        }
        let mut h = SMatrix::<f64, 1, STATE>::zeros();
        h[(0, 3)] = self.x[3] / s;
        h[(0, 4)] = self.x[4] / s;
        self.update(&[speed], &[s], &h, &diagonal([sigma * sigma]), Residual::Linear)
    }

    /// Wake-split update: the change of the relative front/rear BPF split against hover,
    /// `split` ± `sigma` (dimensionless), predicted as k·|v_xy| with k the state's wake gain
    /// ([`WAKE_GAIN`]). Speed and gain are learned together: the split fixes their product,
    /// the bearings' rate speed over range, the Doppler (and earlier legs, through k) the scale.
    /// Skipped (None) while the predicted speed is too small for a direction.
    pub fn update_wake_split(&mut self, split: f64, sigma: f64) -> Option<f64> {
        let s = self.x[3].hypot(self.x[4]);
        if s < 0.05 || !(split.is_finite() && sigma > 0.0) {
            return None;
        }
        let k = self.x[WAKE_GAIN];
        let mut h = SMatrix::<f64, 1, STATE>::zeros();
        h[(0, 3)] = k * self.x[3] / s;
        h[(0, 4)] = k * self.x[4] / s;
        h[(0, WAKE_GAIN)] = s;
        let ll = self.update(&[split], &[k * s], &h, &diagonal([sigma * sigma]), Residual::Linear);
        // The gain is a positive physical constant: a linearised step may not cross zero.
        self.x[WAKE_GAIN] = self.x[WAKE_GAIN].max(1e-4);
        ll
    }

    /// Linear update of selected velocity components towards `values` ± `sigma`.
    pub fn update_velocity<const M: usize>(
        &mut self,
        axes: &[usize; M],
        values: &[f64; M],
        sigma: f64,
    ) -> Option<f64>
    where
        Const<M>: DimMin<Const<M>, Output = Const<M>>,
    {
        let mut h = SMatrix::<f64, M, STATE>::zeros();
        let mut hx = [0.0; M];
        for (row, &axis) in axes.iter().enumerate() {
            h[(row, 3 + axis)] = 1.0;
            hx[row] = self.x[3 + axis];
        }
        let r = SMatrix::<f64, M, M>::identity() * (sigma * sigma);
        self.update(values, &hx, &h, &r, Residual::Linear)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::linalg::asymmetry;

    fn assert_spd(p: &StateCov) {
        assert!(asymmetry(p) < 1e-12, "asymmetric: {}", asymmetry(p));
        assert!(p.cholesky().is_some(), "not positive definite: {p:?}");
    }

    #[test]
    fn covariance_stays_symmetric_positive_definite() {
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.3, 0.0, 0.0);
        let mut f = Ekf::new(
            [5.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01],
            diagonal([4.0, 4.0, 1.0, 1.0, 1.0, 1.0, 1e-3, 1e-2, 1e-4]),
        );
        let mut rng = crate::testutil::Rng::new(11);
        for k in 0..300 {
            f.predict(0.1, [0.5, 0.5, 0.05], 20.0, 0.05);
            let t = k as f64 * 0.1;
            let truth = [6.0 + 1.5 * (0.2 * t).cos(), 1.0 + 1.5 * (0.2 * t).sin(), 2.0];
            let (az, zen) = angles_of(array.to_array(truth));
            f.update_bearing(
                &array,
                az + 0.01 * rng.normal(),
                zen + 0.01 * rng.normal(),
                0.01,
                0.01,
            );
            f.update_horizontal_speed(0.3, 0.05);
            if k % 7 == 0 {
                f.update_velocity(&[2], &[0.0], 0.1);
            }
            assert_spd(&f.p);
        }
        // Bearings alone leave range poorly known: its variance stays the largest.
        let d = f.position();
        let u = [
            d[0] / crate::observation::norm(d),
            d[1] / crate::observation::norm(d),
            d[2] / crate::observation::norm(d),
        ];
        let mut along = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                along += u[i] * f.p[(i, j)] * u[j];
            }
        }
        let across = f.p[(2, 2)].min(along);
        assert!(along >= across);
    }

    #[test]
    fn a_constant_zenith_offset_goes_into_the_bias_state() {
        // The position is known tightly; every zenith reads 3° high: the offset must end up in
        // the bias state, not move the position.
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let truth = [8.0, 3.0, 2.0];
        let mut f = Ekf::new(
            [truth[0], truth[1], truth[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.01],
            diagonal([1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 0.1f64.powi(2), 1e-4, 1e-4]),
        );
        let (az, zen) = angles_of(truth);
        let offset = 3.0f64.to_radians();
        for _ in 0..200 {
            f.predict(0.1, [1e-6; 3], 20.0, 0.1);
            f.update_bearing(&array, az, zen + offset, 0.01, 0.01).unwrap();
        }
        let b = f.x[ZENITH_BIAS];
        assert!((b - offset).abs() < 0.2f64.to_radians(), "bias {}°", b.to_degrees());
        let moved =
            crate::observation::norm([f.x[0] - truth[0], f.x[1] - truth[1], f.x[2] - truth[2]]);
        assert!(moved < 0.05, "position moved {moved} m");
    }

    #[test]
    fn azimuth_update_leaves_the_range_alone() {
        // An azimuth says nothing about range: after the update the position moves across
        // the ray, its distance from the array almost unchanged.
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let mut f = Ekf::new(
            [6.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01],
            diagonal([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-4]),
        );
        let range = |f: &Ekf| f.x[0].hypot(f.x[1]);
        let before = range(&f);
        let az = 10.0f64.to_radians();
        f.update_azimuth(&array, az, 0.01).unwrap();
        let after_az = f.x[1].atan2(f.x[0]);
        assert!((after_az - az).abs() < 0.5f64.to_radians(), "{}", after_az.to_degrees());
        assert!((range(&f) - before).abs() < 0.1, "{before} → {}", range(&f));
    }

    /// Another array's bearing heard `lag` ago is predicted from where the state was then
    /// (oracle: the exact bearing of `x − v·lag` leaves the state where it is, the same
    /// bearing taken as current pulls it), and one far off the prediction updates nothing and
    /// scores the outlier floor.
    #[test]
    fn another_arrays_bearing_is_predicted_where_the_drone_was_and_gated() {
        let array = ArrayPose::new(2, [10.0, 0.0, 0.0], 0.3, 0.0, 0.0);
        let start = [5.0, 4.0, 2.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.01];
        let p = diagonal([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-6, 1e-6, 1e-6]);
        let lag = 0.4;
        let then = [5.0 - 1.5 * lag, 4.0, 2.0];
        let rel = [then[0] - 10.0, then[1], then[2]];
        let (az, zen) = angles_of(array.to_array(rel));
        let sigma = (0.02, 0.02);
        let mut f = Ekf::new(start, p);
        let ll = f.update_bearing_other(&array, (az, zen), sigma, lag, (4.0, 0.05)).unwrap();
        let moved = |f: &Ekf| (0..3).map(|i| (f.x[i] - start[i]).powi(2)).sum::<f64>().sqrt();
        assert!(moved(&f) < 1e-6, "moved {} m", moved(&f));
        let mut g = Ekf::new(start, p);
        g.update_bearing_other(&array, (az, zen), sigma, 0.0, (4.0, 0.05)).unwrap();
        assert!(moved(&g) > 0.1, "moved {} m", moved(&g));
        // 1.2 rad off: gated, nothing moves, scored at the outlier floor (below the exact one).
        let mut h = Ekf::new(start, p);
        let gated =
            h.update_bearing_other(&array, (az + 1.2, zen), sigma, lag, (4.0, 0.05)).unwrap();
        assert_eq!(h.x, start);
        // Its likelihood is the outlier floor, ln(ε / π²), whatever the hypothesis.
        let floor = (0.05 / (std::f64::consts::PI * std::f64::consts::PI)).ln();
        assert!((gated - floor).abs() < 1e-6 && gated < ll, "{gated} against {ll}, floor {floor}");
    }

    /// A range difference measured where the drone was `lag` ago: exact there, no move; the
    /// same read as now moves the state onto the hyperboloid; one far off is gated at the
    /// outlier floor.
    #[test]
    fn a_range_difference_is_predicted_where_the_drone_was_and_gated() {
        let (p, q) = ([0.0, 0.0, 0.0], [10.0, 0.0, 0.5]);
        let start = [5.0, 4.0, 2.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.01];
        let cov = diagonal([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-6, 1e-6, 1e-6]);
        let lag = 0.4;
        let rd = |x: [f64; 3]| {
            let d = |a: [f64; 3]| (0..3).map(|i| (x[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            d(p) - d(q)
        };
        let z = rd([5.0 - 1.5 * lag, 4.0, 2.0]);
        let gate = (4.0, 0.05, 0.5, 0.0);
        let moved = |f: &Ekf| (0..3).map(|i| (f.x[i] - start[i]).powi(2)).sum::<f64>().sqrt();
        let mut f = Ekf::new(start, cov);
        let ll = f.update_range_difference(p, q, z, 0.01, lag, gate).unwrap();
        assert!(moved(&f) < 1e-6, "moved {} m", moved(&f));
        let mut g = Ekf::new(start, cov);
        g.update_range_difference(p, q, z, 0.01, 0.0, gate).unwrap();
        let now = [g.x[0], g.x[1], g.x[2]];
        assert!(moved(&g) > 0.3 && (rd(now) - z).abs() < 0.02, "{} m off", rd(now) - z);
        let mut h = Ekf::new(start, cov);
        let gated = h.update_range_difference(p, q, z + 8.0, 0.01, lag, gate).unwrap();
        assert_eq!(h.x, start);
        // (the Gaussian 5σ out adds a few parts in a million)
        let floor = (0.05 / (2.0 * 0.5f64)).ln();
        assert!((gated - floor).abs() < 1e-4 && gated < ll, "{gated} against {ll}, floor {floor}");
    }

    #[test]
    fn a_range_difference_within_the_gate_floor_updates_an_overconfident_state() {
        // The state believes itself to 1 cm; the range difference says it is 0.2 m off
        // (20σ). A Mahalanobis gate alone refuses it; a 0.3 m floor lets it pull the state.
        // Oracle: the generating range difference.
        let (p, q) = ([10.0, 0.0, 3.0], [0.0, 0.0, 3.0]);
        let start = [4.0, 2.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01];
        let cov = diagonal([1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]);
        let d =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
        let rd = |x: [f64; 3]| d(x, p) - d(x, q);
        let z = rd([start[0], start[1], start[2]]) + 0.2;
        let mut f = Ekf::new(start, cov);
        f.update_range_difference(p, q, z, 0.01, 0.0, (4.0, 0.05, 1.2, 0.0)).unwrap();
        assert_eq!(f.x, start);
        let mut g = Ekf::new(start, cov);
        g.update_range_difference(p, q, z, 0.01, 0.0, (4.0, 0.05, 1.2, 0.3)).unwrap();
        let now = [g.x[0], g.x[1], g.x[2]];
        // The linear Kalman step: the range difference moves by hPhᵀ/(hPhᵀ + r) of the
        // innovation, h = u_p − u_q (unit vectors from the arrays), P = 1e-4 I, r = 1e-4.
        let x0 = [start[0], start[1], start[2]];
        let unit = |a: [f64; 3]| {
            let n = d(x0, a);
            [(x0[0] - a[0]) / n, (x0[1] - a[1]) / n, (x0[2] - a[2]) / n]
        };
        let h: Vec<f64> = (0..3).map(|i| unit(p)[i] - unit(q)[i]).collect();
        let hph = 1e-4 * h.iter().map(|v| v * v).sum::<f64>();
        let expected = rd(x0) + 0.2 * hph / (hph + 1e-4);
        assert!((rd(now) - expected).abs() < 0.01, "{} against {expected}", rd(now));
        assert!(rd(now) - rd(x0) > 0.05, "moved {} m", rd(now) - rd(x0));
    }

    #[test]
    fn bearing_update_moves_towards_the_ray() {
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let mut f = Ekf::new(
            [5.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01],
            diagonal([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1e-6, 1e-6, 1e-6]),
        );
        let truth = [5.0, 1.0, 2.0];
        let (az, zen) = angles_of(truth);
        let before = wrap_pi(angles_of(f.position()).0 - az).abs();
        let ll = f.update_bearing(&array, az, zen, 0.01, 0.01).unwrap();
        let after = wrap_pi(angles_of(f.position()).0 - az).abs();
        assert!(after < 0.1 * before, "{before} → {after}");
        assert!(ll.is_finite());
    }

    #[test]
    fn the_wake_gain_is_learned_from_splits_where_the_speed_is_known() {
        // The speed is pinned (a 1.5 m/s leg along x, speed updates as the bearings' rate
        // would give at a known range); the splits read 0.7 %/(m/s)·1.5 m/s with 0.4 % noise
        // per frame: the gain state, started at 0.01 ± 0.01, must end within 5 % of 0.007.
        let mut f = Ekf::new(
            [5.0, 0.0, 2.0, 1.5, 0.0, 0.0, 0.0, 0.0, 0.01],
            diagonal([0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 1e-6, 1e-6, 1e-4]),
        );
        let mut rng = crate::testutil::Rng::new(3);
        for _ in 0..400 {
            f.predict(0.1, [1e-4; 3], 20.0, 1e-3);
            f.update_velocity(&[0, 1], &[1.5, 0.0], 0.02).unwrap();
            f.update_wake_split(0.007 * 1.5 + 0.004 * rng.normal(), 0.004).unwrap();
            assert_spd(&f.p);
        }
        assert!((f.x[WAKE_GAIN] - 0.007).abs() < 0.05 * 0.007, "gain {}", f.x[WAKE_GAIN]);
        // And the other way round: with the gain known, a split reads the speed.
        let mut g = Ekf::new(
            [5.0, 0.0, 2.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.007],
            diagonal([0.01, 0.01, 0.01, 1.0, 0.01, 0.01, 1e-6, 1e-6, 1e-10]),
        );
        for _ in 0..50 {
            g.update_wake_split(0.007 * 1.5, 0.001).unwrap();
        }
        assert!((g.x[3] - 1.5).abs() < 0.05, "speed {}", g.x[3]);
    }
}
