//! The Doppler range cue: the BPF lines of a moving drone are heard shifted by its radial
//! speed, and with bearings that fixes the range scale of a single array.
//!
//! A source moving with velocity v, seen from the array along the unit vector u (array →
//! drone), is heard at f_obs = f_rest · c / (c + v·u): ln f_obs = ln f_rest − ln(1 + v·u/c).
//! At 1.5 m/s that is 0.44 % (1.4 Hz of a 328 Hz BPF). The emitted BPF is not known (hover
//! level, imbalance, thrust and wake in flight), so it is a state of the filter
//! ([`crate::filter::ekf::LN_REST`], a random walk): frequency–bearing target motion
//! analysis. What fixes the scale is the *change* of the radial speed along a leg: for
//! constant velocity d(v·u)/dt = |v_⊥|²/r while the bearing rate is |v_⊥|/r, so
//! r = (d(v·u)/dt) / (bearing rate)², with no knowledge of the carrier.
//!
//! Per BPF frame, one frequency goes to the filter: the *centre* of the frame's rotor groups
//! (after the hover pattern has taken out the static imbalance, [`crate::wake::HoverPattern`]).
//! The wake of cruise spins the rear rotors ≈ 1 % faster than the front ones, more than the
//! Doppler itself; a frame that hears both the lowest and the highest group gives their
//! geometric mean, whose ratio is free of the Doppler scale. A frame that hears one group
//! alone cannot tell which side it is on: its noise grows by half the split, learnt from the
//! frames that heard both.
//!
//! Measured with truth (throwaway script on `host-sim fly` of square10-los with drawn
//! airframes, seeds 101–103): the centre of two-group frames follows v·u/c with slope
//! 0.8–1.3 and a residual of 0.25–0.30 % per frame, against a Doppler spread of 0.2 %.

/// Speed of sound when the site does not give one (dry air at 20 °C), m/s.
pub const DEFAULT_SPEED_OF_SOUND_MPS: f64 = 343.2;

/// ln(f_obs / f_ref) of a line emitted at ln(f_rest / f_ref) = `ln_rest` by a source at
/// `rel` (m, from the array) moving at `velocity` (m/s), heard at the array through air with
/// speed of sound `speed_of_sound` (m/s). `None` with the source on the array or moving at
/// the speed of sound away from it.
pub fn observed_ln_ratio(
    ln_rest: f64,
    rel: [f64; 3],
    velocity: [f64; 3],
    speed_of_sound: f64,
) -> Option<f64> {
    let r = crate::observation::norm(rel);
    if !(r > 0.0 && speed_of_sound > 0.0) {
        return None;
    }
    let w = (0..3).map(|i| rel[i] / r * velocity[i]).sum::<f64>();
    let factor = 1.0 + w / speed_of_sound;
    (factor > 0.0).then(|| ln_rest - factor.ln())
}

/// Tunables of the per-frame centre.
#[derive(Clone, Debug, PartialEq)]
pub struct DopplerConfig {
    /// Noise of the log centre of a frame that heard the lowest and highest groups (rotor
    /// jitter and DSP frequency noise over a 0.512 s frame; measured 0.25–0.30 %).
    pub centre_sigma: f64,
    /// Relative split assumed before one has been heard (for the noise of a one-group frame).
    pub initial_split: f64,
    /// Weight of a new two-group frame in the running split.
    pub split_alpha: f64,
    /// Splits wider than this are not a wake (a yaw, or a stray line): not learnt.
    pub max_split: f64,
}

impl Default for DopplerConfig {
    fn default() -> Self {
        Self { centre_sigma: 0.003, initial_split: 0.01, split_alpha: 0.2, max_split: 0.04 }
    }
}

/// One BPF frame as the Doppler cue uses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DopplerFrame {
    /// Time (middle of the frame's span), s.
    pub t: f64,
    /// ln(f_centre / f_ref), f_ref the reference given to [`FrameCentre::frame`].
    pub ln_ratio: f64,
    /// Its standard deviation.
    pub sigma: f64,
}

/// Turns each frame's rotor groups into one centre frequency with its noise.
#[derive(Clone, Debug, Default)]
pub struct FrameCentre {
    config: DopplerConfig,
    /// Running relative split ln(f_high / f_low) of the frames that heard two groups.
    split: Option<f64>,
}

impl FrameCentre {
    /// With explicit tunables.
    pub fn new(config: DopplerConfig) -> Self {
        Self { config, split: None }
    }

    /// The running relative split (ln high/low), once a frame has heard two groups.
    pub fn split(&self) -> Option<f64> {
        self.split
    }

    /// The centre of a frame at `t` (s) whose groups are `groups_hz` (Hz, hover pattern
    /// normalised), against the reference `f_ref` (Hz). `None` without a usable group.
    pub fn frame(&mut self, t: f64, groups_hz: &[f64], f_ref: f64) -> Option<DopplerFrame> {
        if !(t.is_finite() && f_ref.is_finite() && f_ref > 0.0) {
            return None;
        }
        let (lo, hi) = groups_hz
            .iter()
            .filter(|f| f.is_finite() && **f > 0.0)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &f| (l.min(f), h.max(f)));
        if !lo.is_finite() {
            return None;
        }
        let c = &self.config;
        let split = (hi / lo).ln();
        let sigma = if split > 1e-9 {
            if split <= c.max_split {
                let s = self.split.get_or_insert(split);
                *s += c.split_alpha * (split - *s);
            }
            c.centre_sigma
        } else {
            // One group: the lower or the upper side, ± half the split around the centre.
            let half = 0.5 * self.split.unwrap_or(c.initial_split);
            c.centre_sigma.hypot(half)
        };
        Some(DopplerFrame { t, ln_ratio: 0.5 * (lo * hi).ln() - f_ref.ln(), sigma })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::ekf::{Ekf, LN_REST, STATE, ZENITH_BIAS};
    use crate::linalg::Mat;
    use crate::observation::{angles_of, norm};
    use crate::site::ArrayPose;

    #[test]
    fn the_shift_is_the_moving_source_doppler() {
        // Oracle: f_obs = f_s · c / (c − v_towards). Approaching at 1.5 m/s along the line of
        // sight: +0.44 %; receding: −0.44 %; crossing: none.
        let c = 343.2;
        let rel = [6.0, 0.0, 0.0];
        let approach = observed_ln_ratio(0.0, rel, [-1.5, 0.0, 0.0], c).unwrap();
        assert!((approach - (c / (c - 1.5f64)).ln()).abs() < 1e-12);
        assert!((approach.exp() - 1.0 - 0.00439).abs() < 1e-4, "{approach}");
        let recede = observed_ln_ratio(0.0, rel, [1.5, 0.0, 0.0], c).unwrap();
        assert!((recede - (c / (c + 1.5f64)).ln()).abs() < 1e-12);
        assert_eq!(observed_ln_ratio(0.02, rel, [0.0, 1.5, 0.0], c), Some(0.02));
        assert_eq!(observed_ln_ratio(0.0, [0.0; 3], [1.0, 0.0, 0.0], c), None);
    }

    #[test]
    fn a_frame_centre_is_free_of_the_split_and_a_lone_group_is_noisier() {
        let mut centre = FrameCentre::default();
        // Rear rotors 1 % above the front ones, the whole frame Doppler-shifted by +0.3 %.
        let d = 1.003;
        let (front, rear) = (326.0 * d, 326.0 * 1.01 * d);
        let both = centre.frame(1.0, &[front, rear], 326.0).unwrap();
        assert!((both.ln_ratio - (d * 1.01f64.sqrt()).ln()).abs() < 1e-12);
        assert_eq!(both.sigma, DopplerConfig::default().centre_sigma);
        assert!((centre.split().unwrap() - 1.01f64.ln()).abs() < 1e-12);
        let alone = centre.frame(1.25, &[rear], 326.0).unwrap();
        let expected = 0.003f64.hypot(0.5 * 1.01f64.ln());
        assert!((alone.sigma - expected).abs() < 1e-12, "{}", alone.sigma);
        assert!(centre.frame(1.5, &[f64::NAN, -3.0], 326.0).is_none());
        assert!(centre.frame(1.5, &[], 326.0).is_none());
    }

    /// A constant-velocity pass at 1.5 m/s along y, 5 m abeam of the array, 2 m up, heard
    /// for 10 s (from 7.5 m before the closest point to 7.5 m after): bearings (0.5° noise) at
    /// 10 Hz, a BPF centre (0.3 % noise, emitted 2.3 % off the reference) at 4 Hz. One EKF
    /// starts at `start_range` times the true range along the first bearing with an unknown
    /// velocity; returns its relative range error at the end and the summed log-likelihood of
    /// its bearing and Doppler updates (what weighs it in the `aim` mixture).
    fn pass(start_range: f64, doppler: bool, seed: u64) -> (f64, f64) {
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let c = DEFAULT_SPEED_OF_SOUND_MPS;
        let ln_rest = 1.023f64.ln();
        let v = [0.0, 1.5, 0.0];
        let p0 = [5.0, -7.5, 2.0];
        let at = |t: f64| [p0[0], p0[1] + v[1] * t, p0[2]];
        let mut rng = crate::testutil::Rng::new(seed);
        let x0 = at(0.0).map(|x| x * start_range);
        let mut ekf = Ekf::new(
            [x0[0], x0[1], x0[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.01],
            Mat::diagonal(&[1.0, 1.0, 0.25, 4.0, 4.0, 0.01, 1e-6, 0.05f64.powi(2), 1e-6]),
        );
        let sigma_b = 0.5f64.to_radians();
        let dt = 0.1;
        let mut ll = 0.0;
        for k in 1..=100 {
            let t = k as f64 * dt;
            ekf.predict(dt, [0.01, 0.01, 0.001], 20.0, 1e-3);
            ekf.diffuse_rest(1e-7 * dt);
            let p = at(t);
            let (az, zen) = angles_of(p);
            let (az, zen) = (az + sigma_b * rng.normal(), zen + sigma_b * rng.normal());
            ll += ekf.update_bearing(&array, az, zen, sigma_b, sigma_b).unwrap_or(0.0);
            let noise = 0.003 * rng.normal();
            if doppler && matches!(k % 5, 0 | 2) {
                let z = observed_ln_ratio(ln_rest, p, v, c).unwrap() + noise;
                ll += ekf.update_doppler(&array, z, 0.003, c).unwrap_or(0.0);
            }
        }
        assert!(ekf.p.asymmetry() < 1e-9 && ekf.p[(ZENITH_BIAS, ZENITH_BIAS)] > 0.0);
        assert_eq!(ekf.x.len(), STATE);
        if doppler && start_range == 1.0 {
            // The unknown rest frequency is absorbed by its state.
            assert!((ekf.x[LN_REST] - ln_rest).abs() < 0.002, "ln rest {}", ekf.x[LN_REST]);
        }
        let truth = norm(at(10.0));
        ((norm(ekf.position()) - truth) / truth, ll)
    }

    #[test]
    fn a_constant_velocity_pass_weighs_the_true_range_through_the_doppler() {
        // Three range hypotheses along the first bearing (half, true, twice), as the `aim`
        // mixture spawns them; each is weighed by the likelihood of its updates. The oracle is
        // the Doppler's share of the log-likelihood ratio of the true hypothesis against each
        // wrong one: ratio with the frames' Doppler minus ratio with bearings alone (same
        // noise). Physics: twice the range means twice the speed and twice the sweep of v·u
        // (±0.38 % against ±0.19 % here, frames at 0.3 %): ≈ 10 nats over the pass before
        // the emitted-BPF state absorbs part of it; half the range, half the sweep: ≈ 3 nats.
        // Measured: +4.0 to +12.3 nats against ×2, −1.7 to +2.9 (mean +1.0) against ×½.
        let mut gain_far = Vec::new();
        let mut gain_near = Vec::new();
        for seed in 1..=6 {
            let (_, ll_true) = pass(1.0, true, seed);
            let (_, ll_true_control) = pass(1.0, false, seed);
            for (start, gains) in [(2.0, &mut gain_far), (0.5, &mut gain_near)] {
                let (_, ll) = pass(start, true, seed);
                let (_, ll_control) = pass(start, false, seed);
                gains.push((ll_true - ll) - (ll_true_control - ll_control));
            }
        }
        let mean = |g: &[f64]| g.iter().sum::<f64>() / g.len() as f64;
        assert!(gain_far.iter().all(|g| *g > 2.0), "against ×2: {gain_far:?}");
        assert!(mean(&gain_far) > 5.0, "against ×2: {gain_far:?}");
        assert!(mean(&gain_near) > 0.3, "against ×½: {gain_near:?}");
    }
}
