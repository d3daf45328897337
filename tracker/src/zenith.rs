//! Site calibration of each array's zenith: what the array reads against where the source is.
//!
//! A planar array in a room cannot resolve the ceiling's (and, off the floor, the floor's)
//! image from the direct sound, so its zenith reads low, by an amount that grows towards the
//! horizon and depends on the room and on where the array sits (BENCHMARKS, "Zenith bias from
//! room reflections": −1° at zenith 30°, −4 to −7° at 65–80° on the floor of a 5 m hall, −10°
//! on a table). The filter cannot learn it in flight: with one array nothing else tells the
//! height. So it is measured once per installation, like the array's position: a source is
//! moved through the room at the heights drones fly at while a reference (a total station,
//! motion capture, marked spots with their times noted) gives where it is, and
//! `aim calibrate FRAMES --reference REF.csv --site SITE.toml` fits the array's **zenith
//! correction**: the median of (measured − true) zenith per 5° of the measured zenith, written
//! into the site file as
//!
//! ```toml
//! [[array]]
//! zenith_correction_deg = [[27.5, -0.8], [32.5, -0.8], ..., [77.5, -4.1]]  # [measured zenith, bias], degrees
//! ```
//!
//! The intake subtracts the bias, linearly interpolated in the measured zenith (held constant
//! beyond the first and last points), from every `Doa` frame's zenith of that array before
//! anything else sees it ([`crate::intake`]). It is a correction of the measurement, so it is
//! an average over the heights and distances the calibration covered: towards the horizon the
//! measured zenith stops following the true one (a far source reads little lower than a nearer
//! one), and there one measured zenith stands for several true ones. The bias is a property of
//! the site, not of the drone: it holds no airframe constant and is fitted on the site's own
//! recording. Frames whose straight path crosses one of the site's `[[obstacle]]` boxes are
//! left out of the fit.

use std::path::Path;

use crate::config::ConfigError;
use crate::observation::Bearing;
use crate::site::Site;

/// Largest bias a correction may give, degrees: more is not a room's image but a broken array
/// or a wrong site file.
pub const MAX_BIAS_DEG: f64 = 30.0;
/// Widest spread a bin may have to give a point by default, degrees ([`FitConfig`]).
pub const MAX_MAD_DEG: f64 = 3.0;

/// One array's zenith correction: points (measured zenith, bias = measured − true), rad, with
/// the measured zenith strictly ascending. Empty: no correction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ZenithCorrection {
    points: Vec<(f64, f64)>,
}

impl ZenithCorrection {
    /// A correction from points `[measured zenith, bias]` in degrees (the site file's form).
    /// The zeniths must be finite, within 0–180° and strictly ascending; the biases finite and
    /// within ±[`MAX_BIAS_DEG`]. The error says which point is wrong.
    pub fn from_degrees(points: &[[f64; 2]]) -> Result<Self, String> {
        for (k, p) in points.iter().enumerate() {
            if !(p[0].is_finite() && (0.0..=180.0).contains(&p[0])) {
                return Err(format!("point {}: zenith {} must be 0 to 180 degrees", k + 1, p[0]));
            }
            if !(p[1].is_finite() && p[1].abs() <= MAX_BIAS_DEG) {
                return Err(format!(
                    "point {}: bias {} must be within ±{MAX_BIAS_DEG} degrees",
                    k + 1,
                    p[1]
                ));
            }
            if k > 0 && p[0] <= points[k - 1][0] {
                return Err(format!(
                    "point {}: zenith {} must be above the previous point's {}",
                    k + 1,
                    p[0],
                    points[k - 1][0]
                ));
            }
        }
        Ok(Self { points: points.iter().map(|p| (p[0].to_radians(), p[1].to_radians())).collect() })
    }

    /// The points as `[measured zenith, bias]` in degrees.
    pub fn to_degrees(&self) -> Vec<[f64; 2]> {
        self.points.iter().map(|&(z, b)| [z.to_degrees(), b.to_degrees()]).collect()
    }

    /// No points: nothing is corrected.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The bias at measured zenith `zenith_rad`, rad: linear between points, the end points'
    /// beyond them, 0 without points.
    pub fn bias(&self, zenith_rad: f64) -> f64 {
        let p = &self.points;
        match p.iter().position(|&(z, _)| z >= zenith_rad) {
            None => p.last().map_or(0.0, |&(_, b)| b),
            Some(0) => p[0].1,
            Some(i) => {
                let ((z0, b0), (z1, b1)) = (p[i - 1], p[i]);
                b0 + (b1 - b0) * (zenith_rad - z0) / (z1 - z0)
            }
        }
    }

    /// A measured zenith, rad, corrected: the measurement minus its bias, kept on the side of
    /// the array's plane it was measured on (0–90° stays within 0–90°, 90–180° within
    /// 90–180°): a correction does not turn a direction over.
    pub fn correct(&self, zenith_rad: f64) -> f64 {
        use std::f64::consts::{FRAC_PI_2, PI};
        let z = zenith_rad - self.bias(zenith_rad);
        if zenith_rad <= FRAC_PI_2 {
            z.clamp(0.0, FRAC_PI_2)
        } else {
            z.clamp(FRAC_PI_2, PI)
        }
    }

    /// The site file's line for this correction (`zenith_correction_deg = [...]`), at 0.01°.
    pub fn to_toml_line(&self) -> String {
        let pts: Vec<String> =
            self.to_degrees().iter().map(|p| format!("[{:.2}, {:.2}]", p[0], p[1])).collect();
        format!("zenith_correction_deg = [{}]", pts.join(", "))
    }
}

/// One bin of a fit: the frames whose measured zenith fell in it.
#[derive(Clone, Debug, PartialEq)]
pub struct Bin {
    /// Centre of the bin, degrees of measured zenith.
    pub centre_deg: f64,
    /// Frames in it.
    pub frames: usize,
    /// Median of (measured − true) zenith, degrees.
    pub median_deg: f64,
    /// Median absolute deviation of (measured − true) around that median, degrees.
    pub mad_deg: f64,
}

impl Bin {
    /// Why this bin gives no point of the correction under `config`, or None when it gives one.
    pub fn no_point(&self, config: &FitConfig) -> Option<&'static str> {
        if self.frames < config.min_frames.max(1) {
            Some("too few frames")
        } else if self.mad_deg.is_nan() || self.mad_deg > config.max_mad_deg {
            Some("too wide a spread")
        } else if !(-MAX_BIAS_DEG..=MAX_BIAS_DEG).contains(&self.median_deg) {
            Some("a bias beyond ±30°: not the room's image (a wrong reference or site file?)")
        } else if !(0.0..=180.0).contains(&self.centre_deg) {
            Some("outside 0–180°")
        } else {
            None
        }
    }
}

/// How [`fit`] bins the frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitConfig {
    /// Width of a bin of measured zenith, degrees.
    pub bin_deg: f64,
    /// Fewest frames a bin needs to give a point.
    pub min_frames: usize,
    /// Largest spread (median absolute deviation of measured − true) a bin may have to give a
    /// point, degrees: a wider one holds frames that locked onto a reflection or came round an
    /// obstacle, and its median is no correction.
    pub max_mad_deg: f64,
}

impl Default for FitConfig {
    fn default() -> Self {
        Self { bin_deg: 5.0, min_frames: 20, max_mad_deg: MAX_MAD_DEG }
    }
}

/// The fit of one array: its correction and the bins behind it (including those with too few
/// frames or too wide a spread to give a point).
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The array.
    pub array_id: u16,
    /// The correction (bins with at least `min_frames` frames and a narrow spread, at their
    /// centres).
    pub correction: ZenithCorrection,
    /// Every bin that had a frame, by measured zenith.
    pub bins: Vec<Bin>,
    /// Frames used (with a reference position in line of sight).
    pub frames: usize,
}

/// Median of a non-empty slice (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    crate::iqr::quantile_sorted(v, 0.5)
}

/// One frame against the reference: measured and true zenith, and the azimuth's error, rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair {
    /// Zenith the array measured, rad.
    pub measured_rad: f64,
    /// Zenith of the reference position, rad.
    pub true_rad: f64,
    /// Measured − reference azimuth, wrapped to ±π, rad (never corrected: it checks that the
    /// reference and the frames agree, [`time_check`]).
    pub azimuth_error_rad: f64,
}

/// The bin of width `width_deg` a measured zenith falls in (bin k spans k·width to
/// (k + 1)·width degrees), shared by [`fit`] and the time check's spread.
fn bin_of(measured_rad: f64, width_deg: f64) -> i64 {
    (measured_rad.to_degrees() / width_deg).floor() as i64
}

/// Fits one array's correction: per bin of the measured zenith, the median of (measured −
/// true). A median, because a frame that locked onto a reflection is an outlier, not noise.
pub fn fit(array_id: u16, pairs: &[Pair], config: FitConfig) -> Fit {
    let width = config.bin_deg.max(0.1);
    let mut bins: std::collections::BTreeMap<i64, Vec<f64>> = Default::default();
    for p in pairs {
        if !(p.measured_rad.is_finite() && p.true_rad.is_finite()) {
            continue;
        }
        let key = bin_of(p.measured_rad, width);
        bins.entry(key).or_default().push((p.measured_rad - p.true_rad).to_degrees());
    }
    let mut out = Vec::new();
    for (key, mut errors) in bins {
        let m = median(&mut errors);
        let mut dev: Vec<f64> = errors.iter().map(|e| (e - m).abs()).collect();
        out.push(Bin {
            centre_deg: (key as f64 + 0.5) * width,
            frames: errors.len(),
            median_deg: m,
            mad_deg: median(&mut dev),
        });
    }
    let points: Vec<[f64; 2]> = out
        .iter()
        .filter(|b| b.no_point(&config).is_none())
        .map(|b| [b.centre_deg, b.median_deg])
        .collect();
    // The bins come in ascending order and `no_point` refuses what `from_degrees` would.
    let correction = match ZenithCorrection::from_degrees(&points) {
        Ok(c) => c,
        Err(e) => unreachable!("a point no_point let through: {e}"),
    };
    Fit { array_id, correction, bins: out, frames: pairs.len() }
}

/// A reference track: where the calibration source was, world ENU m, at times on the arrays'
/// time base (the intake's: the site file's clock offset plus the sample index over the rate).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Reference {
    /// Times, s, strictly ascending.
    pub t: Vec<f64>,
    /// Positions, world ENU m.
    pub position: Vec<[f64; 3]>,
}

impl Reference {
    /// Parses a CSV with a header naming at least the columns `t`, `x`, `y` and `z` (any order,
    /// other columns ignored: `host-sim`'s `truth.csv` is one). An error names the file and
    /// the line.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let err = |line: usize, message: String| ConfigError {
            path: path.to_path_buf(),
            line: Some(line),
            message,
        };
        // A spreadsheet's byte-order mark is not part of the first column's name.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let Some((h, header)) = lines.next() else {
            return Err(err(1, "empty: a header `t,x,y,z` and rows are needed".into()));
        };
        let names: Vec<&str> = header.split(',').map(|n| n.trim().trim_matches('"')).collect();
        let col = |name: &str| {
            names.iter().position(|n| *n == name).ok_or_else(|| {
                err(h + 1, format!("the header has no column `{name}` (it needs t, x, y, z)"))
            })
        };
        let cols = [col("t")?, col("x")?, col("y")?, col("z")?];
        let mut r = Reference::default();
        for (i, line) in lines {
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let mut v = [0.0; 4];
            for (k, &c) in cols.iter().enumerate() {
                let f = fields.get(c).ok_or_else(|| {
                    err(i + 1, format!("{} fields; column {} is missing", fields.len(), c + 1))
                })?;
                v[k] = f.parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| {
                    err(i + 1, format!("`{f}` is not a finite number (column {})", names[c]))
                })?;
            }
            if r.t.last().is_some_and(|&last| v[0] <= last) {
                return Err(err(i + 1, format!("t = {} is not after the row before", v[0])));
            }
            r.t.push(v[0]);
            r.position.push([v[1], v[2], v[3]]);
        }
        if r.t.len() < 2 {
            return Err(err(h + 1, "fewer than two rows: nothing to interpolate".into()));
        }
        Ok(r)
    }

    /// The position at `t`, linearly interpolated; None outside the track or across a gap of
    /// more than `max_gap_s` between rows.
    pub fn at(&self, t: f64, max_gap_s: f64) -> Option<[f64; 3]> {
        let (first, last) = (*self.t.first()?, *self.t.last()?);
        if !(first..=last).contains(&t) || self.t.len() < 2 {
            return None;
        }
        let i = self.t.partition_point(|&x| x <= t).clamp(1, self.t.len() - 1);
        let (t0, t1) = (self.t[i - 1], self.t[i]);
        if t1 - t0 > max_gap_s {
            return None;
        }
        let w = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let (a, b) = (self.position[i - 1], self.position[i]);
        Some([0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * w))
    }
}

/// Largest gap between reference rows a frame may fall in, s.
pub const MAX_REFERENCE_GAP_S: f64 = 1.0;

/// Whether the segment from `a` to `b` passes through the box `[min, max]` (slab test).
fn crosses(a: [f64; 3], b: [f64; 3], min: [f64; 3], max: [f64; 3]) -> bool {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..3 {
        let d = b[k] - a[k];
        if d.abs() < 1e-12 {
            if a[k] < min[k] || a[k] > max[k] {
                return false;
            }
            continue;
        }
        let (u, v) = ((min[k] - a[k]) / d, (max[k] - a[k]) / d);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Each bearing against the reference position at its time, in its array's frame, with the
/// array id. Left out: bearings outside the reference, of an array not in `site`, of a source
/// within 0.3 m of the array (no direction), or whose straight path to the array crosses one
/// of the site's `obstacles` (an obstacle's shadow is not the room's image).
pub fn pairs(
    site: &Site,
    obstacles: &[crate::site::SiteObstacle],
    bearings: &[Bearing],
    reference: &Reference,
) -> Vec<(u16, Pair)> {
    let mut out = Vec::new();
    for b in bearings {
        let Some(pose) = site.array(b.array_id) else { continue };
        let Some(p) = reference.at(b.t, MAX_REFERENCE_GAP_S) else { continue };
        if obstacles.iter().any(|o| crosses(pose.position, p, o.min, o.max)) {
            continue;
        }
        let world = [0, 1, 2].map(|k| p[k] - pose.position[k]);
        let v = pose.to_array(world);
        let r = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if r < 0.3 {
            continue;
        }
        let az_error = b.azimuth_rad - v[1].atan2(v[0]);
        let pair = Pair {
            measured_rad: b.zenith_rad,
            true_rad: (v[2] / r).clamp(-1.0, 1.0).acos(),
            azimuth_error_rad: az_error.sin().atan2(az_error.cos()),
        };
        out.push((b.array_id, pair));
    }
    out
}

/// The bearings a recording of frames gives, through the intake every tracking path uses
/// ([`crate::intake::Intake`], frames in link order), with every array's correction removed
/// first so that the fit sees the zenith as measured; and the intake's counts (frames read,
/// frames of arrays the site does not have, ...), which say why there are none.
pub fn bearings_of<R: std::io::Read>(
    site: &Site,
    source: &mut crate::link::FrameSource<R>,
) -> anyhow::Result<(Vec<Bearing>, crate::intake::IntakeStats)> {
    use crate::intake::{Intake, IntakeConfig, Released};
    use crate::observation::Input;
    let mut raw = site.clone();
    for a in &mut raw.arrays {
        a.zenith_correction = ZenithCorrection::default();
    }
    let mut intake = Intake::new(raw, IntakeConfig::default());
    let mut out = Vec::new();
    let mut sink = |r: Released| {
        if let Released::Input(Input::Bearing(b)) = r {
            out.push(b);
        }
    };
    for frame in source.by_ref() {
        let frame = frame?;
        intake.push(&frame, &mut sink)?;
    }
    intake.finish(&mut sink);
    Ok((out, *intake.stats()))
}

/// Fits every array of `site` that has bearings in `bearings` against `reference`, leaving out
/// what `obstacles` hide.
pub fn calibrate(
    site: &Site,
    obstacles: &[crate::site::SiteObstacle],
    bearings: &[Bearing],
    reference: &Reference,
    config: FitConfig,
) -> Vec<Fit> {
    let all = pairs(site, obstacles, bearings, reference);
    site.arrays
        .iter()
        .filter_map(|a| {
            let mine: Vec<Pair> = all.iter().filter(|p| p.0 == a.id).map(|p| p.1).collect();
            (!mine.is_empty()).then(|| fit(a.id, &mine, config))
        })
        .collect()
}

/// Widest shift of the reference's times [`time_check`] tries, s.
pub const TIME_CHECK_RANGE_S: f64 = 1.0;
/// Step of [`time_check`]'s shifts, s.
pub const TIME_CHECK_STEP_S: f64 = 0.05;
/// A best shift this large or larger, with the spread at no shift
/// [`TIME_CHECK_SPREAD_RATIO`] times the best or more, means the reference's times are off
/// (on a survey of a 5 m hall a reference 0.2 s late moved two points of the fit by 2.2–2.5°,
/// one 0.1 s late two points by 0.8°; a simulated survey's reference clock is up to 50 ms off and
/// the sound reaches the array up to 45 ms after it left the drone).
pub const TIME_CHECK_MAX_SHIFT_S: f64 = 0.15;
/// See [`TIME_CHECK_MAX_SHIFT_S`].
pub const TIME_CHECK_SPREAD_RATIO: f64 = 1.3;
/// Widest spread of the bearings about the reference at its best shift that still describes
/// the same source, degrees (a survey in a 5 m hall: 1.1°): more, and the reference is not of
/// this recording, or the site file's array pose is wrong.
pub const MAX_REFERENCE_SPREAD_DEG: f64 = 6.0;

/// How well a reference agrees with the frames in time ([`time_check`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeCheck {
    /// The shift of the reference's times that fits the frames best, s: the reference reads
    /// this much later than the arrays' time base (subtract it from its `t` to align them).
    pub best_shift_s: f64,
    /// The spread of the bearings about the reference at that shift, degrees.
    pub best_spread_deg: f64,
    /// The spread with the reference as given, degrees.
    pub spread_deg: f64,
}

impl TimeCheck {
    /// Whether the reference's times are off: a best shift of [`TIME_CHECK_MAX_SHIFT_S`] or
    /// more that tightens the spread by [`TIME_CHECK_SPREAD_RATIO`] or more.
    pub fn is_off(&self) -> bool {
        self.best_shift_s.abs() >= TIME_CHECK_MAX_SHIFT_S - 1e-9
            && (self.spread_deg.is_nan()
                || self.spread_deg >= TIME_CHECK_SPREAD_RATIO * self.best_spread_deg)
    }

    /// Ok when the reference describes the frames' source on their time base; otherwise what
    /// is wrong, for an error about `reference` (its file name).
    pub fn verdict(&self, reference: &str) -> Result<(), String> {
        if self.best_spread_deg.is_nan() || self.best_spread_deg > MAX_REFERENCE_SPREAD_DEG {
            return Err(format!(
                "{reference} does not describe the source the arrays heard: their directions \
                 are {:.1}° from it at the median even at its best time shift ({:+.2} s; more \
                 than {MAX_REFERENCE_SPREAD_DEG}° is not a room's image). Is it this \
                 recording's reference, on the arrays' time base within a second, and are the \
                 arrays' position and yaw in the site file right?",
                self.best_spread_deg, self.best_shift_s
            ));
        }
        if self.is_off() {
            // The best shift at the end of the search: the offset may be larger.
            let edge = self.best_shift_s.abs() >= TIME_CHECK_RANGE_S - 1e-9;
            let at_least = if edge { "at least " } else { "" };
            return Err(format!(
                "{reference} does not agree with the frames in time: their directions fit it \
                 best ({:.2}° against {:.2}°) when its times are read {}{:+.2} s off. Put it \
                 on the arrays' time base (subtract {}{:.2} s from its t?) and run again",
                self.best_spread_deg,
                self.spread_deg,
                at_least,
                self.best_shift_s,
                at_least,
                self.best_shift_s
            ));
        }
        Ok(())
    }
}

/// The spread of `pairs` about the reference, degrees: the median over frames of the angle
/// between the measurement and the reference once each array's zenith bias per `bin_deg` of
/// measured zenith is taken out (the bias is what the fit is for; what is left is noise, and
/// the reference's own errors).
fn spread_deg(pairs: &[(u16, Pair)], bin_deg: f64) -> Option<f64> {
    let key = |a: u16, p: &Pair| (a, bin_of(p.measured_rad, bin_deg));
    let mut bins: std::collections::BTreeMap<(u16, i64), Vec<f64>> = Default::default();
    for (a, p) in pairs {
        bins.entry(key(*a, p)).or_default().push(p.measured_rad - p.true_rad);
    }
    let medians: std::collections::BTreeMap<(u16, i64), f64> =
        bins.into_iter().map(|(k, mut v)| (k, median(&mut v))).collect();
    let mut r: Vec<f64> = pairs
        .iter()
        .map(|(a, p)| {
            let dz = p.measured_rad - p.true_rad - medians[&key(*a, p)];
            (p.azimuth_error_rad * p.true_rad.sin()).hypot(dz).to_degrees()
        })
        .collect();
    (r.len() >= 20).then(|| median(&mut r))
}

/// Checks the reference's time base against the frames: the spread of the bearings about the
/// reference ([`spread_deg`]) with the reference's times shifted by −1 to 1 s in 0.05 s steps.
/// A reference that is late or early shows as a best shift away from 0 (the azimuth of a
/// source moving across the array and the zenith of one moving along a spoke both lag). None
/// with fewer than 20 frames against the reference.
pub fn time_check(
    site: &Site,
    obstacles: &[crate::site::SiteObstacle],
    bearings: &[Bearing],
    reference: &Reference,
    bin_deg: f64,
) -> Option<TimeCheck> {
    let bin_deg = bin_deg.max(0.1);
    let at = |shift_s: f64| {
        let shifted: Vec<Bearing> =
            bearings.iter().map(|b| Bearing { t: b.t + shift_s, ..*b }).collect();
        spread_deg(&pairs(site, obstacles, &shifted, reference), bin_deg)
    };
    let spread = at(0.0)?;
    let steps = (TIME_CHECK_RANGE_S / TIME_CHECK_STEP_S).round() as i64;
    let mut best = (0.0, spread);
    for k in (-steps..=steps).filter(|&k| k != 0) {
        let shift = k as f64 * TIME_CHECK_STEP_S;
        if let Some(s) = at(shift) {
            if s < best.1 {
                best = (shift, s);
            }
        }
    }
    Some(TimeCheck { best_shift_s: best.0, best_spread_deg: best.1, spread_deg: spread })
}

/// A site file's lines as TOML sees them: each line's code (comment cut off, strings kept
/// whole) and the depth of brackets open before it, so that a `[` starting a continuation line
/// of a multi-line array is not taken for a table header.
struct SiteLines<'a> {
    lines: Vec<&'a str>,
    code: Vec<&'a str>,
    depth_before: Vec<i64>,
    /// Whether the line starts inside a multi-line string (`"""` or `\'\'\'`) opened above it:
    /// then it is text, never a header or a key.
    in_string_before: Vec<bool>,
    newline: &'static str,
}

impl<'a> SiteLines<'a> {
    fn new(text: &'a str) -> Self {
        let lines: Vec<&str> = text.lines().collect();
        let mut code = Vec::with_capacity(lines.len());
        let mut depth_before = Vec::with_capacity(lines.len());
        let mut in_string_before = Vec::with_capacity(lines.len());
        let mut depth = 0i64;
        // The delimiter of a multi-line string still open at the end of the line above.
        let mut open: Option<&'static str> = None;
        for l in &lines {
            depth_before.push(depth);
            in_string_before.push(open.is_some());
            // Bytes: every delimiter is ASCII, and a cut at `#` is a char boundary.
            let b = l.as_bytes();
            let mut quote = open;
            let mut end = b.len();
            let mut i = 0;
            while i < b.len() {
                let rest = &b[i..];
                match quote {
                    Some(q) => {
                        if q.starts_with('"') && b[i] == b'\\' {
                            i += 2;
                            continue;
                        }
                        if rest.starts_with(q.as_bytes()) {
                            // A multi-line string may end in one or two of its quotes just
                            // before the delimiter (`"""a """"`): the run's last three close it.
                            let run = if q.len() == 3 {
                                rest.iter().take(5).take_while(|&&c| c == q.as_bytes()[0]).count()
                            } else {
                                1
                            };
                            i += run;
                            quote = None;
                            continue;
                        }
                    }
                    None => {
                        if let Some(q) = ["\"\"\"", "\'\'\'", "\"", "\'"]
                            .into_iter()
                            .find(|q| rest.starts_with(q.as_bytes()))
                        {
                            quote = Some(q);
                            i += q.len();
                            continue;
                        }
                        match b[i] {
                            b'#' => {
                                end = i;
                                break;
                            }
                            b'[' => depth += 1,
                            b']' => depth -= 1,
                            _ => {}
                        }
                    }
                }
                i += 1;
            }
            // A one-line string ends with its line; a multi-line one carries on.
            open = quote.filter(|q| q.len() == 3);
            code.push(&l[..end]);
        }
        let newline = if text.contains("\r\n") { "\r\n" } else { "\n" };
        Self { lines, code, depth_before, in_string_before, newline }
    }

    /// Whether line `j` starts outside any value: no bracket and no multi-line string open.
    fn at_top(&self, j: usize) -> bool {
        self.depth_before[j] == 0 && !self.in_string_before[j]
    }

    /// Whether line `j` is a table header (`[...]` or `[[...]]` outside any value).
    fn is_header(&self, j: usize) -> bool {
        self.at_top(j) && self.code[j].trim_start().starts_with('[')
    }

    /// Whether line `j` is a `zenith_correction_deg` key outside any value.
    fn is_correction(&self, j: usize) -> bool {
        self.at_top(j) && self.key(j) == Some("zenith_correction_deg")
    }

    /// The key of line `j` (`key = value`), if it has one.
    fn key(&self, j: usize) -> Option<&'a str> {
        let (k, _) = self.code[j].split_once('=')?;
        Some(k.trim())
    }

    /// Whether line `j`'s value closes on the line (its brackets balance).
    fn closes(&self, j: usize) -> bool {
        self.depth_before.get(j + 1).is_none_or(|&d| d == self.depth_before[j])
    }

    fn join(&self, out: &[String]) -> String {
        let mut s = out.join(self.newline);
        s.push_str(self.newline);
        s
    }
}

/// The error for a `zenith_correction_deg` written over several lines at line `j` (0-based).
fn multi_line(path: &Path, j: usize) -> ConfigError {
    ConfigError {
        path: path.to_path_buf(),
        line: Some(j + 1),
        message: "a zenith_correction_deg over several lines: put it on one line or remove it \
                  before calibrating"
            .into(),
    }
}

/// Site file text with every `zenith_correction_deg` line taken out (each on one line, as
/// [`site_with_corrections`] writes it; other lines, comments and line ends stay as they were),
/// checked by reading it back.
pub fn site_without_corrections(text: &str, path: &Path) -> Result<String, ConfigError> {
    let s = SiteLines::new(text);
    let mut kept = Vec::with_capacity(s.lines.len());
    for (j, l) in s.lines.iter().enumerate() {
        if s.is_correction(j) {
            if !s.closes(j) {
                return Err(multi_line(path, j));
            }
            continue;
        }
        kept.push((*l).to_string());
    }
    let out = s.join(&kept);
    let site = Site::parse(&out, path)?;
    if site.arrays.iter().any(|a| !a.zenith_correction.is_empty()) {
        return Err(ConfigError {
            path: path.to_path_buf(),
            line: None,
            message: "a zenith_correction_deg is left after taking them out".into(),
        });
    }
    Ok(out)
}

/// Site file text with each given array's `zenith_correction_deg` line set (replacing the one
/// it had; an empty correction takes it out; other lines, comments and line ends stay as they
/// were), checked by reading it back: every array parses and carries the correction written (at
/// the line's 0.01°).
pub fn site_with_corrections(
    text: &str,
    path: &Path,
    corrections: &[(u16, ZenithCorrection)],
) -> Result<String, ConfigError> {
    let err = |line: Option<usize>, message: String| ConfigError {
        path: path.to_path_buf(),
        line,
        message,
    };
    let s = SiteLines::new(text);
    let n = s.lines.len();
    let mut out: Vec<String> = Vec::with_capacity(n + corrections.len());
    let mut written = Vec::new();
    let mut i = 0;
    while i < n {
        if !(s.is_header(i) && s.code[i].trim() == "[[array]]") {
            out.push(s.lines[i].to_string());
            i += 1;
            continue;
        }
        let end = (i + 1..n).find(|&j| s.is_header(j)).unwrap_or(n);
        let id = (i + 1..end).find_map(|j| {
            (s.at_top(j) && s.key(j) == Some("id"))
                .then(|| s.code[j].split_once('=')?.1.trim().parse::<u16>().ok())?
        });
        let new = id.and_then(|id| corrections.iter().find(|c| c.0 == id));
        let mut block: Vec<String> = Vec::new();
        for j in i..end {
            if s.is_correction(j) && new.is_some() {
                if !s.closes(j) {
                    return Err(multi_line(path, j));
                }
                continue;
            }
            block.push(s.lines[j].to_string());
        }
        if let Some((id, c)) = new {
            if !c.is_empty() {
                let last = block.iter().rposition(|l| !l.trim().is_empty()).unwrap_or(0);
                block.insert(last + 1, c.to_toml_line());
            }
            written.push(*id);
        }
        out.extend(block);
        i = end;
    }
    if let Some((id, _)) = corrections.iter().find(|c| !written.contains(&c.0)) {
        return Err(err(None, format!("no [[array]] with id = {id} to calibrate")));
    }
    let result = s.join(&out);
    let site = Site::parse(&result, path)?;
    for (id, c) in corrections {
        let got = site.array(*id).map(|a| a.zenith_correction.to_toml_line());
        if got.as_deref() != Some(c.to_toml_line().as_str()) {
            return Err(err(None, format!("array {id}: the correction did not read back")));
        }
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bias_is_interpolated_and_held_beyond_the_ends() {
        let c = ZenithCorrection::from_degrees(&[[30.0, -1.0], [70.0, -5.0]]).unwrap();
        let deg = |z: f64| c.bias(z.to_radians()).to_degrees();
        assert!((deg(50.0) + 3.0).abs() < 1e-9);
        assert!((deg(10.0) + 1.0).abs() < 1e-9 && (deg(85.0) + 5.0).abs() < 1e-9);
        assert!((c.correct(70f64.to_radians()).to_degrees() - 75.0).abs() < 1e-9);
        assert_eq!(ZenithCorrection::default().correct(0.7), 0.7);
    }

    #[test]
    fn a_bad_point_is_named() {
        let e = ZenithCorrection::from_degrees(&[[30.0, -1.0], [30.0, -2.0]]).unwrap_err();
        assert!(e.contains("point 2") && e.contains("above"), "{e}");
        let e = ZenithCorrection::from_degrees(&[[30.0, 45.0]]).unwrap_err();
        assert!(e.contains("bias 45"), "{e}");
        let e = ZenithCorrection::from_degrees(&[[f64::NAN, 0.0]]).unwrap_err();
        assert!(e.contains("point 1"), "{e}");
    }

    /// The oracle: frames whose measured zenith is the true one plus a known bias curve, noise
    /// and outliers; the fit recovers the curve within a tenth of a degree where frames are.
    #[test]
    fn the_fit_recovers_a_known_bias_despite_outliers() {
        let truth_bias = |z_true_deg: f64| -0.1 * (z_true_deg - 20.0).max(0.0);
        let mut pairs = Vec::new();
        let mut state = 12345u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for k in 0..20_000 {
            let z = 10.0 + 75.0 * uniform();
            let noise = 0.5 * (uniform() - 0.5);
            let outlier = if k % 10 == 0 { 25.0 * (uniform() - 0.5) } else { 0.0 };
            let measured = z + truth_bias(z) + noise + outlier;
            pairs.push(Pair {
                measured_rad: measured.to_radians(),
                true_rad: z.to_radians(),
                azimuth_error_rad: 0.0,
            });
        }
        let f = fit(1, &pairs, FitConfig::default());
        assert!(f.correction.to_degrees().len() >= 12, "{:?}", f.bins);
        for p in f.correction.to_degrees() {
            if !(25.0..=75.0).contains(&p[0]) {
                continue;
            }
            // The measured zenith m = z − 0.1 (z − 20) for z > 20: z = (m − 2) / 0.9.
            let z = (p[0] - 2.0) / 0.9;
            let want = p[0] - z;
            assert!((p[1] - want).abs() < 0.1, "at {}: {} against {want}", p[0], p[1]);
        }
        // Corrected, a measurement lands on its truth.
        let m = 60.0 + truth_bias(60.0);
        assert!((f.correction.correct(m.to_radians()).to_degrees() - 60.0).abs() < 0.15);
    }

    /// A frame at true zenith `z` measured `e` off, degrees.
    fn pair(z: f64, e: f64) -> Pair {
        Pair {
            measured_rad: (z + e).to_radians(),
            true_rad: z.to_radians(),
            azimuth_error_rad: 0.0,
        }
    }

    #[test]
    fn a_bin_with_too_few_frames_or_too_wide_a_spread_gives_no_point() {
        let mut pairs: Vec<Pair> = (0..25).map(|_| pair(43.0, -2.0)).collect();
        pairs.extend((0..25).map(|_| pair(54.0, -3.0)));
        pairs.extend((0..5).map(|_| pair(65.0, -4.0)));
        // One measured zenith standing for true zeniths 4° either side of it: too wide.
        pairs.extend((0..30).map(|k| if k % 2 == 0 { pair(74.0, 4.0) } else { pair(82.0, -4.0) }));
        let f = fit(1, &pairs, FitConfig::default());
        assert_eq!(f.bins.len(), 4, "{:?}", f.bins);
        let pts = f.correction.to_degrees();
        let want = [[42.5, -2.0], [52.5, -3.0]];
        assert_eq!(pts.len(), 2, "{pts:?}");
        assert!(pts.iter().zip(want).all(|(p, w)| (0..2).all(|k| (p[k] - w[k]).abs() < 1e-9)));
    }

    #[test]
    fn a_path_through_an_obstacle_is_left_out() {
        let (min, max) = ([4.0, -1.0, 0.0], [5.0, 1.0, 2.0]);
        assert!(crosses([0.0, 0.0, 0.05], [8.0, 0.0, 1.5], min, max));
        assert!(!crosses([0.0, 0.0, 0.05], [8.0, 0.0, 5.0], min, max), "above it");
        assert!(!crosses([0.0, 0.0, 0.05], [3.0, 0.0, 1.5], min, max), "short of it");
        assert!(!crosses([0.0, 0.0, 0.05], [0.0, 8.0, 1.5], min, max), "beside it");
    }

    #[test]
    fn a_reference_is_read_by_its_header_and_its_errors_name_the_line() {
        let p = Path::new("ref.csv");
        let r = Reference::parse("t,x,y,z,extra\n0,0,0,1,a\n1,2,0,1,b\n", p).unwrap();
        assert_eq!(r.at(0.5, 2.0), Some([1.0, 0.0, 1.0]));
        assert_eq!(r.at(1.5, 2.0), None);
        assert_eq!(r.at(0.5, 0.5), None, "a gap longer than allowed");
        let e = Reference::parse("t,x,y\n0,0,0\n", p).unwrap_err().to_string();
        assert!(e.contains("ref.csv:1") && e.contains("`z`"), "{e}");
        let e = Reference::parse("t,x,y,z\n0,0,0,1\n1,0,zz,1\n", p).unwrap_err().to_string();
        assert!(e.contains("ref.csv:3") && e.contains("zz"), "{e}");
        let e = Reference::parse("t,x,y,z\n1,0,0,1\n1,0,0,1\n", p).unwrap_err().to_string();
        assert!(e.contains("ref.csv:3") && e.contains("not after"), "{e}");
    }

    #[test]
    fn a_site_gets_its_corrections_and_keeps_the_rest() {
        let text = "# a site\nsample_rate_hz = 48000\n\n[[array]]\nid = 1\nposition = [0.0, 0.0, 0.05]\nzenith_correction_deg = [[10.0, 1.0]]\n\n[[array]]\nid = 2 # east\nposition = [5.0, 0.0, 0.05]\n\n[room]\nsize = [10.0, 10.0, 4.0]\n";
        let p = Path::new("site.toml");
        let c1 = ZenithCorrection::from_degrees(&[[30.0, -1.0], [70.0, -5.0]]).unwrap();
        let c2 = ZenithCorrection::from_degrees(&[[50.0, -2.5]]).unwrap();
        let out = site_with_corrections(text, p, &[(1, c1.clone()), (2, c2.clone())]).unwrap();
        let site = Site::parse(&out, p).unwrap();
        assert_eq!(site.array(1).unwrap().zenith_correction, c1);
        assert_eq!(site.array(2).unwrap().zenith_correction, c2);
        assert!(out.starts_with("# a site\n") && out.contains("id = 2 # east"), "{out}");
        assert_eq!(out.matches("zenith_correction_deg").count(), 2, "{out}");
        assert!(out.contains("zenith_correction_deg = [[30.00, -1.00], [70.00, -5.00]]"));
        let e = site_with_corrections(text, p, &[(3, c1)]).unwrap_err().to_string();
        assert!(e.contains("id = 3"), "{e}");
        // A bad correction in a site file is reported at its line.
        let bad = text.replace("[[10.0, 1.0]]", "[[10.0, 1.0], [5.0, 1.0]]");
        let e = Site::parse(&bad, p).unwrap_err().to_string();
        assert!(e.contains("site.toml:7") && e.contains("point 2"), "{e}");
        let bad = text.replace("[[10.0, 1.0]]", "[[10.0, 1.0, 2.0]]");
        let e = Site::parse(&bad, p).unwrap_err().to_string();
        assert!(e.contains("site.toml:7") && e.contains("two numbers (got 3)"), "{e}");
        // And taken out again.
        let bare = site_without_corrections(&out, p).unwrap();
        assert!(!bare.contains("zenith_correction_deg") && bare.contains("id = 2 # east"));
    }

    #[test]
    fn a_bin_beyond_the_largest_bias_gives_no_point_and_a_correction_stays_on_its_side() {
        let mut pairs: Vec<Pair> = (0..25).map(|_| pair(43.0, -2.0)).collect();
        pairs.extend((0..25).map(|_| pair(90.0, -35.0)));
        let f = fit(1, &pairs, FitConfig::default());
        let pts = f.correction.to_degrees();
        assert!(pts.len() == 1 && (pts[0][0] - 42.5).abs() < 1e-9, "{:?}", f.bins);
        assert!((pts[0][1] + 2.0).abs() < 1e-9, "{pts:?}");
        let far = f.bins.iter().find(|b| (b.centre_deg - 57.5).abs() < 1e-9).unwrap();
        assert!(far.no_point(&FitConfig::default()).unwrap().contains("30°"), "{far:?}");
        // A −12° bias at 80° would put a measured 85° below the array's plane: held at 90°.
        let c = ZenithCorrection::from_degrees(&[[80.0, -12.0]]).unwrap();
        assert!((c.correct(85f64.to_radians()).to_degrees() - 90.0).abs() < 1e-9);
        let c = ZenithCorrection::from_degrees(&[[5.0, 3.0]]).unwrap();
        assert_eq!(c.correct(2f64.to_radians()), 0.0);
    }

    /// A site with one array at the origin, level, and bearings of a source flying a square
    /// at 2 m/s around it (measured with a bias of −2° in zenith), against its reference.
    fn square_flight() -> (Site, Vec<Bearing>, Reference) {
        let site = Site::parse(
            "sample_rate_hz = 48000\n[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n",
            Path::new("site.toml"),
        )
        .unwrap();
        let at = |t: f64| {
            // A 16 m square side, centred on the array at 3–5 m out, at 2 m height.
            let u = (t * 2.0 / 16.0).rem_euclid(4.0);
            let (k, f) = (u.floor(), u.fract());
            let corners = [[-4.0, -4.0], [4.0, -4.0], [4.0, 4.0], [-4.0, 4.0], [-4.0, -4.0]];
            let (a, b) = (corners[k as usize], corners[k as usize + 1]);
            [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, 2.0 + 0.5 * (t / 7.0).sin()]
        };
        let mut reference = Reference::default();
        for k in 0..=6000 {
            let t = f64::from(k) * 0.01;
            reference.t.push(t);
            reference.position.push(at(t));
        }
        let bearings = (5..590)
            .map(|k| {
                let t = f64::from(k) * 0.1;
                let p = at(t);
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                Bearing {
                    t,
                    array_id: 1,
                    azimuth_rad: p[1].atan2(p[0])
                        + 0.3f64.to_radians() * (f64::from(k) * 1.7).sin(),
                    zenith_rad: (p[2] / r).acos() - 2f64.to_radians(),
                    residual: 0.0,
                    quality: 1.0,
                }
            })
            .collect();
        (site, bearings, reference)
    }

    /// The oracle: the reference's times moved by a known amount; the check finds that amount
    /// and says the times are off, and says nothing of the reference as it is.
    #[test]
    fn a_reference_off_in_time_is_found() {
        let (site, bearings, reference) = square_flight();
        let check = time_check(&site, &[], &bearings, &reference, 5.0).unwrap();
        assert_eq!(check.best_shift_s, 0.0, "{check:?}");
        assert!(!check.is_off(), "{check:?}");
        for shift in [0.5, -0.6] {
            let late = Reference {
                t: reference.t.iter().map(|t| t + shift).collect(),
                position: reference.position.clone(),
            };
            let check = time_check(&site, &[], &bearings, &late, 5.0).unwrap();
            assert!((check.best_shift_s - shift).abs() < 0.051, "{shift}: {check:?}");
            assert!(check.is_off(), "{shift}: {check:?}");
            assert!(check.verdict("ref.csv").unwrap_err().contains("in time"), "{check:?}");
        }
        assert_eq!(check.verdict("ref.csv"), Ok(()), "{check:?}");
        // Another flight's reference (ten seconds off: beyond the search) does not describe
        // this one at all.
        let other = Reference {
            t: reference.t.iter().map(|t| t + 10.0).collect(),
            position: reference.position.clone(),
        };
        let check = time_check(&site, &[], &bearings, &other, 5.0).unwrap();
        assert!(check.verdict("ref.csv").unwrap_err().contains("does not describe"), "{check:?}");
        // The fit, on the reference as it is, finds the −2°.
        let fits = calibrate(&site, &[], &bearings, &reference, FitConfig::default());
        assert!(fits[0].correction.to_degrees().iter().all(|p| (p[1] + 2.0).abs() < 0.05));
    }

    #[test]
    fn the_site_rewrite_reads_toml_not_lines() {
        let p = Path::new("site.toml");
        // A multi-line array whose continuation lines start with `[`, a header with a
        // comment, a one-line empty correction, CRLF line ends.
        let text = "sample_rate_hz = 48000\r\n[[array]]  # north\r\nid = 1\r\nposition = [0.0, 0.0, 0.05]\r\npositions = [\r\n  [0.05, 0.0],\r\n  [0.0, 0.05],\r\n  [-0.05, 0.0],\r\n  [0.0, -0.05],\r\n]\r\nzenith_correction_deg = []\r\n\r\n[[array]]\r\nid = 2\r\nposition = [5.0, 0.0, 0.05]\r\nzenith_correction_deg = [[40.0, -1.0]]\r\n";
        check_rewrite(text, p, 0);
        // A multi-line string holding what looks like a header and a correction is text.
        let text = "sample_rate_hz = 48000\n[[obstacle]]\nname = \"\"\"shelf\n[[array]]\nzenith_correction_deg = [[10.0, 9.0]]\n\"\"\"\nmin = [1.0, 1.0, 0.0]\nmax = [2.0, 2.0, 1.0]\n[[array]]  # north\nid = 1\nposition = [0.0, 0.0, 0.05]\npositions = [[0.05, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]]\n[[array]]\nid = 2\nposition = [5.0, 0.0, 0.05]\nzenith_correction_deg = [[40.0, -1.0]]\n[[obstacle]]\nname = '''\nzenith_correction_deg = [[1.0, 2.0]]'''\nmin = [3.0, 1.0, 0.0]\nmax = [4.0, 2.0, 1.0]\n".replace('\n', "\r\n");
        check_rewrite(&text, p, 2);
        let out = site_with_corrections(&text, p, &[(1, ZenithCorrection::default())]).unwrap();
        let kept = "name = \"\"\"shelf\r\n[[array]]\r\nzenith_correction_deg = [[10.0, 9.0]]\r\n\"\"\"\r\n";
        assert!(out.contains(kept), "{out}");
        let bare = site_without_corrections(&text, p).unwrap();
        assert!(bare.contains("zenith_correction_deg = [[10.0, 9.0]]"), "{bare}");
        assert!(bare.contains("zenith_correction_deg = [[1.0, 2.0]]'''"), "{bare}");
        assert_eq!(bare.matches("zenith_correction_deg").count(), 2, "{bare}");
    }

    #[test]
    fn a_multi_line_string_may_end_in_its_own_quotes() {
        let p = Path::new("site.toml");
        // `""""`: the text ends in a quote; the comment after it, with its bracket, is a comment.
        let text = "sample_rate_hz = 48000\n[[obstacle]]\nname = \"\"\"say \"hi\"\"\"\"  # a 5\" shelf [old\nmin = [1.0, 1.0, 0.0]\nmax = [2.0, 2.0, 1.0]\n[[array]]\nid = 1\nposition = [0.0, 0.0, 0.05]\npositions = [[0.05, 0.0], [0.0, 0.05], [-0.05, 0.0], [0.0, -0.05]]\n";
        Site::parse(text, p).unwrap();
        let c = ZenithCorrection::from_degrees(&[[30.0, -1.0], [70.0, -5.0]]).unwrap();
        let out = site_with_corrections(text, p, &[(1, c.clone())]).unwrap();
        assert_eq!(Site::parse(&out, p).unwrap().array(1).unwrap().zenith_correction, c);
    }

    /// `in_strings`: how many `zenith_correction_deg` of `text` are inside strings (they stay).
    fn check_rewrite(text: &str, p: &Path, in_strings: usize) {
        Site::parse(text, p).unwrap();
        let c1 = ZenithCorrection::from_degrees(&[[30.0, -1.0], [70.0, -5.0]]).unwrap();
        let out = site_with_corrections(text, p, &[(1, c1.clone())]).unwrap();
        let site = Site::parse(&out, p).unwrap();
        assert_eq!(site.array(1).unwrap().zenith_correction, c1);
        assert_eq!(site.array(2).unwrap().zenith_correction.to_degrees(), vec![[40.0, -1.0]]);
        assert!(!out.replace("\r\n", "").contains('\n'), "a bare LF: {out:?}");
        assert!(out.contains("[[array]]  # north\r\n"), "{out:?}");
        // An empty correction takes array 2's out; the rest stays.
        let out = site_with_corrections(&out, p, &[(2, ZenithCorrection::default())]).unwrap();
        let site = Site::parse(&out, p).unwrap();
        assert!(site.array(2).unwrap().zenith_correction.is_empty(), "{out:?}");
        assert_eq!(site.array(1).unwrap().zenith_correction, c1);
        let bare = site_without_corrections(&out, p).unwrap();
        assert_eq!(bare.matches("zenith_correction_deg").count(), in_strings, "{bare:?}");
        assert!(bare.contains("\r\n"), "{bare:?}");
    }
}
