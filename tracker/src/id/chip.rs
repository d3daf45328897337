//! The classifier's input from what the chip sends: `Mfcc` frames (aim-dsp `idframe`, one per
//! 0.256 s BPF analysis of 0.512 s) aggregated over a window of [`WINDOW_FRAMES`] frames.
//!
//! Live (`aim track`, `aim replay`), the window is the tracked array's last [`WINDOW_FRAMES`]
//! frames; for training and evaluation (`aim id ... --features chip`), a recording runs
//! through the very pipeline the chip runs ([`frames_of_recording`]: aim-dsp at the
//! recording's rate, its mono signal on every microphone, outputs quantised by
//! `aim_wire::from_dsp`), so a model sees the numbers the link carries, bit for bit.
//!
//! Per window, in this order ([`names`]):
//! - MFCC c1..c12: mean and standard deviation over the frames (24; c0, the level, is dropped);
//! - log-mel bands minus the frame's mean band level, mean over the frames (24);
//! - comb features: median fundamental (octaves re 250 Hz), its standard deviation, mean
//!   salience, half-, third-way levels and harmonic envelope (10);
//! - the fundamental, half-, third-way levels and envelope averaged with weights
//!   `max(0, salience − 3 dB)²` (8), the largest salience (1) and the share of frames whose
//!   fundamental is within 1/12 octave of the previous frame's (1);
//! - the spectral flux (mean absolute frame-to-frame change of the level-free log-mel, dB; 1);
//! - the same 20 comb numbers for the second comb (`Mfcc::second_harmonic`: the strongest
//!   comb of another source, so a drone beside a louder fan or pump is still described).
use super::clip::mean_sd;
use aim_dsp::{Config, Geometry, Output, Pipeline};
use aim_wire::{Mfcc, MFCC_COEFFS, MFCC_HARMONIC, MFCC_MEL_BANDS};

/// Frames per classification window: five 0.256 s hops plus the 0.512 s analysis window, 1.79
/// s of audio (a 2 s clip at 16 kHz gives 6 frames).
pub const WINDOW_FRAMES: usize = 6;
/// Fewest frames a window may have.
pub const MIN_FRAMES: usize = 2;
/// Length of a window's feature vector.
pub const FEATURES: usize =
    2 * (MFCC_COEFFS - 1) + MFCC_MEL_BANDS + 2 * (MFCC_HARMONIC + 1 + MFCC_HARMONIC - 1 + 2) + 1;

/// Names of the features, in vector order (prefixed `chip_`: a model records them, and one
/// made for the 16 kHz clip features is not mistaken for one of these).
pub fn names() -> Vec<String> {
    let mut v = super::clip::spectral_names("chip_", MFCC_COEFFS, MFCC_MEL_BANDS);
    comb_names(&mut v, "chip_");
    v.push("chip_log_mel_flux_db".into());
    comb_names(&mut v, "chip_second_");
    debug_assert_eq!(v.len(), FEATURES);
    v
}

/// Names of [`comb_features`]' numbers, each prefixed `prefix`.
fn comb_names(v: &mut Vec<String>, prefix: &str) {
    let h = super::clip::HARMONIC_NAMES;
    v.push(format!("{prefix}log2_f0_median"));
    v.push(format!("{prefix}log2_f0_sd"));
    for n in &h[1..] {
        v.push(format!("{prefix}{n}_mean"));
    }
    for n in h.iter().filter(|n| **n != "salience_db") {
        v.push(format!("{prefix}weighted_{n}"));
    }
    v.push(format!("{prefix}salience_max_db"));
    v.push(format!("{prefix}f0_continuity"));
}

/// A comb's numbers over a window (`h`: per frame, `Mfcc::harmonic_values` or
/// `Mfcc::second_harmonic_values`): median fundamental, its standard deviation, the mean of
/// the other eight, the fundamental and those but the salience weighted by
/// `max(0, salience − 3 dB)²`, the largest salience and the share of frames whose fundamental
/// is within 1/12 octave of the previous frame's.
fn comb_features(v: &mut Vec<f32>, h: &[[f32; MFCC_HARMONIC]]) {
    super::clip::comb_stats(v, h);
    super::clip::comb_weighted(v, h);
    v.push(h.iter().map(|a| a[1]).fold(0.0, f32::max));
    v.push(super::clip::f0_continuity(h));
}

/// The feature vector of a window of frames (oldest first; at least one).
pub fn features(frames: &[Mfcc]) -> Vec<f32> {
    let mut v = Vec::with_capacity(FEATURES);
    let stats: Vec<(f32, f32)> =
        (1..MFCC_COEFFS).map(|c| mean_sd(frames.iter().map(move |f| f.mfcc_db(c)))).collect();
    v.extend(stats.iter().map(|s| s.0));
    v.extend(stats.iter().map(|s| s.1));
    let rel = |f: &Mfcc| -> [f32; MFCC_MEL_BANDS] {
        let l: [f32; MFCC_MEL_BANDS] = core::array::from_fn(|b| f.log_mel_db(b));
        let m = l.iter().sum::<f32>() / MFCC_MEL_BANDS as f32;
        l.map(|x| x - m)
    };
    let rels: Vec<[f32; MFCC_MEL_BANDS]> = frames.iter().map(rel).collect();
    for b in 0..MFCC_MEL_BANDS {
        v.push(mean_sd(rels.iter().map(move |r| r[b])).0);
    }
    let h: Vec<[f32; MFCC_HARMONIC]> = frames.iter().map(Mfcc::harmonic_values).collect();
    comb_features(&mut v, &h);
    let pairs = frames.len().saturating_sub(1).max(1) as f32;
    let flux: f32 = rels
        .windows(2)
        .map(|p| p[0].iter().zip(&p[1]).map(|(x, y)| (x - y).abs()).sum::<f32>())
        .sum::<f32>()
        / (MFCC_MEL_BANDS as f32 * pairs);
    v.push(flux);
    // Frames of firmware without the second comb read as none found (`aim track` does not
    // classify them: `session::Identifier::push`).
    let second: Vec<[f32; MFCC_HARMONIC]> =
        frames.iter().map(|f| f.second_harmonic_values().unwrap_or_default()).collect();
    comb_features(&mut v, &second);
    debug_assert_eq!(v.len(), FEATURES);
    v
}

/// The `Mfcc` frames the chip sends for a mono recording at `rate_hz` (16 or 48 kHz; samples
/// as fractions of full scale, clipped to ±1): the signal on every microphone of a 4-mic
/// array, 24-bit words, through [`aim_dsp::Pipeline`] with its defaults, each output quantised
/// by `aim_wire::from_dsp::mfcc`, with the sample index its frame header would carry. The
/// first frame covers the first 0.512 s.
pub fn frames_of_recording(mono: &[f32], rate_hz: u32) -> anyhow::Result<Vec<(u64, Mfcc)>> {
    frames_of_arrival(mono, rate_hz, None)
}

/// Speed of sound for [`Arrival`]'s delays, m/s.
pub const SOUND_SPEED_MPS: f32 = 343.0;
/// Half-length of [`Arrival`]'s fractional-delay filters, taps (each has `2·HALF_TAPS + 1`).
const HALF_TAPS: usize = 16;

/// A plane wave reaching an array from one direction. The chip's spectral features are made
/// from the mean of its microphones, and that mean low-passes a sound arriving from the side
/// (a 6-mic circle of 4.6 cm radius: −9 dB at 2.5 kHz from the horizon, nothing from
/// overhead). A recording made with one microphone lacks that; training with
/// [`frames_of_arrival`] teaches a model both.
#[derive(Clone, Debug, PartialEq)]
pub struct Arrival {
    /// The array.
    pub geometry: Geometry,
    /// Azimuth of the source in the array's frame, rad.
    pub azimuth_rad: f32,
    /// Angle of the source from the array's axis (0: overhead), rad.
    pub zenith_rad: f32,
}

impl Arrival {
    /// An arrival drawn from `seed`: one of the shipped arrays (ReSpeaker 6-mic and 4-mic, the
    /// 8-mic circle), azimuth uniform, zenith uniform in 30–90° (a drone seen from an array on
    /// a floor, table or ceiling).
    pub fn draw(seed: u64) -> Self {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_add(1);
            unit_hash(state)
        };
        let geometry = match (next() * 3.0) as usize {
            0 => Geometry::respeaker_6mic(),
            1 => Geometry::respeaker_4mic(),
            _ => Geometry::circle_8mic(),
        };
        let azimuth_rad = (next() * std::f64::consts::TAU) as f32;
        let zenith_rad = (30.0 + 60.0 * next()).to_radians() as f32;
        Self { geometry, azimuth_rad, zenith_rad }
    }

    /// Each microphone's delay behind the array's centre, samples at `rate_hz` (negative:
    /// the wave reaches it first).
    pub fn delays_samples(&self, rate_hz: u32) -> Vec<f32> {
        let (s, c) = self.azimuth_rad.sin_cos();
        let horizontal = self.zenith_rad.sin();
        self.geometry
            .positions()
            .iter()
            .map(|p| -(p[0] * c + p[1] * s) * horizontal / SOUND_SPEED_MPS * rate_hz as f32)
            .collect()
    }
}

/// A number in [0, 1) that follows from `seed` alone (SplitMix64's output function).
pub fn unit_hash(seed: u64) -> f64 {
    let mut z = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// `x` delayed by `d` samples (|d| well below [`HALF_TAPS`]): a Blackman-windowed sinc of
/// `2·HALF_TAPS + 1` taps, zeros before the start.
fn delayed(x: &[f32], d: f32) -> Vec<f32> {
    let taps: Vec<f32> = (-(HALF_TAPS as i32)..=HALF_TAPS as i32)
        .map(|k| {
            let t = k as f32 - d;
            let sinc = if t.abs() < 1e-6 {
                1.0
            } else {
                (std::f32::consts::PI * t).sin() / (std::f32::consts::PI * t)
            };
            let u = (t / (2.0 * HALF_TAPS as f32 + 2.0) + 0.5).clamp(0.0, 1.0);
            let w = 0.42 - 0.5 * (std::f32::consts::TAU * u).cos()
                + 0.08 * (2.0 * std::f32::consts::TAU * u).cos();
            sinc * w
        })
        .collect();
    (0..x.len())
        .map(|n| {
            taps.iter()
                .enumerate()
                .filter_map(|(j, h)| {
                    let i = n as i64 - (j as i64 - HALF_TAPS as i64);
                    (0..x.len() as i64).contains(&i).then(|| h * x[i as usize])
                })
                .sum()
        })
        .collect()
}

/// [`frames_of_recording`], the recording heard by an array: with `arrival`, each microphone
/// of its geometry gets the sound delayed as the plane wave reaches it (the pipeline runs with
/// that geometry); without, every microphone of a 4-mic array gets the same samples.
pub fn frames_of_arrival(
    mono: &[f32],
    rate_hz: u32,
    arrival: Option<&Arrival>,
) -> anyhow::Result<Vec<(u64, Mfcc)>> {
    let geometry = arrival.map_or_else(Geometry::respeaker_4mic, |a| a.geometry);
    let config = Config::new(geometry, rate_hz);
    let mut pipeline = Pipeline::new(&config)
        .map_err(|e| anyhow::anyhow!("the pipeline refuses {rate_hz} Hz: {e}"))?;
    let slots = config.tdm_slots;
    // Each microphone's samples (slots beyond the array's silent); without an arrival every
    // slot carries the recording itself.
    let delayed_mics: Vec<Vec<f32>> = arrival.map_or_else(Vec::new, |a| {
        a.delays_samples(rate_hz).iter().map(|&d| delayed(mono, d)).collect()
    });
    let mic = |i: usize| match arrival {
        Some(_) => delayed_mics.get(i).map(Vec::as_slice),
        None => Some(mono),
    };
    let word = |x: f32| ((x.clamp(-1.0, 1.0) * 8_388_607.0).round() as i32) << 8;
    let mut frames = Vec::new();
    let mut words = Vec::with_capacity(1024 * slots);
    for start in (0..mono.len()).step_by(1024) {
        words.clear();
        for n in start..(start + 1024).min(mono.len()) {
            words.extend((0..slots).map(|i| mic(i).map_or(0, |m| word(m[n]))));
        }
        pipeline.push(&words, &mut |o| {
            if let Output::Mfcc(f) = o {
                frames.push((f.sample_index, aim_wire::from_dsp::mfcc(&f)));
            }
        });
    }
    Ok(frames)
}

/// The feature vectors of a recording: one per window of [`WINDOW_FRAMES`] consecutive frames,
/// windows `WINDOW_FRAMES` apart (a recording shorter than one window but with at least
/// [`MIN_FRAMES`] frames gives one vector of all its frames).
pub fn windows(frames: &[Mfcc]) -> Vec<Vec<f32>> {
    if frames.len() < MIN_FRAMES {
        return Vec::new();
    }
    if frames.len() < WINDOW_FRAMES {
        return vec![features(frames)];
    }
    frames.chunks_exact(WINDOW_FRAMES).map(features).collect()
}

/// Windows whose probabilities decide whether a live verdict names a drone at all: the newest
/// window and the ones ending [`WINDOW_FRAMES`] and 2·[`WINDOW_FRAMES`] frames before it
/// (disjoint windows, 18 frames, 17 hops + 0.512 s = 4.86 s of audio); also the fewest the
/// type is decided on ([`TYPE_WINDOWS`]). A drone does not come and go within
/// seconds, and one window of 2 s at 15 m over a 70 dB hall is misread far more often than
/// three (BENCHMARKS.md, "Issue 16, session 17").
pub const DECISION_WINDOWS: usize = 3;

/// Disjoint windows the *type* of a detected drone is decided on: up to the newest six (36
/// frames, 35 hops + 0.512 s = 9.47 s of audio) since the drone was last gone. A drone does not
/// change type in flight, so its type may take evidence from longer ago than its presence:
/// whether a drone is there is decided on [`DECISION_WINDOWS`] (it must follow a drone that
/// comes and goes), which drone it is on up to this many. Six is the most the 10 s tuning
/// recordings can measure (BENCHMARKS.md, "Issue 16, session 20").
pub const TYPE_WINDOWS: usize = 6;

/// The live classifier of one array: the model's probabilities of its windows of the last
/// [`WINDOW_FRAMES`] frames, one per frame; whether a drone is there from the last
/// [`DECISION_WINDOWS`] disjoint ones, and which from up to [`TYPE_WINDOWS`] disjoint ones
/// (see [`Verdict`]).
#[derive(Debug, Clone)]
pub struct Live {
    model: super::model::Model,
    frames: std::collections::VecDeque<Mfcc>,
    /// Probabilities of the windows ending at the last frames, newest last (at most
    /// `(max(decision_windows, type_windows) − 1)·WINDOW_FRAMES + 1`).
    history: std::collections::VecDeque<Vec<f32>>,
    /// Disjoint windows the detection pools ([`DECISION_WINDOWS`] unless set).
    decision_windows: usize,
    /// Most disjoint windows the type averages ([`TYPE_WINDOWS`] unless set).
    type_windows: usize,
    /// Windows (one per frame) since the type's evidence began: since the start, a
    /// [`Live::clear`], or the end of a run of `none` verdicts as long as the detection's span.
    type_run: usize,
    /// Consecutive `none` verdicts up to the newest.
    none_run: usize,
    verdict: Option<Verdict>,
}

/// Smallest and largest probability [`pooled_probability`] takes from a window (its log-odds
/// are finite; a window's `f32` probability of exactly 0 or 1 would otherwise decide alone).
const POOL_CLAMP: f64 = 1e-6;

/// The probability whose log-odds are the mean of `windows`' log-odds (each clamped to
/// [`POOL_CLAMP`]..1 − [`POOL_CLAMP`]): the geometric pooling of independent windows' evidence,
/// where a plain mean lets one confident window outvote the others. 0.5 for no window; NaN
/// if a window's probability is NaN (a broken model, not a verdict).
pub fn pooled_probability(windows: &[f32]) -> f32 {
    if windows.is_empty() {
        return 0.5;
    }
    let logit = |p: f32| {
        let p = f64::from(p).clamp(POOL_CLAMP, 1.0 - POOL_CLAMP);
        (p / (1.0 - p)).ln()
    };
    let mean = windows.iter().map(|&p| logit(p)).sum::<f64>() / windows.len() as f64;
    (1.0 / (1.0 + (-mean).exp())) as f32
}

/// Sets `p[none]` to `pooled` and scales the other classes to share the rest in their
/// proportions (all equal if they had nothing).
fn pool_none(p: &mut [f32], none: usize, pooled: f32) {
    let rest: f32 = (0..p.len()).filter(|&c| c != none).map(|c| p[c]).sum();
    let others = p.len().saturating_sub(1).max(1) as f32;
    for (c, v) in p.iter_mut().enumerate() {
        *v = match c {
            c if c == none => pooled,
            _ if rest > 0.0 => *v / rest * (1.0 - pooled),
            _ => (1.0 - pooled) / others,
        };
    }
}

/// The classifier's verdict. Whether a drone is there: the probability of `none` pooled
/// ([`pooled_probability`], the mean of the log-odds) over the newest window and up to
/// [`DECISION_WINDOWS`] − 1 earlier disjoint ones. Which drone:
/// the drone classes' mean probabilities over up to [`TYPE_WINDOWS`] disjoint windows since
/// the type's evidence began (never fewer than the detection's; `none` for as long as the
/// detection's span starts it again), scaled to share the detection's drone probability.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The decided class (`none`: no drone): the most probable, or with the model's
    /// `drone_threshold` the most probable drone class only when the drone probability is
    /// above it ([`super::model::Model::decide`]).
    pub class: String,
    /// Its probability, 0–1.
    pub probability: f32,
    /// Probability that a drone is there (1 − P(none)), 0–1.
    pub drone_probability: f32,
    /// Every class's probability, in the model's class order: `none`'s over the detection's
    /// windows, the drone classes' share of the rest over the type's.
    pub probabilities: Vec<f32>,
    /// The newest window's probabilities alone, in the model's class order.
    pub window_probabilities: Vec<f32>,
    /// Windows the detection pooled (1 to the classifier's decision windows,
    /// [`DECISION_WINDOWS`] by default).
    pub windows: usize,
    /// Windows the type averaged (at least `windows`, at most the classifier's type windows).
    pub type_windows: usize,
}

impl Live {
    /// A live classifier with `model` (made with `--features chip`; anything else is refused).
    pub fn new(model: super::model::Model) -> anyhow::Result<Self> {
        if model.features != names() {
            anyhow::bail!(
                "the model was not trained on this build's features of the chip's Mfcc frames \
                 (train it with `aim id train --features chip`; a chip model made before the \
                 frames carried a second comb must be trained again)"
            );
        }
        Ok(Self {
            model,
            frames: Default::default(),
            history: Default::default(),
            decision_windows: DECISION_WINDOWS,
            type_windows: TYPE_WINDOWS,
            type_run: 0,
            none_run: 0,
            verdict: None,
        })
    }

    /// The same classifier deciding whether a drone is there on `n` disjoint windows (at
    /// least 1); a drone is gone, and its type's evidence starts again, after `n` windows'
    /// worth of `none` verdicts.
    pub fn with_decision_windows(mut self, n: usize) -> Self {
        self.decision_windows = n.max(1);
        self
    }

    /// The same classifier deciding a detected drone's type on up to `n` disjoint windows
    /// (fewer than the detection's windows: as many as the detection's).
    pub fn with_type_windows(mut self, n: usize) -> Self {
        self.type_windows = n.max(1);
        self
    }

    /// The model's classes.
    pub fn classes(&self) -> &[String] {
        &self.model.classes
    }

    /// One frame of the tracked array (link order); classifies once the window is full.
    pub fn push(&mut self, frame: &Mfcc) {
        if self.frames.len() == WINDOW_FRAMES {
            self.frames.pop_front();
        }
        self.frames.push_back(*frame);
        if self.frames.len() < WINDOW_FRAMES {
            return;
        }
        let window: Vec<Mfcc> = self.frames.iter().copied().collect();
        let span = self.decision_windows.max(self.type_windows);
        while self.history.len() > (span - 1) * WINDOW_FRAMES {
            self.history.pop_front();
        }
        self.history.push_back(self.model.predict(&features(&window)));
        // The newest window and up to `k − 1` disjoint ones before it, and their mean.
        let n = self.history.len();
        let disjoint = |k: usize| -> Vec<&Vec<f32>> {
            (0..k)
                .filter_map(|i| n.checked_sub(1 + i * WINDOW_FRAMES))
                .map(|i| &self.history[i])
                .collect()
        };
        let mean_of = |k: usize| {
            let used = disjoint(k);
            let mut p = vec![0.0f32; self.model.classes.len()];
            for w in &used {
                p.iter_mut().zip(w.iter()).for_each(|(a, b)| *a += b / used.len() as f32);
            }
            (p, used.len())
        };
        let (mut detection, windows) = mean_of(self.decision_windows);
        let none = self.model.none_index();
        if let Some(none) = none {
            let of_none: Vec<f32> =
                disjoint(self.decision_windows).iter().map(|w| w[none]).collect();
            pool_none(&mut detection, none, pooled_probability(&of_none));
        }
        let detected = none != Some(self.model.decide(&detection));
        // A drone gone for as long as the detection's span takes its type with it (another
        // may come; the windows heard while it was gone are not its evidence); a verdict of
        // `none` now and then (a far drone in a loud hall) does not.
        self.none_run = if detected { 0 } else { self.none_run + 1 };
        if self.none_run >= self.decision_windows * WINDOW_FRAMES {
            self.type_run = 0;
        } else {
            self.type_run += 1;
        }
        // The type: the disjoint windows since its evidence began, at least the detection's,
        // at most `type_windows`.
        let held = self.type_run.div_ceil(WINDOW_FRAMES);
        let (kind, type_windows) = mean_of(held.min(self.type_windows).max(self.decision_windows));
        let p = match none {
            Some(none) => {
                let drone = 1.0 - detection[none];
                let share: f32 = (0..kind.len()).filter(|&c| c != none).map(|c| kind[c]).sum();
                (0..kind.len())
                    .map(|c| match c {
                        c if c == none => detection[none],
                        _ if share > 0.0 => kind[c] / share * drone,
                        _ => detection[c],
                    })
                    .collect()
            }
            None => kind,
        };
        // Presence from the detection's windows alone, also for a model without a threshold
        // (whose plain most probable class of `p` could differ).
        let best = match none {
            Some(none) if detected => self.model.most_probable(&p, Some(none)),
            Some(none) => none,
            None => self.model.decide(&p),
        };
        self.verdict = Some(Verdict {
            class: self.model.classes[best].clone(),
            probability: p[best],
            drone_probability: self.model.drone_probability(&p),
            window_probabilities: self.history[n - 1].clone(),
            windows,
            type_windows,
            probabilities: p,
        });
    }

    /// Forgets the windows (the array restarted: its frames no longer follow on).
    pub fn clear(&mut self) {
        self.frames.clear();
        self.history.clear();
        self.type_run = 0;
        self.none_run = 0;
        self.verdict = None;
    }

    /// The verdict on the newest full window and the disjoint ones before it, if any.
    pub fn verdict(&self) -> Option<&Verdict> {
        self.verdict.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pooling by the mean log-odds, against hand values: opposite evidence cancels, equal
    /// windows keep their value, two windows at 0.9 and one at 0.1 give the probability of
    /// log-odds ln(9)/3 (1/(1 + 9^(−1/3)) = 0.6753), where the plain mean would be 0.6333; a
    /// window at exactly 0 or 1 is clamped, not decisive. The other classes keep their shares.
    #[test]
    fn windows_pool_by_their_mean_log_odds() {
        let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
        assert!(close(pooled_probability(&[0.9, 0.1]), 0.5));
        assert!(close(pooled_probability(&[0.8, 0.8]), 0.8));
        let hand = 1.0 / (1.0 + 9f32.powf(-1.0 / 3.0));
        assert!(close(pooled_probability(&[0.9, 0.9, 0.1]), hand), "{hand}");
        assert!(close(pooled_probability(&[1.0, 0.0]), 0.5));
        assert!(close(pooled_probability(&[]), 0.5));
        let mut p = [0.2f32, 0.5, 0.3];
        pool_none(&mut p, 1, 0.8);
        assert!(close(p[1], 0.8) && close(p[0], 0.08) && close(p[2], 0.12), "{p:?}");
        let mut q = [0.0f32, 1.0, 0.0];
        pool_none(&mut q, 1, 0.4);
        assert!(close(q[0], 0.3) && close(q[2], 0.3), "{q:?}");
    }

    /// The fractional delay reproduces a delayed tone (oracle: sin(2πf(n − d)/fs)) within
    /// 1e-3 of full scale away from the edges, for delays of either sign.
    #[test]
    fn delayed_tone_matches_the_analytic_delay() {
        let (fs, f) = (16_000.0f32, 1_234.5f32);
        let x: Vec<f32> =
            (0..4000).map(|n| (std::f32::consts::TAU * f * n as f32 / fs).sin()).collect();
        for d in [-3.7f32, -0.5, 0.0, 0.25, 2.9] {
            let y = delayed(&x, d);
            let worst = (100..3900)
                .map(|n| (y[n] - (std::f32::consts::TAU * f * (n as f32 - d) / fs).sin()).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-3, "delay {d}: worst error {worst}");
        }
    }

    /// Delays follow the plane wave: none from overhead; from the horizon along +x the
    /// 6-mic circle's microphone 0 (on +x) hears first, r/c earlier, and the opposite one
    /// r/c later.
    #[test]
    fn arrival_delays_follow_the_plane_wave() {
        let six = Geometry::respeaker_6mic();
        let overhead = Arrival { geometry: six, azimuth_rad: 1.0, zenith_rad: 0.0 };
        assert!(overhead.delays_samples(48_000).iter().all(|d| d.abs() < 1e-6));
        let side = Arrival { geometry: six, azimuth_rad: 0.0, zenith_rad: 90f32.to_radians() };
        let d = side.delays_samples(48_000);
        let r = aim_dsp::RESPEAKER_6MIC_RADIUS_M / SOUND_SPEED_MPS * 48_000.0;
        assert!((d[0] + r).abs() < 1e-4 && (d[3] - r).abs() < 1e-4, "{d:?}");
        // Draws stay in their stated ranges and differ with the seed.
        let a = Arrival::draw(1);
        assert!((30f32.to_radians()..=90f32.to_radians()).contains(&a.zenith_rad));
        assert_ne!(a, Arrival::draw(2));
    }
}
