//! Per-array DoA window: IQR smoothing, the motion trend and the line-of-sight decision
//! (paper §V-B, ALGORITHMS.md §4 and §7).
//!
//! The paper asks one variance threshold two questions. Here they are separate:
//! a moving drone makes a smooth *trend* in DoA (the slope of a local linear fit), a blocked
//! line of sight makes *erratic residuals* around that fit, a poor DoA fit residual and low
//! pair quality.

use std::collections::VecDeque;

use crate::iqr::iqr_inliers;
use crate::observation::{wrap_pi, Bearing};

/// Tunables of the DoA window.
#[derive(Clone, Debug, PartialEq)]
pub struct DoaConfig {
    /// Length of the sliding window, s.
    pub window_s: f64,
    /// Minimum inliers for a state.
    pub min_points: usize,
    /// Largest RMS angular residual around the local linear fit still called LoS, rad.
    pub los_max_erratic_rad: f64,
    /// Largest mean DoA fit residual (DSP units) still called LoS; `f64::INFINITY` disables it.
    pub los_max_fit_residual: f64,
    /// Smallest mean pair quality still called LoS; 0 disables it.
    pub los_min_quality: f64,
    /// Smallest fraction of inliers still called LoS (IQR inliers, and bearings within
    /// `los_inlier_floor_rad` of the window's fit).
    pub los_min_inlier_fraction: f64,
    /// A bearing this close to the window's fit (angle on the sky) is an inlier for the LoS
    /// decision whatever the IQR rule says, rad; 0 leaves the IQR rule alone.
    pub los_inlier_floor_rad: f64,
    /// A DoA trend slower than this is "stable", rad/s.
    pub moving_min_rate: f64,
    /// ... and it must also exceed this many standard errors of the slope.
    pub moving_min_sigmas: f64,
}

impl Default for DoaConfig {
    fn default() -> Self {
        Self {
            window_s: 1.0,
            min_points: 2,
            los_max_erratic_rad: 3.0f64.to_radians(),
            los_max_fit_residual: 0.35,
            los_min_quality: 0.35,
            los_min_inlier_fraction: 0.6,
            los_inlier_floor_rad: 1.5f64.to_radians(),
            moving_min_rate: 1.0f64.to_radians(),
            moving_min_sigmas: 3.0,
        }
    }
}

/// What the window says at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoaState {
    /// Time the smoothed bearing refers to, s.
    pub t: f64,
    /// Smoothed azimuth (linear fit evaluated at `t`), rad.
    pub azimuth_rad: f64,
    /// Smoothed zenith, rad.
    pub zenith_rad: f64,
    /// Azimuth rate, rad/s.
    pub azimuth_rate: f64,
    /// Zenith rate, rad/s.
    pub zenith_rate: f64,
    /// Angular speed of the bearing's unit vector, rad/s.
    pub angular_rate: f64,
    /// Standard error of `angular_rate`, rad/s.
    pub angular_rate_sigma: f64,
    /// RMS angular residual of the inliers around the linear fit, rad.
    pub erratic_rad: f64,
    /// Mean DSP fit residual of the inliers.
    pub fit_residual: f64,
    /// Mean pair quality of the inliers.
    pub quality: f64,
    /// Fraction of the window's estimates counted as inliers: kept by the IQR rule, or within
    /// `DoaConfig::los_inlier_floor_rad` of the fit.
    pub inlier_fraction: f64,
    /// Number of inliers.
    pub inliers: usize,
    /// Noise of one bearing per component (azimuth·sin zenith, zenith) around the fit, rad.
    pub noise_rad: f64,
    /// √Σ(t − t̄)² of the inliers' times, s: a slope's standard error is noise / this.
    pub time_spread_s: f64,
    /// Line-of-sight decision.
    pub los: bool,
    /// DoA-trend decision: the drone moves.
    pub moving: bool,
}

/// The trend of a window's bearings for the motion classifier's slow span: a least-squares
/// line per component (azimuth·sin zenith, zenith), fitted again without the bearings that lie
/// beyond 3 robust σ of the first fit (a reflection's bearing), and the same trend over the
/// span's older and newer halves, which a slow drift shows and a step does not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trend {
    /// Angular speed of the bearing's unit vector (least-squares slopes), rad/s.
    pub angular_rate: f64,
    /// The smaller of the two halves' angular rates along the whole span's direction of
    /// motion, rad/s (negative: a half turned the other way; 0 with fewer than two bearings
    /// in a half).
    pub halves_rate: f64,
    /// Noise of one bearing per component (azimuth·sin zenith, zenith) around the refitted
    /// lines: 1.4826 × the median absolute residual of the kept bearings, rad.
    pub noise_rad: f64,
    /// √Σ(t − t̄)² of the kept bearings' times, s: the rate's standard error is noise / this.
    pub time_spread_s: f64,
}

/// A trend's slopes, rad/s: (azimuth·sin zenith, zenith).
type Slopes = (f64, f64);

/// The least-squares slopes of (ts, az, zen) at the indices `keep`, with sin zenith `sin`.
fn slopes(ts: &[f64], az: &[f64], zen: &[f64], keep: &[usize], sin: f64) -> Slopes {
    let sel = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let tk = sel(ts);
    let (_, az_rate, _, _) = line_fit(&tk, &sel(az), 0.0);
    let (_, zen_rate, _, _) = line_fit(&tk, &sel(zen), 0.0);
    (sin * az_rate, zen_rate)
}

/// A sliding window of one array's bearings.
#[derive(Clone, Debug)]
pub struct DoaWindow {
    config: DoaConfig,
    /// How long bearings are kept, s: at least `config.window_s`, longer for a [`Trend`]
    /// over a longer span.
    history_s: f64,
    bearings: VecDeque<Bearing>,
}

/// Least-squares line through (t, y): returns (value at t_eval, slope, RMS residual, Σ(t − t̄)²).
fn line_fit(t: &[f64], y: &[f64], t_eval: f64) -> (f64, f64, Vec<f64>, f64) {
    let n = t.len() as f64;
    let tm = t.iter().sum::<f64>() / n;
    let ym = y.iter().sum::<f64>() / n;
    let stt: f64 = t.iter().map(|ti| (ti - tm) * (ti - tm)).sum();
    let sty: f64 = t.iter().zip(y).map(|(ti, yi)| (ti - tm) * (yi - ym)).sum();
    let slope = if stt > 0.0 { sty / stt } else { 0.0 };
    let residuals = t.iter().zip(y).map(|(ti, yi)| yi - (ym + slope * (ti - tm))).collect();
    (ym + slope * (t_eval - tm), slope, residuals, stt)
}

impl DoaWindow {
    /// An empty window.
    pub fn new(config: DoaConfig) -> Self {
        let history_s = config.window_s;
        Self { config, history_s, bearings: VecDeque::new() }
    }

    /// An empty window that keeps its bearings for `history_s` (s) if that is longer than its
    /// `window_s`, for [`DoaWindow::trend`] over such a span; the states see `window_s` only.
    pub fn with_history(config: DoaConfig, history_s: f64) -> Self {
        let history_s = config.window_s.max(history_s);
        Self { config, history_s, bearings: VecDeque::new() }
    }

    /// The tunables.
    pub fn config(&self) -> &DoaConfig {
        &self.config
    }

    /// Adds a bearing (in time order) and forgets those older than the window's history.
    pub fn push(&mut self, b: Bearing) {
        if !(b.azimuth_rad.is_finite() && b.zenith_rad.is_finite() && b.t.is_finite()) {
            return;
        }
        self.bearings.push_back(b);
        while let Some(first) = self.bearings.front() {
            if first.t < b.t - self.history_s {
                self.bearings.pop_front();
            } else {
                break;
            }
        }
    }

    /// Time of the newest bearing, s.
    pub fn latest_t(&self) -> Option<f64> {
        self.bearings.back().map(|b| b.t)
    }

    /// The bearings from `t − span_s` to `t`, oldest first, with their times, azimuths
    /// unwrapped around the newest one (so the span never straddles ±π) and zeniths.
    fn span(&self, t: f64, span_s: f64) -> (Vec<&Bearing>, [Vec<f64>; 3]) {
        let pts: Vec<&Bearing> =
            self.bearings.iter().filter(|b| b.t >= t - span_s && b.t <= t + 1e-9).collect();
        let reference = pts.last().map_or(0.0, |b| b.azimuth_rad);
        let ts = pts.iter().map(|b| b.t).collect();
        let az = pts.iter().map(|b| reference + wrap_pi(b.azimuth_rad - reference)).collect();
        let zen = pts.iter().map(|b| b.zenith_rad).collect();
        (pts, [ts, az, zen])
    }

    /// The trend of the bearings of the last `span_s` (s, within the window's history) up to
    /// `t` ([`Trend`]), or `None` with fewer than four bearings kept.
    pub fn trend(&self, t: f64, span_s: f64) -> Option<Trend> {
        let (pts, [ts, az, zen]) = self.span(t, span_s.min(self.history_s));
        if pts.len() < 4 {
            return None;
        }
        let all: Vec<usize> = (0..pts.len()).collect();
        // Residuals per component (azimuth·sin zenith, zenith) of the lines through `keep`.
        let residuals = |keep: &[usize]| {
            let sel = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
            let tk = sel(&ts);
            let (za, sa, _, _) = line_fit(&tk, &sel(&az), t);
            let (zz, sz, _, stt) = line_fit(&tk, &sel(&zen), t);
            let sin = zz.clamp(0.0, std::f64::consts::PI).sin();
            let r: Vec<(f64, f64)> = (0..pts.len())
                .map(|i| (sin * (az[i] - za - sa * (ts[i] - t)), zen[i] - zz - sz * (ts[i] - t)))
                .collect();
            (r, sin, stt, (sin * sa, sz))
        };
        let robust_sigma = |r: &[(f64, f64)], keep: &[usize]| {
            let mut abs: Vec<f64> =
                keep.iter().flat_map(|&i| [r[i].0.abs(), r[i].1.abs()]).collect();
            abs.sort_by(f64::total_cmp);
            1.4826 * crate::iqr::quantile_sorted(&abs, 0.5)
        };
        let (r, _, _, _) = residuals(&all);
        let cut = 3.0 * robust_sigma(&r, &all);
        let kept: Vec<usize> =
            all.iter().copied().filter(|&i| r[i].0.abs() <= cut && r[i].1.abs() <= cut).collect();
        let keep = if kept.len() >= 4 { kept } else { all };
        let (r, sin, stt, whole) = residuals(&keep);
        if stt <= 0.0 {
            return None;
        }
        let rate = whole.0.hypot(whole.1);
        // Each half's slopes projected on the whole span's direction of motion.
        let mid = 0.5 * (ts[keep[0]] + ts[keep[keep.len() - 1]]);
        let (older, newer): (Vec<usize>, Vec<usize>) = keep.iter().partition(|&&i| ts[i] < mid);
        let along = |half: &[usize]| {
            if half.len() < 2 || rate <= 0.0 {
                return 0.0;
            }
            let h = slopes(&ts, &az, &zen, half, sin);
            (h.0 * whole.0 + h.1 * whole.1) / rate
        };
        Some(Trend {
            angular_rate: rate,
            halves_rate: along(&older).min(along(&newer)),
            noise_rad: robust_sigma(&r, &keep),
            time_spread_s: stt.sqrt(),
        })
    }

    /// The window's state evaluated at time `t` (normally the newest bearing's time), or
    /// `None` with too few estimates.
    pub fn state(&self, t: f64) -> Option<DoaState> {
        self.state_over(t, self.config.window_s, 0)
    }

    /// The state of the bearings of the last `span_s` seconds up to `t` only, reaching back
    /// further (within the window) until it holds `min_count` bearings: a shorter span
    /// follows a start or a stop sooner, at the price of a larger standard error of the trend
    /// (the `moving` test accounts for it); `min_count` keeps enough bearings for a trend.
    pub fn state_over(&self, t: f64, span_s: f64, min_count: usize) -> Option<DoaState> {
        let c = &self.config;
        let (in_window, [ts, az, zen]) = self.span(t, c.window_s);
        let recent = in_window.iter().filter(|b| b.t >= t - span_s).count();
        let skip = in_window.len() - recent.max(min_count).min(in_window.len());
        let pts = &in_window[skip..];
        if pts.len() < c.min_points {
            return None;
        }
        let (ts, az, zen) = (&ts[skip..], &az[skip..], &zen[skip..]);
        // IQR on the values (the paper's rule), then again on the residuals of a line fit so a
        // steady trend is not mistaken for a spread.
        let (ia, iz) = (iqr_inliers(az), iqr_inliers(zen));
        let mut keep: Vec<usize> = (0..pts.len()).filter(|&i| ia[i] && iz[i]).collect();
        if keep.len() >= c.min_points {
            let sel = |v: &[f64], k: &[usize]| k.iter().map(|&i| v[i]).collect::<Vec<f64>>();
            let (_, _, ra, _) = line_fit(&sel(ts, &keep), &sel(az, &keep), t);
            let (_, _, rz, _) = line_fit(&sel(ts, &keep), &sel(zen, &keep), t);
            let (ma, mz) = (iqr_inliers(&ra), iqr_inliers(&rz));
            let second: Vec<usize> = keep
                .iter()
                .enumerate()
                .filter(|(j, _)| ma[*j] && mz[*j])
                .map(|(_, &i)| i)
                .collect();
            if second.len() >= c.min_points {
                keep = second;
            }
        }
        if keep.len() < c.min_points {
            keep = (0..pts.len()).collect();
        }
        let sel = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let tk = sel(ts);
        let (azimuth, az_rate, ra, stt) = line_fit(&tk, &sel(az), t);
        let (zenith, zen_rate, rz, _) = line_fit(&tk, &sel(zen), t);
        let zenith = zenith.clamp(0.0, std::f64::consts::PI);
        let s = zenith.sin();
        let n = keep.len() as f64;
        let ss: f64 = ra.iter().zip(&rz).map(|(a, z)| (s * a).powi(2) + z * z).sum();
        let erratic = (ss / n).sqrt();
        let angular_rate = ((s * az_rate).powi(2) + zen_rate.powi(2)).sqrt();
        // Standard error of a slope: σ / sqrt(Σ(t − t̄)²), σ per component ≈ erratic/√2.
        let dof = (n - 2.0).max(1.0);
        let sigma_component = (ss / (2.0 * dof)).sqrt();
        let angular_rate_sigma =
            if stt > 0.0 { sigma_component / stt.sqrt() } else { f64::INFINITY };
        let fit_residual = keep.iter().map(|&i| pts[i].residual).sum::<f64>() / n;
        let quality = keep.iter().map(|&i| pts[i].quality).sum::<f64>() / n;
        // A bearing counts as an inlier when the IQR rule kept it or when it lies within
        // `los_inlier_floor_rad` of the fit: with the five or six bearings a window holds, the
        // IQR's fences sit a fraction of a degree apart and reject noise, and a hovering
        // drone in plain sight was flagged NLoS in one fix of ten.
        let floor = c.los_inlier_floor_rad;
        let near_fit = (0..pts.len())
            .filter(|i| {
                keep.contains(i) || {
                    let da = az[*i] - (azimuth + az_rate * (ts[*i] - t));
                    let dz = zen[*i] - (zenith + zen_rate * (ts[*i] - t));
                    (s * da).hypot(dz) <= floor
                }
            })
            .count();
        let inlier_fraction = near_fit as f64 / pts.len() as f64;
        let los = erratic <= c.los_max_erratic_rad
            && fit_residual <= c.los_max_fit_residual
            && quality >= c.los_min_quality
            && inlier_fraction >= c.los_min_inlier_fraction;
        // Too few estimates for a trend: not moving (yet).
        let moving = keep.len() >= 4
            && angular_rate > c.moving_min_rate
            && angular_rate > c.moving_min_sigmas * angular_rate_sigma;
        Some(DoaState {
            t,
            azimuth_rad: wrap_pi(azimuth),
            zenith_rad: zenith,
            azimuth_rate: az_rate,
            zenith_rate: zen_rate,
            angular_rate,
            angular_rate_sigma,
            erratic_rad: erratic,
            fit_residual,
            quality,
            inlier_fraction,
            inliers: keep.len(),
            noise_rad: sigma_component,
            time_spread_s: stt.sqrt(),
            los,
            moving,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::Rng;

    fn bearing(t: f64, az: f64, zen: f64) -> Bearing {
        Bearing { t, array_id: 0, azimuth_rad: az, zenith_rad: zen, residual: 0.0, quality: 5.0 }
    }

    #[test]
    fn slow_trend_recovers_a_drift_drops_a_wild_bearing_and_tells_a_step_by_its_halves() {
        // Nine bearings over 1.5 s (one per 0.17 s, the chip's DoA rate), 0.3° of noise per
        // component (azimuth·sin zenith, zenith).
        let sigma = 0.3f64.to_radians();
        let config = DoaConfig::default();
        let run = |azimuth: &dyn Fn(f64) -> f64, seed: u64| {
            let mut rng = Rng::new(seed);
            let mut w = DoaWindow::with_history(config.clone(), 1.5);
            let mut t = 0.0;
            while t <= 3.0 {
                let az = wrap_pi(azimuth(t) + sigma / 1.3f64.sin() * rng.normal());
                w.push(bearing(t, az, 1.3 + sigma * rng.normal()));
                t += 8192.0 / 48_000.0;
            }
            w.trend(w.latest_t().unwrap(), 1.5).unwrap()
        };
        let sin = 1.3f64.sin();
        let rate = 2.4f64.to_radians();
        for seed in 1..6 {
            // A drift of 2.4°/s in azimuth across ±π: its rate (× sin zenith) within 3 standard
            // errors, both halves turning with it, the noise near the true 0.3°.
            let drift = run(&|t| 3.1 + rate * t, seed);
            let se = sigma / drift.time_spread_s;
            assert!((drift.angular_rate - sin * rate).abs() < 3.0 * se, "seed {seed}: {drift:?}");
            assert!(drift.halves_rate > 0.25 * drift.angular_rate, "seed {seed}: {drift:?}");
            assert!(drift.noise_rad > 0.4 * sigma && drift.noise_rad < 2.0 * sigma, "{drift:?}");
            // The same drift with one bearing 10° off: the refit leaves it out.
            let wild =
                run(&|t| 3.1 + rate * t + if (t - 2.5).abs() < 0.09 { 0.17 } else { 0.0 }, seed);
            assert!((wild.angular_rate - sin * rate).abs() < 3.0 * se, "seed {seed}: {wild:?}");
            // A still bearing that steps 3° in the span's middle: a least-squares slope, but
            // halves that barely turn.
            let step = run(&|t| 0.5 + if t >= 2.25 { 3f64.to_radians() } else { 0.0 }, seed);
            assert!(step.angular_rate > 1f64.to_radians(), "seed {seed}: {step:?}");
            assert!(step.halves_rate < 0.25 * step.angular_rate, "seed {seed}: {step:?}");
        }
    }

    #[test]
    fn trend_noise_and_outliers_are_told_apart() {
        let mut rng = Rng::new(7);
        let sigma = 0.5f64.to_radians();
        // A steady trend of 5°/s in azimuth near ±π (wrap) with noise and 10 % wild outliers.
        let mut w = DoaWindow::new(DoaConfig::default());
        let rate = 5.0f64.to_radians();
        for k in 0..50 {
            let t = k as f64 * 0.02;
            let mut az = 3.1 + rate * t + sigma * rng.normal();
            if k % 10 == 3 {
                az += 0.8;
            }
            w.push(bearing(t, wrap_pi(az), 1.2 + sigma * rng.normal()));
        }
        let s = w.state(0.98).unwrap();
        assert!(s.moving && s.los, "{s:?}");
        assert!((s.azimuth_rate - rate).abs() < 1.5f64.to_radians(), "{s:?}");
        assert!(wrap_pi(s.azimuth_rad - (3.1 + rate * 0.98)).abs() < 1.0f64.to_radians(), "{s:?}");
        assert!(s.inlier_fraction < 0.95 && s.inlier_fraction > 0.8, "{s:?}");

        // Stationary source, same noise: stable and LoS.
        let mut w = DoaWindow::new(DoaConfig::default());
        for k in 0..50 {
            w.push(bearing(
                k as f64 * 0.02,
                0.5 + sigma * rng.normal(),
                1.2 + sigma * rng.normal(),
            ));
        }
        let s = w.state(0.98).unwrap();
        assert!(!s.moving && s.los, "{s:?}");

        // Erratic bearings (a reflection that wanders by ±8°): NLoS.
        let mut w = DoaWindow::new(DoaConfig::default());
        for k in 0..50 {
            w.push(bearing(k as f64 * 0.02, 0.5 + 0.14 * rng.normal(), 1.2 + 0.14 * rng.normal()));
        }
        assert!(!w.state(0.98).unwrap().los);
    }

    #[test]
    fn a_still_drone_in_sight_is_in_line_of_sight_with_few_bearings() {
        // The chip's rate: a bearing every 0.17 s, six in the 1 s window, 0.5° of noise. The
        // IQR rule on six values rejects one or two of them by chance.
        let share_los = |config: DoaConfig| {
            let mut rng = Rng::new(3);
            let sigma = 0.5f64.to_radians();
            let mut w = DoaWindow::new(config);
            let (mut los, mut states) = (0, 0);
            for k in 0..600 {
                let t = k as f64 * 8192.0 / 48_000.0;
                w.push(bearing(t, 0.9 + sigma * rng.normal(), 1.23 + sigma * rng.normal()));
                if k >= 6 {
                    los += usize::from(w.state(t).unwrap().los);
                    states += 1;
                }
            }
            los as f64 / states as f64
        };
        let with = share_los(DoaConfig::default());
        assert!(with > 0.99, "{with}");
        let without = share_los(DoaConfig { los_inlier_floor_rad: 0.0, ..DoaConfig::default() });
        assert!(without < 0.95, "{without}");
    }
}
