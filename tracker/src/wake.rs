//! Cruise speed from the wake: the rear rotors, working in the front rotors' wake, spin faster
//! the faster the drone flies (paper §VII-C, ALGORITHMS.md §5), so the thrust excess
//! ρ − 1 = Σ BPF² / Σ_hover − 1 grows with speed.
//!
//! One spectrum frame is a poor measurement of it: the DSP resolves the front and rear groups
//! (≈ 1 % apart at 1.5 m/s) only some of the time, and a frame that hears one of them alone
//! reads the excess of that group. So the estimate averages the frames of the current leg over
//! a window, and its standard deviation comes from the frame-to-frame spread *measured in
//! cruise* (a running estimate), not from the much smaller spread at hover.

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

/// Speed from the wake excess of one horizontal leg.
#[derive(Clone, Debug)]
pub struct WakeSpeed {
    config: WakeConfig,
    /// Excess per m/s: wake loss × Σ downstream / N.
    excess_per_mps: f64,
    /// (time s, excess) of the current leg's frames.
    frames: VecDeque<(f64, f64)>,
    /// Time of the leg's first frame, s.
    leg_start: Option<f64>,
    /// Running frame-to-frame variance of the excess in cruise.
    frame_var: f64,
}

impl WakeSpeed {
    /// An estimator for a drone whose excess grows by `excess_per_mps` per m/s; `None` when
    /// the profile gives no wake coefficient (the cue is then unavailable).
    pub fn new(config: WakeConfig, excess_per_mps: f64) -> Option<Self> {
        (excess_per_mps > 0.0 && excess_per_mps.is_finite()).then(|| Self {
            frame_var: config.initial_frame_sigma.powi(2),
            config,
            excess_per_mps,
            frames: VecDeque::new(),
            leg_start: None,
        })
    }

    /// The leg is over (or has not begun): forget its frames.
    pub fn reset(&mut self) {
        self.frames.clear();
        self.leg_start = None;
    }

    /// Adds the excess ρ − 1 of a spectrum frame at time `t` (s) heard during the leg and
    /// returns that frame's speed and its standard deviation (m/s) once the leg has settled.
    pub fn push(&mut self, t: f64, excess: f64) -> Option<(f64, f64)> {
        if !(t.is_finite() && excess.is_finite()) {
            return None;
        }
        if t - *self.leg_start.get_or_insert(t) < self.config.settle_s {
            return None;
        }
        if self.frames.len() >= self.config.min_frames {
            let mean = self.mean();
            let g = self.config.spread_gain;
            self.frame_var += g * ((excess - mean).powi(2) - self.frame_var);
        }
        self.frames.push_back((t, excess));
        while self.frames.front().is_some_and(|f| f.0 < t - self.config.window_s) {
            self.frames.pop_front();
        }
        let speed = speed_from_wake(excess, self.excess_per_mps)?;
        Some((speed, self.frame_sigma() / self.excess_per_mps))
    }

    /// True once the leg's first `settle_s` are over and frames are being averaged.
    pub fn settled(&self) -> bool {
        !self.frames.is_empty()
    }

    fn mean(&self) -> f64 {
        self.frames.iter().map(|f| f.1).sum::<f64>() / self.frames.len().max(1) as f64
    }

    /// Frame-to-frame standard deviation of the excess measured so far.
    pub fn frame_sigma(&self) -> f64 {
        self.frame_var.sqrt()
    }

    /// Horizontal speed and its standard deviation, m/s, once enough frames were heard.
    pub fn estimate(&self) -> Option<(f64, f64)> {
        let n = self.frames.len();
        if n < self.config.min_frames {
            return None;
        }
        let v = speed_from_wake(self.mean(), self.excess_per_mps)?;
        let sigma = self.frame_sigma() / (n as f64).sqrt() / self.excess_per_mps;
        Some((v, sigma.max(self.config.min_sigma_mps)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
