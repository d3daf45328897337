//! Cruise speed from the wake: the rear rotors, working in the front rotors' wake, spin faster
//! the faster the drone flies (paper §VII-C, ALGORITHMS.md §5). Two cues come from it:
//!
//! - [`WakeSpeed`], the thrust excess ρ − 1 = Σ BPF² / Σ_hover − 1. One spectrum frame is a
//!   poor measurement of it: the DSP resolves the front and rear groups (≈ 1 % apart at
//!   1.5 m/s) only some of the time, and a frame that hears one of them alone reads the excess
//!   of that group; which group is heard depends on loudness and range, so the leg mean is
//!   biased too (measured on square15-los: +0.7 m/s). It also needs the hover calibration and
//!   carries the Doppler shift of the radial velocity (±0.9 % at 1.5 m/s).
//! - [`WakeSplit`], the front/rear split f_rear / f_front − 1. The leg's group frequencies
//!   are clustered into the two groups, and a frame's split is read against the other
//!   cluster, so a frame hearing one group is not biased by which; a Doppler shift scales
//!   both groups alike, and no hover calibration enters. Measured on square10-los, its frame
//!   scatter is 0.5 m/s against the excess's 1.3 m/s.
//!
//! Each averages the frames of the current leg over a window, with a standard deviation from
//! the frame-to-frame spread *measured in cruise* (a running estimate), and gives each frame's
//! own speed once to the filter.

use std::collections::VecDeque;

use crate::dynamics::speed_from_wake;

/// Tunables of the wake speed.
#[derive(Clone, Debug, PartialEq)]
pub struct WakeConfig {
    /// Frames of the last this many seconds are averaged, s.
    pub window_s: f64,
    /// Frames of a leg's first seconds are not used: the tilt that accelerates the drone adds
    /// its own thrust excess (√(1 + (a/g)²) − 1, 0.5 % at 1 m/s²), comparable to the wake's, s.
    pub settle_s: f64,
    /// Frames needed for an estimate.
    pub min_frames: usize,
    /// Frame-to-frame standard deviation of the excess assumed before cruise has been heard.
    pub initial_frame_sigma: f64,
    /// Weight of a new squared deviation in the running spread.
    pub spread_gain: f64,
    /// Smallest standard deviation reported, m/s.
    pub min_sigma_mps: f64,
}

impl Default for WakeConfig {
    fn default() -> Self {
        Self {
            window_s: 20.0,
            settle_s: 1.5,
            min_frames: 3,
            initial_frame_sigma: 0.01,
            spread_gain: 0.05,
            min_sigma_mps: 0.1,
        }
    }
}

impl WakeConfig {
    /// Defaults for [`WakeSplit`]: a frame's relative split scatters by about 0.4 % (0.5 m/s
    /// measured on square10-los, × 0.71 % per m/s), before cruise has taught it.
    pub fn split() -> Self {
        Self { initial_frame_sigma: 0.004, ..Self::default() }
    }
}

/// The bookkeeping both cues share: the current leg's frames after its settling time, within
/// the window, and the running frame-to-frame variance of the cue in cruise.
#[derive(Clone, Debug)]
struct LegFrames<T> {
    config: WakeConfig,
    /// (time s, frame) of the current leg.
    frames: VecDeque<(f64, T)>,
    /// Time of the leg's first frame, s.
    leg_start: Option<f64>,
    /// Running frame-to-frame variance of the cue.
    frame_var: f64,
}

impl<T> LegFrames<T> {
    fn new(config: WakeConfig) -> Self {
        Self {
            frame_var: config.initial_frame_sigma.powi(2),
            config,
            frames: VecDeque::new(),
            leg_start: None,
        }
    }

    fn reset(&mut self) {
        self.frames.clear();
        self.leg_start = None;
    }

    /// True once the leg's first `settle_s` are over and frames are being kept.
    fn settled(&self) -> bool {
        !self.frames.is_empty()
    }

    /// Whether a frame at `t` (s) is past the leg's settling time; the first frame starts
    /// the leg.
    fn past_settling(&mut self, t: f64) -> bool {
        t - *self.leg_start.get_or_insert(t) >= self.config.settle_s
    }

    /// Keeps a frame and drops those older than the window.
    fn keep(&mut self, t: f64, frame: T) {
        self.frames.push_back((t, frame));
        while self.frames.front().is_some_and(|f| f.0 < t - self.config.window_s) {
            self.frames.pop_front();
        }
    }

    /// Enough frames for a leg estimate.
    fn enough(&self) -> bool {
        self.frames.len() >= self.config.min_frames
    }

    /// Adds a frame's deviation from the leg's value to the running variance.
    fn learn_spread(&mut self, deviation: f64) {
        self.frame_var += self.config.spread_gain * (deviation.powi(2) - self.frame_var);
    }

    fn frame_sigma(&self) -> f64 {
        self.frame_var.sqrt()
    }

    /// Standard deviation of the leg mean in m/s for a cue of `per_mps` per m/s, floored at
    /// `min_sigma_mps`; `None` before enough frames.
    fn mean_sigma_mps(&self, per_mps: f64) -> Option<f64> {
        let n = self.frames.len();
        self.enough().then(|| {
            (self.frame_sigma() / (n as f64).sqrt() / per_mps).max(self.config.min_sigma_mps)
        })
    }
}

/// Speed from the wake excess of one horizontal leg.
#[derive(Clone, Debug)]
pub struct WakeSpeed {
    /// Excess per m/s: wake loss × Σ downstream / N.
    excess_per_mps: f64,
    /// The leg's excess frames.
    leg: LegFrames<f64>,
}

impl WakeSpeed {
    /// An estimator for a drone whose excess grows by `excess_per_mps` per m/s; `None` when
    /// the profile gives no wake coefficient (the cue is then unavailable).
    pub fn new(config: WakeConfig, excess_per_mps: f64) -> Option<Self> {
        (excess_per_mps > 0.0 && excess_per_mps.is_finite())
            .then(|| Self { excess_per_mps, leg: LegFrames::new(config) })
    }

    /// The leg is over (or has not begun): forget its frames.
    pub fn reset(&mut self) {
        self.leg.reset();
    }

    /// Adds the excess ρ − 1 of a spectrum frame at time `t` (s) heard during the leg and
    /// returns that frame's speed and its standard deviation (m/s) once the leg has settled.
    pub fn push(&mut self, t: f64, excess: f64) -> Option<(f64, f64)> {
        if !(t.is_finite() && excess.is_finite()) {
            return None;
        }
        if !self.leg.past_settling(t) {
            return None;
        }
        if self.leg.enough() {
            let deviation = excess - self.mean();
            self.leg.learn_spread(deviation);
        }
        self.leg.keep(t, excess);
        let speed = speed_from_wake(excess, self.excess_per_mps)?;
        Some((speed, self.frame_sigma() / self.excess_per_mps))
    }

    /// True once the leg's first `settle_s` are over and frames are being averaged.
    pub fn settled(&self) -> bool {
        self.leg.settled()
    }

    fn mean(&self) -> f64 {
        let frames = &self.leg.frames;
        frames.iter().map(|f| f.1).sum::<f64>() / frames.len().max(1) as f64
    }

    /// Frame-to-frame standard deviation of the excess measured so far.
    pub fn frame_sigma(&self) -> f64 {
        self.leg.frame_sigma()
    }

    /// Horizontal speed and its standard deviation, m/s, once enough frames were heard.
    pub fn estimate(&self) -> Option<(f64, f64)> {
        let sigma = self.leg.mean_sigma_mps(self.excess_per_mps)?;
        Some((speed_from_wake(self.mean(), self.excess_per_mps)?, sigma))
    }
}

/// Centres (low, high) of two groups of values: two-means in one dimension, started from the
/// extremes. `None` when fewer than two distinct values were given.
fn two_means<I: Iterator<Item = f64>>(all: impl Fn() -> I) -> Option<(f64, f64)> {
    let (mut lo, mut hi) =
        all().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), f| (l.min(f), h.max(f)));
    if hi <= lo {
        return None;
    }
    for _ in 0..32 {
        let mid = 0.5 * (lo + hi);
        let (mut low, mut high) = ((0.0, 0usize), (0.0, 0usize));
        for f in all() {
            let side = if f <= mid { &mut low } else { &mut high };
            side.0 += f;
            side.1 += 1;
        }
        let next = (low.0 / low.1 as f64, high.0 / high.1 as f64);
        if next == (lo, hi) {
            break;
        }
        (lo, hi) = next;
    }
    Some((lo, hi))
}

/// The static BPF group pattern of the drone in hover, calibrated on the spot.
///
/// A real drone does not hover with all rotors alike: a centre of gravity off the rotors'
/// centre and the motors' thrust spread make some rotors hover faster than others (the
/// population's drones: up to ≈ 3 %). The DSP hears that as up to four groups in hover, which
/// the wake split would read as several m/s of cruise and the motion classifier as a tilt.
/// While the drone is still, each heard group's BPF is kept (a drone's hover BPFs do not move:
/// its mass does not); the sorted BPFs cut at gaps wider than `gap_hz` give the hover groups.
/// A frame's group is then normalised by the level of the hover group it is nearest to (that
/// group's BPF over the mean of the groups'), and the wake split is judged against the hover
/// split measured the way the leg's is (two-means; its noise bias cancels too).
#[derive(Clone, Debug)]
pub struct HoverPattern {
    /// Group BPFs heard while still, Hz, newest last.
    heard: VecDeque<f64>,
    /// Most BPFs kept.
    capacity: usize,
    /// BPFs needed before the pattern is used.
    min_heard: usize,
    /// Sorted BPFs further apart than this are different groups, Hz.
    gap_hz: f64,
    /// A group with less than this share of the BPFs is noise and joins its neighbour.
    min_share: f64,
    /// The hover groups' centres, Hz, ascending (empty before calibration).
    centres: Vec<f64>,
    /// Two-means split of the hover BPFs (0 before calibration).
    split: f64,
}

impl Default for HoverPattern {
    fn default() -> Self {
        Self::new(400, 8, 2.0, 0.05)
    }
}

impl HoverPattern {
    /// A pattern keeping the last `capacity` group BPFs, used after `min_heard`; groups are cut
    /// at gaps wider than `gap_hz` (Hz) and need `min_share` of the BPFs.
    pub fn new(capacity: usize, min_heard: usize, gap_hz: f64, min_share: f64) -> Self {
        Self {
            heard: VecDeque::new(),
            capacity,
            min_heard,
            gap_hz,
            min_share,
            centres: Vec::new(),
            split: 0.0,
        }
    }

    /// Adds the groups (Hz) of one frame heard in hover.
    pub fn learn(&mut self, groups_hz: &[f64]) {
        for &f in groups_hz.iter().filter(|f| f.is_finite() && **f > 0.0) {
            self.heard.push_back(f);
            if self.heard.len() > self.capacity {
                self.heard.pop_front();
            }
        }
        if self.heard.len() < self.min_heard {
            return;
        }
        let mut sorted: Vec<f64> = self.heard.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        // (sum, count) of each run of BPFs without a gap.
        let mut runs: Vec<(f64, usize)> = Vec::new();
        let mut prev = f64::NEG_INFINITY;
        for f in sorted {
            match runs.last_mut() {
                Some(r) if f - prev <= self.gap_hz => {
                    r.0 += f;
                    r.1 += 1;
                }
                _ => runs.push((f, 1)),
            }
            prev = f;
        }
        // Runs too small to be a group join their nearer neighbour.
        let min_count = (self.min_share * self.heard.len() as f64).ceil() as usize;
        while runs.len() > 1 {
            let Some(i) =
                (0..runs.len()).filter(|&i| runs[i].1 < min_count).min_by_key(|&i| runs[i].1)
            else {
                break;
            };
            let centre = |r: (f64, usize)| r.0 / r.1 as f64;
            let c = centre(runs[i]);
            let j = match (i.checked_sub(1), (i + 1 < runs.len()).then_some(i + 1)) {
                (Some(a), Some(b)) => {
                    if c - centre(runs[a]) <= centre(runs[b]) - c {
                        a
                    } else {
                        b
                    }
                }
                (Some(a), None) => a,
                (None, Some(b)) => b,
                (None, None) => break,
            };
            let r = runs.remove(i);
            let j = if j > i { j - 1 } else { j };
            runs[j].0 += r.0;
            runs[j].1 += r.1;
        }
        self.centres = runs.iter().map(|r| r.0 / r.1 as f64).collect();
        // A drone heard as one hover group has no imbalance to subtract (two-means would only
        // split the noise, which cruise's two real groups do not).
        self.split = if self.centres.len() >= 2 {
            two_means(|| self.heard.iter().copied()).map_or(0.0, |(lo, hi)| hi / lo - 1.0)
        } else {
            0.0
        };
    }

    /// Relative split high/low − 1 of the hover BPFs, two-means (0 before calibration).
    pub fn split(&self) -> f64 {
        self.split
    }

    /// The hover groups' BPFs, Hz, ascending (empty before calibration).
    pub fn centres(&self) -> &[f64] {
        &self.centres
    }

    /// True once enough hover groups were heard.
    pub fn is_calibrated(&self) -> bool {
        !self.centres.is_empty()
    }

    /// A frame's group BPF (Hz) normalised to the mean hover level: divided by the level of the
    /// nearest hover group relative to the mean of the groups.
    pub fn normalise(&self, hz: f64) -> f64 {
        if self.centres.len() < 2 {
            return hz;
        }
        let mean = self.centres.iter().sum::<f64>() / self.centres.len() as f64;
        let nearest =
            self.centres.iter().copied().min_by(|a, b| (a - hz).abs().total_cmp(&(b - hz).abs()));
        nearest.map_or(hz, |c| hz * mean / c)
    }
}

/// Cruise speed from the front/rear split of the BPF groups (see the module documentation).
#[derive(Clone, Debug)]
pub struct WakeSplit {
    /// Relative split per m/s ([`crate::profile::Profile::wake_split_per_mps`]).
    split_per_mps: f64,
    /// The leg's frames (group BPFs, Hz); the spread is that of the relative split.
    leg: LegFrames<Vec<f64>>,
    /// The split heard in hover ([`HoverPattern::split`]): the wake's is the change from it.
    hover_split: f64,
}

impl WakeSplit {
    /// An estimator for a drone whose relative split grows by `split_per_mps` per m/s; `None`
    /// when the profile gives no wake coefficient (the cue is then unavailable).
    pub fn new(config: WakeConfig, split_per_mps: f64) -> Option<Self> {
        (split_per_mps > 0.0 && split_per_mps.is_finite()).then(|| Self {
            split_per_mps,
            leg: LegFrames::new(config),
            hover_split: 0.0,
        })
    }

    /// Sets the relative split heard in hover ([`HoverPattern::split`]); the speed is read from
    /// the change of the split against it. A static imbalance along the flight's axis adds to
    /// or subtracts from the wake's split: the size of the change is the wake's either way
    /// (as long as the wake's split stays below twice the hover's, or the hover's is small).
    pub fn set_hover_split(&mut self, split: f64) {
        if split.is_finite() && split >= 0.0 {
            self.hover_split = split;
        }
    }

    /// The leg is over (or has not begun): forget its frames.
    pub fn reset(&mut self) {
        self.leg.reset();
    }

    /// True once the leg's first `settle_s` are over and frames are being kept.
    pub fn settled(&self) -> bool {
        self.leg.settled()
    }

    /// Centres (low, high) of the two groups over the leg's frames, Hz: two-means in one
    /// dimension, started from the extremes. `None` until both groups have been heard.
    fn clusters(&self) -> Option<(f64, f64)> {
        two_means(|| self.leg.frames.iter().flat_map(|f| f.1.iter().copied()))
    }

    /// Sign of the leg's split change against the hover split (+1 when the split grew).
    fn sign(&self, (lo, hi): (f64, f64)) -> f64 {
        if hi / lo - 1.0 >= self.hover_split {
            1.0
        } else {
            -1.0
        }
    }

    /// Relative split of one frame's groups against the clusters: the mean of each side it
    /// heard, the other cluster's centre for a side it did not.
    fn frame_split(groups: &[f64], (lo, hi): (f64, f64)) -> f64 {
        let mid = 0.5 * (lo + hi);
        let side_mean = |low: bool| {
            let (sum, n) = groups
                .iter()
                .filter(|&&f| (f <= mid) == low)
                .fold((0.0, 0usize), |(s, n), f| (s + f, n + 1));
            (n > 0).then(|| sum / n as f64)
        };
        side_mean(false).unwrap_or(hi) / side_mean(true).unwrap_or(lo) - 1.0
    }

    /// Adds the BPF groups (Hz) of a spectrum frame at time `t` (s) heard during the leg and
    /// returns that frame's speed and its standard deviation (m/s) once the leg has settled
    /// and both groups have been heard.
    pub fn push(&mut self, t: f64, groups: &[f64]) -> Option<(f64, f64)> {
        if !t.is_finite()
            || groups.is_empty()
            || groups.iter().any(|f| !(f.is_finite() && *f > 0.0))
        {
            return None;
        }
        if !self.leg.past_settling(t) {
            return None;
        }
        self.leg.keep(t, groups.to_vec());
        if !self.leg.enough() {
            return None;
        }
        let clusters = self.clusters()?;
        let split = Self::frame_split(groups, clusters);
        self.leg.learn_spread(split - (clusters.1 / clusters.0 - 1.0));
        let change = self.sign(clusters) * (split - self.hover_split);
        Some((change / self.split_per_mps, self.leg.frame_sigma() / self.split_per_mps))
    }

    /// Horizontal speed of the leg and its standard deviation, m/s, once enough frames were
    /// heard.
    pub fn estimate(&self) -> Option<(f64, f64)> {
        let sigma = self.leg.mean_sigma_mps(self.split_per_mps)?;
        let (lo, hi) = self.clusters()?;
        let change = (hi / lo - 1.0 - self.hover_split).abs();
        Some((change / self.split_per_mps, sigma))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Profile;

    /// A Mini 2 with a 2 % wake loss per m/s (test data: the bundled profile has no wake
    /// constant; a calibrated one would be added by hand).
    fn wake_drone() -> Profile {
        Profile { wake_loss_per_mps: 0.02, ..Profile::dji_mini_2() }
    }

    #[test]
    fn averages_the_leg_and_reports_the_measured_spread() {
        // 1 % excess per m/s, a drone at 1.5 m/s heard with ±1 % frame noise (alternating
        // front and rear groups): the mean is 1.5 m/s and the spread is learnt.
        let mut w = WakeSpeed::new(WakeConfig::default(), 0.01).unwrap();
        assert!(w.estimate().is_none());
        let mut rng = crate::testutil::Rng::new(5);
        for k in 0..200 {
            // The first 1.5 s accelerate: their excess must not count.
            let e = if k < 6 { 0.05 } else { 0.015 + 0.01 * rng.normal() };
            let frame = w.push(k as f64 * 0.25, e);
            assert_eq!(frame.is_some(), k >= 6, "frame {k}: {frame:?}");
            if let Some((v, sigma)) = frame {
                // A frame's own speed: its excess over the coefficient, σ = frame spread / k.
                assert!((v - (e / 0.01).max(0.0)).abs() < 1e-12);
                assert!((sigma - w.frame_sigma() / 0.01).abs() < 1e-12);
            }
        }
        assert!(w.settled());
        let (v, sigma) = w.estimate().unwrap();
        // The window holds window/0.25 + 1 frames: σ of the mean = 1 %/√n per 1 %/(m/s).
        let c = WakeConfig::default();
        let n = (c.window_s / 0.25).floor() + 1.0;
        let expected = (0.01 / n.sqrt() / 0.01).max(c.min_sigma_mps);
        assert!((w.frame_sigma() - 0.01).abs() < 0.003, "{}", w.frame_sigma());
        assert!((sigma - expected).abs() < 0.3 * expected, "{sigma} vs {expected}");
        assert!((v - 1.5).abs() < 3.0 * sigma, "{v} ± {sigma}");
        w.reset();
        assert!(w.estimate().is_none() && !w.settled());
    }

    #[test]
    fn no_coefficient_no_cue() {
        assert!(WakeSpeed::new(WakeConfig::default(), 0.0).is_none());
        assert!(WakeSplit::new(WakeConfig::split(), 0.0).is_none());
    }

    /// Frames of a leg at `v` m/s: front rotors at 328 Hz, rear ones `k`·v above, each frame
    /// hearing the rear group alone (`rear_share` of the frames), the front alone, or both,
    /// with 0.4 Hz of frequency noise and the whole frame scaled by `doppler`.
    fn split_leg(
        v: f64,
        k: f64,
        rear_share: f64,
        doppler: impl Fn(usize) -> f64,
    ) -> (WakeSplit, Vec<Option<(f64, f64)>>) {
        let mut w = WakeSplit::new(WakeConfig::split(), k).unwrap();
        let mut rng = crate::testutil::Rng::new(9);
        let (front, rear) = (328.0, 328.0 * (1.0 + k * v));
        let frames = (0..120)
            .map(|i| {
                let d = doppler(i);
                let mut hz = |f: f64| d * (f + 0.4 * rng.normal());
                let u = (i as f64 * 0.618_034).fract();
                let groups = if i % 4 == 0 {
                    vec![hz(front), hz(rear)]
                } else if u < rear_share {
                    vec![hz(rear)]
                } else {
                    vec![hz(front)]
                };
                w.push(i as f64 * 0.25, &groups)
            })
            .collect();
        (w, frames)
    }

    #[test]
    fn the_split_speed_does_not_depend_on_which_group_is_heard() {
        // The excess of a frame hearing the rear group alone is twice the leg's, of one
        // hearing the front alone zero: a leg mostly heard through its louder rear group
        // reads fast. The split reads each frame against the other group, so the speed stays.
        let k = wake_drone().wake_split_per_mps();
        for rear_share in [0.2, 0.5, 0.8] {
            let (w, frames) = split_leg(1.5, k, rear_share, |_| 1.0);
            // Nothing before the leg settles (1.5 s: frames 0–5).
            assert!(frames[..6].iter().all(Option::is_none), "{rear_share}");
            assert!(frames[8..].iter().all(Option::is_some), "{rear_share}");
            let (v, sigma) = w.estimate().unwrap();
            assert!((v - 1.5).abs() < 3.0 * sigma, "share {rear_share}: {v} ± {sigma}");
            // Frame speeds: unbiased, with the spread they report.
            let speeds: Vec<(f64, f64)> = frames.iter().flatten().copied().collect();
            let mean = speeds.iter().map(|s| s.0).sum::<f64>() / speeds.len() as f64;
            let sd = (speeds.iter().map(|s| (s.0 - mean).powi(2)).sum::<f64>()
                / (speeds.len() - 1) as f64)
                .sqrt();
            assert!((mean - 1.5).abs() < 0.15, "share {rear_share}: frame mean {mean}");
            let reported = speeds.last().unwrap().1;
            assert!((reported / sd - 1.0).abs() < 0.35, "reported {reported} vs spread {sd}");
        }
    }

    #[test]
    fn a_doppler_shift_scales_both_groups_and_leaves_the_split() {
        // ±0.9 % Doppler, more than the 1 % excess at 1.5 m/s: the split speed does not move.
        let k = wake_drone().wake_split_per_mps();
        let (w, _) = split_leg(1.5, k, 0.5, |_| 1.009);
        let (v_up, _) = w.estimate().unwrap();
        let (w, _) = split_leg(1.5, k, 0.5, |_| 0.991);
        let (v_down, sigma) = w.estimate().unwrap();
        assert!((v_up - v_down).abs() < 0.01, "{v_up} vs {v_down}");
        assert!((v_up - 1.5).abs() < 3.0 * sigma, "{v_up} ± {sigma}");
        // Control: read as a thrust excess against the hover BPF, the +0.9 % shift alone would
        // be 2.6 m/s of speed.
        let excess = 1.009f64.powi(2) - 1.0;
        let k_excess = wake_drone().wake_excess_per_mps();
        assert!(excess / k_excess > 2.0, "{}", excess / k_excess);
    }

    #[test]
    fn the_split_coefficient_is_the_wake_model() {
        // Quad X, 2 % loss per m/s, nose-first between arms: the two rear rotors sit 0.707
        // downstream; for equal thrust they spin (1 − 0.02·0.707·1.5)^(−½) times faster.
        let p = wake_drone();
        let ratio = (1.0 - 0.02 * std::f64::consts::FRAC_1_SQRT_2 * 1.5).powf(-0.5);
        let v = (ratio - 1.0) / p.wake_split_per_mps();
        // The coefficient is the linear term: the second-order one reads 1.6 % fast here.
        assert!((v - 1.5).abs() < 0.04, "{v}");
    }

    #[test]
    fn one_group_alone_gives_no_split() {
        // A leg that never resolves two groups (or hears nothing usable) says nothing.
        let mut w = WakeSplit::new(WakeConfig::split(), 0.007).unwrap();
        for i in 0..40 {
            assert!(w.push(i as f64 * 0.25, &[328.0]).is_none());
            assert!(w.push(i as f64 * 0.25 + 0.1, &[f64::NAN]).is_none());
            assert!(w.push(i as f64 * 0.25 + 0.2, &[]).is_none());
        }
        assert!(w.estimate().is_none());
    }

    /// Frames of an imbalanced drone: front rotors at 322 and 326 Hz, rear ones 3.7 % faster
    /// (as a drawn drone of square10-los seed 104 hovers), the rear ones `k`·v further above in
    /// cruise;
    /// each frame hears a pseudo-random subset of the four with 0.3 Hz of noise.
    fn imbalanced_frames(v: f64, k: f64, n: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = crate::testutil::Rng::new(seed);
        let wake = 1.0 + k * v;
        let rotors = [322.0, 326.0, 334.0 * wake, 338.0 * wake];
        (0..n)
            .map(|i| {
                let mask = [0b1111, 0b0011, 0b1100, 0b0101, 0b1010, 0b1001][i % 6];
                let mut groups: Vec<f64> = (0..4)
                    .filter(|b| mask & (1 << b) != 0)
                    .map(|b| rotors[b] + 0.3 * rng.normal())
                    .collect();
                groups.sort_by(f64::total_cmp);
                groups
            })
            .collect()
    }

    #[test]
    fn the_hover_pattern_takes_the_static_imbalance_out_of_the_split() {
        let k = wake_drone().wake_split_per_mps();
        let mut pattern = HoverPattern::default();
        assert!(!pattern.is_calibrated() && pattern.split() == 0.0);
        for groups in imbalanced_frames(0.0, k, 40, 3) {
            pattern.learn(&groups);
        }
        // The four hover rotors are found, and normalised they all read the mean hover BPF.
        let centres = pattern.centres().to_vec();
        assert_eq!(centres.len(), 4, "{centres:?}");
        for (c, truth) in centres.iter().zip([322.0, 326.0, 334.0, 338.0]) {
            assert!((c - truth).abs() < 0.2, "{centres:?}");
        }
        for f in [322.0, 326.0, 334.0, 338.0] {
            assert!((pattern.normalise(f) - 330.0).abs() < 0.2, "{f}: {}", pattern.normalise(f));
        }
        // Oracle: a hover leg reads ~0 m/s, a 1.5 m/s cruise leg 1.5 m/s, against the hover
        // split; without the calibration (control) the hover alone reads as fast cruise.
        let leg = |v: f64, hover_split: Option<f64>| {
            let mut w = WakeSplit::new(WakeConfig::split(), k).unwrap();
            if let Some(s) = hover_split {
                w.set_hover_split(s);
            }
            for (i, groups) in imbalanced_frames(v, k, 80, 11).iter().enumerate() {
                w.push(i as f64 * 0.25, groups);
            }
            w.estimate().unwrap()
        };
        let (v_hover, sigma) = leg(0.0, Some(pattern.split()));
        assert!(v_hover.abs() < 0.2_f64.max(3.0 * sigma), "hover: {v_hover} ± {sigma}");
        let (v_cruise, sigma) = leg(1.5, Some(pattern.split()));
        assert!((v_cruise - 1.5).abs() < 0.25_f64.max(3.0 * sigma), "cruise: {v_cruise} ± {sigma}");
        let (v_uncalibrated, _) = leg(0.0, None);
        assert!(v_uncalibrated > 3.0, "control: {v_uncalibrated}");
    }

    #[test]
    fn too_few_hover_groups_leave_the_frames_alone() {
        let mut pattern = HoverPattern::default();
        pattern.learn(&[324.0, 335.0]);
        assert!(!pattern.is_calibrated());
        assert_eq!(pattern.normalise(335.0), 335.0);
        // A balanced drone: one group, nothing to normalise.
        let mut pattern = HoverPattern::default();
        for _ in 0..10 {
            pattern.learn(&[329.5, f64::NAN, -1.0]);
        }
        assert_eq!(pattern.centres(), &[329.5]);
        assert_eq!(pattern.normalise(331.0), 331.0);
        assert_eq!(pattern.split(), 0.0);
    }
}
