//! Yaw from the sound of the rotors: the size of a turn on the spot, |Δψ|, from the odd/even
//! rotor-speed split (paper eq. 1 as corrected in ALGORITHMS.md §5):
//!
//! ```text
//! I_z dω/dt = (k_h / n²)(Σ BPF_odd² − Σ BPF_even²),     Δψ = ∫∫ (dω/dt) dt dt
//! ```
//!
//! The spectrum tells the two rotor groups apart only by frequency, never which of them is the
//! odd (counter-clockwise) set, so every split frame gives |β| = |dω/dt| and not its sign. A
//! multirotor turns on the spot *rest to rest*: it speeds the turn up (one group faster), may
//! turn steadily (no split: nothing resists a steady yaw but a small drag torque), and brakes
//! (the other group faster), ending with ω = 0. With ω = 0 at both ends, integration by parts
//! gives Δψ = −∫ t β dt; splitting the |β| record where its running area reaches half the total
//! A (the braking burst must undo the speeding-up one) leaves
//!
//! ```text
//! |Δψ| = (A / 2) · (t̄_brake − t̄_speed-up)        A = ∫ |β| dt (rad/s), t̄: |β|-weighted mean times
//! ```
//!
//! exact for any rest-to-rest profile whose acceleration changes sign once, and insensitive to
//! a constant delay of the spectra (their time stamps only enter as a difference). The sign of
//! Δψ stays ambiguous: a [`YawEvent`] carries the magnitude, and the caller keeps both
//! candidate headings ψ ± |Δψ| as hypotheses until a clean LoS bearing picks one (§7).
//!
//! A yaw phase is a run of split spectra (the two extreme BPF groups at least `min_split_hz`
//! apart) while the drone is still — Table I's "two peaks, DoA stable" — closed once no split
//! has been heard for `quiet_s`. Splits while the drone translates (front/rear pitch split,
//! rear rotors in the wake) are not yaw and are left out: the caller says per output instant
//! whether the drone is still.

use std::collections::VecDeque;

use crate::observation::BpfPeak;
use crate::profile::Profile;

/// Tunables of the yaw estimator.
#[derive(Clone, Debug, PartialEq)]
pub struct YawConfig {
    /// Smallest spread between the highest and lowest BPF group that opens a yaw phase or keeps
    /// it open, Hz (BPF). Inside a phase every spectrum with two groups adds its |β|, however
    /// close they are, so the faint edges of the speeding-up and braking bursts are not lost.
    pub min_split_hz: f64,
    /// A phase ends when no split has been heard for this long, s. It must exceed the steady
    /// part of the longest turn expected between the speeding-up and the braking bursts.
    pub quiet_s: f64,
    /// Split spectra up to this long before the phase is noticed still count (the caller's
    /// stillness may lag the sound), s.
    pub lookback_s: f64,
    /// The drone must be reported moving this long in a row to end (and cut) a phase, s; a
    /// shorter flicker of the caller's motion decision is ignored.
    pub moving_s: f64,
    /// A lone group (its partner unheard) counts as half a split when it lies at least this far
    /// from the hover BPF, Hz ([`YawEstimator::push_spectrum`]).
    pub min_lone_offset_hz: f64,
    /// Largest relative change of Σ BPF² from hover that a yaw split may show. A turn on the
    /// spot keeps the thrust (hi² + lo² = 2·BPF_hover²); a split with a thrust excess is the
    /// drone tilting or its rear rotors working in the wake, and is not counted. Two groups each
    /// known to `bpf_sigma_hz` give Σ BPF² to about 0.2 % at 328 Hz; the default allows for
    /// the spectral smear of a fast-changing split and a hover reference off by a little.
    pub max_thrust_change: f64,
    /// Multiplier of the profile's k_h / I_z (1: trust the profile); a calibration hook for the
    /// caller (e.g. from turns whose size a LoS track has shown).
    pub scale: f64,
    /// Relative standard deviation of k_h / I_z (times `scale`), the model's own uncertainty.
    pub scale_rel_sigma: f64,
    /// Standard deviation of one BPF group's frequency in one spectrum, Hz.
    pub bpf_sigma_hz: f64,
}

impl Default for YawConfig {
    fn default() -> Self {
        Self {
            min_split_hz: 4.0,
            min_lone_offset_hz: 8.0,
            max_thrust_change: 0.012,
            quiet_s: 1.5,
            lookback_s: 1.0,
            moving_s: 0.5,
            scale: 1.0,
            scale_rel_sigma: 0.3,
            bpf_sigma_hz: 0.5,
        }
    }
}

/// A finished turn on the spot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YawEvent {
    /// Time of the first split spectrum of the phase, s.
    pub t_start_s: f64,
    /// Time of the last spectrum of the phase with two groups, s (the event is emitted about
    /// `quiet_s` later, or when the drone sets off).
    pub t_end_s: f64,
    /// Size of the turn |Δψ|, rad; its sign (left or right) is unknown.
    pub magnitude_rad: f64,
    /// Standard deviation of `magnitude_rad`, rad.
    pub sigma_rad: f64,
    /// Peak |yaw rate| reached, rad/s (A / 2).
    pub peak_rate_rad_s: f64,
    /// Split spectra used.
    pub split_frames: usize,
}

/// Errors building a yaw estimator.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum YawError {
    /// A tunable is out of its range.
    #[error("yaw estimator: {0}")]
    BadConfig(String),
    /// The profile lacks the airframe constants the yaw size needs.
    #[error(
        "yaw estimator: the profile gives no drag-torque coefficient k_h or yaw inertia i_z \
         (measured values are needed; none are published for most drones)"
    )]
    UnknownAirframe,
}

#[derive(Clone, Copy, Debug)]
struct Frame {
    t_s: f64,
    /// |β| = |dω/dt| of the frame, rad/s² (0 with fewer than two groups).
    beta: f64,
    /// The groups are at least `min_split_hz` apart.
    split: bool,
    /// Standard deviation of `beta` from the frequency noise, rad/s².
    beta_sigma: f64,
}

/// The causal yaw estimator (module docs): feed every spectrum's BPF groups with
/// [`YawEstimator::push_spectrum`] and every output instant with [`YawEstimator::update`].
#[derive(Clone, Debug)]
pub struct YawEstimator {
    config: YawConfig,
    /// (k_h / (n² I_z)) · scale, rad/s² per Hz².
    gain: f64,
    /// Rotors in each of the two groups (N/2).
    per_group: f64,
    /// Recent frames (the look-back) while idle; the phase's frames while in a phase.
    frames: VecDeque<Frame>,
    in_phase: bool,
    /// Start of the current run of "moving" instants, s.
    moving_since: Option<f64>,
    /// Latest instant reported moving, s.
    last_moving_s: f64,
}

impl YawEstimator {
    /// An estimator for `profile` (k_h, I_z, blades, rotors).
    pub fn new(profile: &Profile, config: YawConfig) -> Result<Self, YawError> {
        let c = &config;
        let checks = [
            (c.min_split_hz > 0.0, "min_split_hz must be positive"),
            (c.quiet_s > 0.0, "quiet_s must be positive"),
            (c.min_lone_offset_hz > 0.0, "min_lone_offset_hz must be positive"),
            (c.max_thrust_change > 0.0, "max_thrust_change must be positive"),
            (c.lookback_s >= 0.0, "lookback_s must not be negative"),
            (c.moving_s >= 0.0, "moving_s must not be negative"),
            (c.scale > 0.0 && c.scale.is_finite(), "scale must be positive"),
            (c.scale_rel_sigma >= 0.0, "scale_rel_sigma must not be negative"),
            (c.bpf_sigma_hz >= 0.0, "bpf_sigma_hz must not be negative"),
        ];
        if let Some((_, msg)) = checks.iter().find(|(ok, _)| !ok) {
            return Err(YawError::BadConfig((*msg).into()));
        }
        if !(profile.k_h > 0.0 && profile.i_z > 0.0) {
            return Err(YawError::UnknownAirframe);
        }
        let n = f64::from(profile.blades);
        Ok(Self {
            gain: profile.k_h / (n * n * profile.i_z) * config.scale,
            per_group: profile.rotors() as f64 / 2.0,
            config,
            frames: VecDeque::new(),
            in_phase: false,
            moving_since: None,
            last_moving_s: f64::NEG_INFINITY,
        })
    }

    /// True while a yaw phase is open.
    pub fn in_phase(&self) -> bool {
        self.in_phase
    }

    /// |β| (rad/s²) of one spectrum from its distinct BPF groups (Hz, any order): the rotors
    /// are shared equally between the highest and the lowest group, (N/2)·|hi² − lo²|·k_h/(n² I_z);
    /// 0 with fewer than two groups.
    pub fn yaw_acceleration_magnitude(&self, groups: &[BpfPeak]) -> f64 {
        extremes(groups).map_or(0.0, |(hi, lo)| self.gain * self.per_group * (hi * hi - lo * lo))
    }

    /// Adds the BPF groups of one spectrum stamped `t_s` (s, in time order; the groups as
    /// [`crate::motion::bpf_groups`] returns them). Out-of-order spectra are ignored.
    ///
    /// `hover_bpf_hz` (Hz), the BPF at hover (e.g. √(Σ_hover BPF² / N) of the hover
    /// calibration), lets a spectrum in which only one group was heard still count: a turn on
    /// the spot keeps the total thrust, so Σ BPF² stays N·BPF_hover² and the unheard group
    /// mirrors the heard one, lo² = 2·BPF_hover² − hi². A lone group is taken as half a split
    /// only when it lies at least `min_lone_offset_hz` from the hover BPF; with two groups, a
    /// split whose Σ BPF² is more than `max_thrust_change` off hover is not a yaw. `None`
    /// ignores lone groups and skips the thrust check.
    pub fn push_spectrum(&mut self, t_s: f64, groups: &[BpfPeak], hover_bpf_hz: Option<f64>) {
        if !t_s.is_finite() || self.frames.back().is_some_and(|f| t_s <= f.t_s) {
            return;
        }
        let hover = hover_bpf_hz.filter(|h| h.is_finite() && *h > 0.0);
        let pair = match (extremes(groups), hover) {
            (Some((hi, lo)), Some(h)) => {
                let change = (hi * hi + lo * lo) / (2.0 * h * h) - 1.0;
                (change.abs() <= self.config.max_thrust_change).then_some((hi, lo))
            }
            (Some(pair), None) => Some(pair),
            (None, Some(h)) => match groups {
                [one] => {
                    let f = one.hz;
                    let mirror_sq = 2.0 * h * h - f * f;
                    ((f - h).abs() >= self.config.min_lone_offset_hz && mirror_sq > 0.0).then(
                        || {
                            let m = mirror_sq.sqrt();
                            (f.max(m), f.min(m))
                        },
                    )
                }
                _ => None,
            },
            (None, None) => None,
        };
        let (beta, beta_sigma) = match pair {
            Some((hi, lo)) => {
                let beta = self.gain * self.per_group * (hi * hi - lo * lo);
                // ∂/∂hi = 2 hi, ∂/∂lo = −2 lo, each group's frequency with bpf_sigma_hz.
                let sigma =
                    self.gain * self.per_group * 2.0 * hi.hypot(lo) * self.config.bpf_sigma_hz;
                (beta, sigma)
            }
            None => (0.0, 0.0),
        };
        let split = pair.is_some_and(|(hi, lo)| hi - lo >= self.config.min_split_hz);
        self.frames.push_back(Frame { t_s, beta, split, beta_sigma });
        if !self.in_phase {
            let horizon = t_s - self.config.lookback_s.max(self.config.quiet_s);
            while self.frames.front().is_some_and(|f| f.t_s < horizon) {
                self.frames.pop_front();
            }
        }
    }

    /// Advances to output instant `t_s` (s), with `still` the caller's decision that the drone
    /// is not translating (Table I's "DoA stable" column; e.g. motion class hover or yaw).
    /// Returns the event of a yaw phase that ended.
    pub fn update(&mut self, t_s: f64, still: bool) -> Option<YawEvent> {
        if still {
            self.moving_since = None;
        } else {
            self.last_moving_s = t_s;
            let since = *self.moving_since.get_or_insert(t_s);
            if self.in_phase && t_s - since >= self.config.moving_s {
                // The drone set off: the phase ends where the movement began.
                self.frames.retain(|f| f.t_s < since);
                return self.close();
            }
        }
        if !self.in_phase {
            if !still {
                return None;
            }
            // A split heard since the drone was last seen moving (and within the look-back)
            // opens a phase from that spectrum on.
            let from = self.last_moving_s.max(t_s - self.config.lookback_s);
            let first = self.frames.iter().position(|f| f.t_s > from && f.split)?;
            // The faint start of the burst before it: the two-group spectra just before.
            let first = self
                .frames
                .iter()
                .take(first)
                .rposition(|f| f.beta == 0.0 || f.t_s <= from)
                .map_or(0, |i| i + 1);
            self.frames.drain(..first);
            self.in_phase = true;
            return None;
        }
        let last_split = self.frames.iter().rev().find(|f| f.split).map(|f| f.t_s);
        match last_split {
            Some(ts) if t_s - ts < self.config.quiet_s => None,
            _ => self.close(),
        }
    }

    /// Ends the phase and estimates its turn from the frames held.
    fn close(&mut self) -> Option<YawEvent> {
        self.in_phase = false;
        let frames: Vec<Frame> = self.frames.drain(..).collect();
        let last = frames.iter().rposition(|f| f.split)?;
        // The faint end of the braking burst: the two-group spectra just after.
        let last =
            frames[last..].iter().position(|f| f.beta == 0.0).map_or(frames.len(), |i| last + i);
        let frames = &frames[..last];
        estimate(frames, &self.config)
    }
}

/// The smallest and largest of the groups' frequencies (Hz), if there are two distinct ones.
fn extremes(groups: &[BpfPeak]) -> Option<(f64, f64)> {
    let hz = groups.iter().map(|g| g.hz).filter(|f| f.is_finite() && *f > 0.0);
    let hi = hz.clone().fold(f64::NEG_INFINITY, f64::max);
    let lo = hz.fold(f64::INFINITY, f64::min);
    (hi > lo).then_some((hi, lo))
}

/// The turn of one phase's frames (first and last with two groups): module docs.
fn estimate(frames: &[Frame], config: &YawConfig) -> Option<YawEvent> {
    // Each frame stands for the time to the next one; the last for the median spacing.
    let mut gaps: Vec<f64> = frames.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    let spacing = {
        let mut g = gaps.clone();
        g.sort_by(f64::total_cmp);
        g.get(g.len() / 2).copied().unwrap_or(0.0)
    };
    gaps.push(spacing);
    if frames.iter().filter(|f| f.beta > 0.0).count() < 2 {
        // One spectrum cannot tell a speeding-up burst from a braking one: no estimate.
        return None;
    }
    // Weights w_k = |β_k| Δt_k (rad/s each); split at half the area.
    let w: Vec<f64> = frames.iter().zip(&gaps).map(|(f, g)| f.beta * g).collect();
    let area: f64 = w.iter().sum();
    let half = area / 2.0;
    let (mut acc, mut m1, mut m2) = (0.0, 0.0, 0.0);
    for (f, &wk) in frames.iter().zip(&w) {
        // The part of this frame's weight before the half-area point goes to the first burst.
        let first = (half - acc).clamp(0.0, wk);
        m1 += first * f.t_s;
        m2 += (wk - first) * f.t_s;
        acc += wk;
    }
    let (t1, t2) = (m1 / half, m2 / half);
    let span = (t2 - t1).max(0.0);
    let magnitude = half * span;
    // Uncertainty: the model scale, the frequency noise of the area, and the time resolution
    // of the two centroids (one frame spacing, uniform, each).
    let area_var: f64 = frames.iter().zip(&gaps).map(|(f, g)| (f.beta_sigma * g).powi(2)).sum();
    let centroid_var = 2.0 * spacing * spacing / 12.0;
    let variance = (magnitude * config.scale_rel_sigma).powi(2)
        + area_var / 4.0 * span * span
        + half * half * centroid_var;
    Some(YawEvent {
        t_start_s: frames[0].t_s,
        t_end_s: frames[frames.len() - 1].t_s,
        magnitude_rad: magnitude,
        sigma_rad: variance.sqrt(),
        peak_rate_rad_s: half,
        split_frames: frames.iter().filter(|f| f.split).count(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Mini 2 with airframe constants for the yaw size (estimates: a 1.2 % torque-to-thrust
    /// ratio per metre and a 249 g quad's inertia; the bundled profile carries none).
    fn airframe() -> Profile {
        Profile { k_h: 2.72e-7, i_z: 7.5e-4, ..Profile::dji_mini_2() }
    }

    #[test]
    fn a_profile_without_k_h_or_i_z_is_refused() {
        let e = YawEstimator::new(&Profile::dji_mini_2(), YawConfig::default()).err();
        assert!(matches!(e, Some(YawError::UnknownAirframe)), "{e:?}");
        assert!(YawEstimator::new(&airframe(), YawConfig::default()).is_ok());
    }
    use crate::testutil::Rng;

    /// A rest-to-rest turn of `delta` rad: raised-cosine rate ramps of peak acceleration
    /// `accel` up to `rate` (rad/s; less for a turn too short to reach it), as the simulator's
    /// flight plan flies it. Returns ψ̈ (rad/s²) at `tau` s after the start.
    fn turn_accel(delta: f64, rate: f64, accel: f64, tau: f64) -> f64 {
        use std::f64::consts::PI;
        let ramp_of = |v: f64| PI * v / (2.0 * accel);
        let mut v = rate;
        if v * ramp_of(v) > delta.abs() {
            v = (2.0 * accel * delta.abs() / PI).sqrt();
        }
        let ramp = ramp_of(v);
        let dur = delta.abs() / v + ramp;
        let a = |t: f64| v * PI / (2.0 * ramp) * (PI * t / ramp).sin();
        delta.signum()
            * if tau <= 0.0 || tau >= dur {
                0.0
            } else if tau < ramp {
                a(tau)
            } else if tau < dur - ramp {
                0.0
            } else {
                -a(dur - tau)
            }
    }

    /// The BPF groups the torque law gives for yaw acceleration `beta` (rad/s²) around hover
    /// BPF `hover` (Hz), total thrust kept: Σ odd² − Σ even² = β I_z n² / k_h, Σ odd² + Σ even²
    /// = N hover², each group's frequency with Gaussian noise of `noise_hz`. Returned as the
    /// spectrum would, sorted, without saying which is odd, and merged into one group when
    /// closer than `merge_hz` (`motion::bpf_groups` merges at 2 Hz by default).
    fn groups_for(
        p: &Profile,
        beta: f64,
        hover: f64,
        noise_hz: f64,
        merge_hz: f64,
        rng: &mut Rng,
    ) -> Vec<BpfPeak> {
        let n = f64::from(p.blades);
        let diff = beta * p.i_z * n * n / p.k_h / 2.0; // per rotor pair: odd² − even²
        let odd = (hover * hover + diff / 2.0).sqrt() + noise_hz * rng.normal();
        let even = (hover * hover - diff / 2.0).sqrt() + noise_hz * rng.normal();
        if (odd - even).abs() < merge_hz {
            return vec![BpfPeak { hz: (odd + even) / 2.0, amplitude: 2.0 }];
        }
        let mut g = vec![BpfPeak { hz: odd, amplitude: 1.0 }, BpfPeak { hz: even, amplitude: 1.0 }];
        g.sort_by(|a, b| a.hz.total_cmp(&b.hz));
        g
    }

    /// Runs the estimator over a still drone turning `delta` from t = 1 s, spectra every
    /// `frame_s` (point samples of the split, plus Gaussian frequency noise), output every 0.1 s.
    fn run(
        p: &Profile,
        delta: f64,
        frame_s: f64,
        noise_hz: f64,
        merge_hz: f64,
        seed: u64,
    ) -> Vec<YawEvent> {
        let mut est = YawEstimator::new(p, YawConfig::default()).unwrap();
        let mut rng = Rng::new(seed);
        let hover = p.hover_bpf_hz();
        let mut events = Vec::new();
        let (mut next_frame, mut t) = (0.0, 0.0);
        while t < 10.0 {
            while next_frame <= t {
                let rate = 90f64.to_radians();
                let beta = turn_accel(delta, rate, 180f64.to_radians(), next_frame - 1.0);
                let g = groups_for(p, beta, hover, noise_hz, merge_hz, &mut rng);
                est.push_spectrum(next_frame, &g, Some(hover));
                next_frame += frame_s;
            }
            events.extend(est.update(t, true));
            t += 0.1;
        }
        events
    }

    #[test]
    fn recovers_the_size_of_synthetic_turns_either_way() {
        let p = airframe();
        for delta_deg in [90.0f64, -90.0, 45.0, 180.0] {
            let events = run(&p, delta_deg.to_radians(), 0.01, 0.0, 0.0, 1);
            assert_eq!(events.len(), 1, "{delta_deg}: {events:?}");
            let e = events[0];
            let err = (e.magnitude_rad - delta_deg.abs().to_radians()).abs();
            // Sampling every 10 ms a smooth profile: exact up to the rectangle rule.
            assert!(
                err < 0.5f64.to_radians(),
                "{delta_deg}°: {:.2}°",
                e.magnitude_rad.to_degrees()
            );
            // The peak rate is the profile's (90 °/s, or less for a short turn).
            assert!(e.peak_rate_rad_s <= 90f64.to_radians() * 1.01);
            assert!(e.sigma_rad > 0.0 && e.sigma_rad < e.magnitude_rad);
        }
    }

    #[test]
    fn merged_faint_edges_bias_low_by_the_lost_area() {
        // Spectra merge the two groups below 2 Hz apart: the edges of each burst where
        // |β| < c·2 Hz are lost. With this profile c = k_h/(n² I_z)·(N/2)·2·BPF, and a
        // raised-cosine burst loses the fraction 1 − cos(asin(β_lost/β_peak)) of its area.
        let p = airframe();
        let hover = p.hover_bpf_hz();
        let c = p.k_h / (4.0 * p.i_z) * 2.0 * 2.0 * hover;
        let lost = 1.0 - (c * 2.0 / 180f64.to_radians()).asin().cos();
        let e = run(&p, 90f64.to_radians(), 0.01, 0.0, 2.0, 1)[0];
        let expected = 90f64.to_radians() * (1.0 - lost);
        assert!(
            (e.magnitude_rad - expected).abs() < 0.3f64.to_radians(),
            "{:.2}° vs {:.2}°",
            e.magnitude_rad.to_degrees(),
            expected.to_degrees()
        );
    }

    #[test]
    fn coarse_noisy_spectra_stay_within_their_sigma() {
        // Spectra every 0.256 s (the firmware's hop) with 0.5 Hz frequency noise: over 40
        // seeded turns the errors are unbiased within their reported sigma.
        let p = airframe();
        let mut z2 = 0.0;
        let k = 40;
        for seed in 0..k {
            let events = run(&p, 90f64.to_radians(), 0.256, 0.5, 2.0, seed + 1);
            assert_eq!(events.len(), 1, "seed {seed}: {events:?}");
            let e = events[0];
            let err = e.magnitude_rad - 90f64.to_radians();
            z2 += (err / e.sigma_rad).powi(2);
            assert!(
                err.abs() < 20f64.to_radians(),
                "seed {seed}: {:.1}°",
                e.magnitude_rad.to_degrees()
            );
        }
        let rms_z = (z2 / k as f64).sqrt();
        assert!(rms_z < 1.5, "errors are {rms_z:.2} sigmas rms");
    }

    #[test]
    fn splits_while_moving_are_not_yaw_and_a_set_off_closes_the_phase() {
        let p = airframe();
        let hover = p.hover_bpf_hz();
        let mut est = YawEstimator::new(&p, YawConfig::default()).unwrap();
        // Cruise with a wake split of 8 Hz while moving: no phase, no event.
        let split = [
            BpfPeak { hz: hover - 4.0, amplitude: 1.0 },
            BpfPeak { hz: hover + 4.0, amplitude: 1.0 },
        ];
        for k in 0..50 {
            let t = k as f64 * 0.1;
            est.push_spectrum(t, &split, Some(hover));
            assert!(est.update(t, false).is_none());
            assert!(!est.in_phase());
        }
        // Still again, without a split: nothing.
        for k in 50..80 {
            let t = k as f64 * 0.1;
            est.push_spectrum(t, &[BpfPeak { hz: hover, amplitude: 1.0 }], Some(hover));
            assert!(est.update(t, true).is_none());
        }
        // A split while still opens a phase; setting off for `moving_s` ends it at once, and
        // the spectra from the set-off on are left out.
        est.push_spectrum(8.0, &split, Some(hover));
        assert!(est.update(8.0, true).is_none());
        assert!(est.in_phase());
        est.push_spectrum(8.05, &split, Some(hover));
        assert!(est.update(8.1, false).is_none());
        est.push_spectrum(8.15, &split, Some(hover));
        let e = est.update(8.7, false).expect("closed by the set-off");
        assert_eq!(e.split_frames, 2);
        assert!(!est.in_phase());
        // A lone split spectrum is no turn: no event.
        est.push_spectrum(12.0, &split, Some(hover));
        assert!(est.update(12.0, true).is_none());
        assert!(est.update(14.0, true).is_none());
        assert!(!est.in_phase());
    }

    #[test]
    fn the_torque_law_sets_the_acceleration_scale() {
        // |β| of a split against dynamics::yaw_acceleration with the odd group high.
        let p = airframe();
        let est = YawEstimator::new(&p, YawConfig::default()).unwrap();
        let g = [BpfPeak { hz: 340.0, amplitude: 1.0 }, BpfPeak { hz: 316.0, amplitude: 1.0 }];
        let law = crate::dynamics::yaw_acceleration(
            p.k_h,
            p.blades,
            p.i_z,
            2.0 * 340f64.powi(2),
            2.0 * 316f64.powi(2),
        );
        assert!((est.yaw_acceleration_magnitude(&g) - law).abs() < 1e-12 * law);
        // One group: no yaw.
        assert_eq!(est.yaw_acceleration_magnitude(&g[..1]), 0.0);
        // A lone group off hover stands for the pair that keeps Σ BPF² (the thrust): its
        // mirror. Pushed alone with the hover BPF, it gives the same |β| as the full pair.
        let hover = ((340f64.powi(2) + 316f64.powi(2)) / 2.0).sqrt();
        let mut a = YawEstimator::new(&p, YawConfig::default()).unwrap();
        let mut b = a.clone();
        for k in 0..3 {
            let t = k as f64 * 0.25;
            a.push_spectrum(t, &g, None);
            b.push_spectrum(t, &g[..1], Some(hover));
            assert!(a.update(t, true).is_none() && b.update(t, true).is_none());
        }
        let (ea, eb) = (a.update(2.0, true).unwrap(), b.update(2.0, true).unwrap());
        assert!((ea.peak_rate_rad_s - eb.peak_rate_rad_s).abs() < 1e-9 * ea.peak_rate_rad_s);
        // A split with a thrust excess (rear rotors 1.5 % faster in the wake, front at hover:
        // Σ BPF² up 1.5 %) is not a yaw, even if the caller's motion decision says still.
        let mut w = YawEstimator::new(&p, YawConfig::default()).unwrap();
        let h = p.hover_bpf_hz();
        let wake = [BpfPeak { hz: h, amplitude: 1.0 }, BpfPeak { hz: h * 1.015, amplitude: 1.0 }];
        for k in 0..20 {
            let t = k as f64 * 0.25;
            w.push_spectrum(t, &wake, Some(h));
            assert!(w.update(t, true).is_none() && !w.in_phase());
        }
        // Without a hover reference, or near hover, a lone group is no split.
        let mut c = YawEstimator::new(&p, YawConfig::default()).unwrap();
        let near = [BpfPeak { hz: hover + 1.0, amplitude: 1.0 }];
        for k in 0..3 {
            let t = k as f64 * 0.25;
            c.push_spectrum(t, &g[..1], None);
            c.push_spectrum(t + 0.1, &near, Some(hover));
            assert!(c.update(t + 0.1, true).is_none() && !c.in_phase());
        }
        let bad = YawConfig { quiet_s: 0.0, ..YawConfig::default() };
        assert_eq!(
            YawEstimator::new(&p, bad).unwrap_err(),
            YawError::BadConfig("quiet_s must be positive".into())
        );
    }
}
