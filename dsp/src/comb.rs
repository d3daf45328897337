//! Rotor-signature detection in the long mono spectrum: a noise floor that follows the
//! spectrum's tilt, harmonic combs scored on the whitened spectrum, the blade-passing line
//! chosen among a comb's sub-multiples and multiples, a detection test, and continuity over
//! analyses.
//!
//! 1. **Floor.** The band is cut into blocks of [`FLOOR_BLOCK`] bins (62.5 Hz). Per block the
//!    mean magnitude, then the mean of the bins below twice that mean (tonal lines and their
//!    Hann skirts are left out), then the median of each block and its two neighbours (a block
//!    crowded with rotor lines); the floor at a bin is interpolated linearly between block
//!    centres. Whitened level `w(k) = |X(k)| / floor(k)`: noise alone is Rayleigh with mean ≈ 1.1
//!    (`P(w > 3)` ≈ 0.3 %, `P(w > 5)` ≈ 10⁻⁸), whatever the tilt of the spectrum.
//! 2. **Candidates.** Local maxima of `w` at or above `Config::peak_floor_ratio` inside the BPF
//!    search range, the strongest [`MAX_CANDIDATES`].
//! 3. **Blade or shaft line.** A rotor's spectrum has lines at multiples of its shaft rate; the
//!    blade-passing ones (multiples of the blade count) are the strong ones. For a candidate
//!    `f` with line strengths `L(h)` (whitened level of the line nearest `h·f`, 0 when there is
//!    none) the multiples `m·f` (m = 2, 3) stronger than `f` itself are tested: when the lines
//!    between the multiples of `m` (h = m+1 ..= 3m) are weak (median level below
//!    [`SHAFT_RATIO`] of the stronger neighbouring multiple; with none to compare, when `m·f`
//!    is twice as strong as `f`), `f` was a shaft line and `m·f` is the BPF. Then the sub-multiples
//!    `f/d` (d = 2, 3): when the lines between `f`'s harmonics are that strong, `f` is a
//!    harmonic of a lower fundamental: `f/d` if that is in the search range, else the candidate
//!    is dropped (engines, mains hum, fans whose fundamental lies below the rotor range); it is
//!    also dropped when the line at `f/d` lies below the search range and is at least as strong
//!    as `f` by magnitude (a fan's fundamental; a rotor's shaft lines are 8–12 dB weaker). The
//!    lowest line is left out of both tests: there several rotors' shaft lines add up in one
//!    bin.
//! 4. **Comb score.** Over harmonics `h = 1..=Config::harmonics` of the resolved fundamental:
//!    a line is found when the largest `w` within ±r bins of `h·f` is a local maximum of at
//!    least [`LINE_RATIO`] (r = 1 bin plus [`LINE_SEARCH`] of the line's frequency in bins, for
//!    rotor-speed wander within the window). Score = Σ min(w, [`LINE_CAP`]) over the found lines;
//!    harmonicity = found / expected (harmonics below 3.8 kHz); frequency = amplitude-weighted
//!    mean of the refined `f_h / h`.
//! 5. **Detection.** A group passes when it has at least [`MIN_LINES`] lines (or all expected,
//!    if fewer), harmonicity ≥ [`MIN_HARMONICITY`] and quality
//!    `q = harmonicity · score / (score + QUALITY_SCALE)` ≥ `Config::bpf_min_quality`.
//! 6. **Continuity.** A passing group is reported only once it has passed in [`MIN_AGE`]
//!    consecutive analyses, each within `2 bins + Config::bpf_max_rate_per_s · hop · f` of the
//!    previous one (rotor speeds change at most that fast) and with its level (root-sum-square amplitude of its lines)
//!    within [`STEADY_RATIO`] of the previous one's while it is not yet reported: a source must hold a comb for three
//!    analyses (1.02 s) before it is called a rotor; notes and vowels rarely do. A comb once
//!    reported continues at [`HOLD_QUALITY`] of the starting quality (hysteresis), and a
//!    reported comb missed by one analysis keeps its place in the history for the next.
//! 7. **Shaft combs.** Of the groups to report, one whose double or triple lies in the rotor
//!    cluster ([`CLUSTER`]) of another reported group is a rotor's shaft comb and is left out
//!    when that group's first line, or its own line at the multiple, is at least
//!    [`SHAFT_DOMINANCE`] times as strong as its first line; with no such group in this
//!    analysis but one reported in the previous, it is reported at the multiple when its own
//!    line there is. A group whose first line was not found is left as it is. When no group
//!    is reported, the `Peaks` output says "no rotor signature" and carries no BPF.

use crate::bpf::refine_peak;
use crate::{Config, Peak, Peaks, MAX_HARMONICS};

/// Bins per block of the noise-floor estimate.
pub const FLOOR_BLOCK: usize = 32;
/// A harmonic line must stand this many times above the floor (2.5: noise alone reaches it in
/// a bin with probability `exp(−π/4 · 2.5²)` ≈ 0.7 %; a comb still needs [`MIN_LINES`] such
/// lines at half its harmonics, the quality test and [`MIN_AGE`] analyses in a row. Was 3.0;
/// 2.5 finds the upper lines of a rotor 3–10× over a 62–70 dB background, chosen on the BPF
/// bench's tuning seeds, BENCHMARKS.md "Session 9").
pub const LINE_RATIO: f32 = 2.5;
/// Search half-width for a comb's line beyond one bin, as a fraction of the line's frequency
/// (0.3 %; was 0.2 %, which lost the upper lines of rotors whose speed moves within the
/// window). Measured among 0.2–0.6 % on the BPF bench's tuning seeds 1–16 (seeds 9–16 added
/// after a first evaluation at 0.4 %; BENCHMARKS.md issue 19, session 16): within 2 Hz 75.9 /
/// 79.6 / 81.0 % at 0.2 / 0.3 / 0.4 %, non-drone frames with a BPF 1.05 / 1.55 / 2.0 % (a held
/// musical note keeps more lines too).
pub const LINE_SEARCH: f32 = 0.003;
/// Whitened level at which a line's contribution to the score saturates.
pub const LINE_CAP: f32 = 40.0;
/// Fewest lines of a detected group (fewer only if fewer harmonics lie in the band).
pub const MIN_LINES: u32 = 3;
/// Lowest harmonicity of a detected group.
pub const MIN_HARMONICITY: f32 = 0.5;
/// Score at which the quality reaches half the harmonicity.
pub const QUALITY_SCALE: f32 = 30.0;
/// Shaft-line test: lines between the blade lines weaker than this fraction of them.
pub const SHAFT_RATIO: f32 = 0.6;
/// A comb's second or third harmonic this many times stronger than its first makes it the blade
/// line ([`Spectrum::blade_line`]).
pub const BLADE_DOMINANCE: f32 = 2.5;
/// A passing group whose double or triple lies in another's rotor cluster is a shaft comb when
/// that one's first line, or its own line at the multiple, is this many times as strong as
/// its own first line: the blade-passing line is a rotor's strongest, the shaft-rate lines
/// (imbalance) are weaker. Measured at 0.5, 0.7, 1.0, 1.4 and 2.0 on the BPF bench's tuning
/// seeds 1–8 (BENCHMARKS.md issue 19, session 16); 1.0 had the fewest octave errors without
/// losing frames.
pub const SHAFT_DOMINANCE: f32 = 1.0;
/// Consecutive analyses a group must pass before it is reported (3: the comb held steady for
/// 1.02 s; a sung note or a vowel rarely does, a rotor always).
pub const MIN_AGE: u8 = 3;
/// A group continues one of the previous analysis only if its level (root-sum-square amplitude of its lines) is within
/// this factor of that one's either way (±6 dB per 0.256 s: a rotor's level is steady, a note
/// dying away in a hall falls 10 dB per hop at RT60 1.6 s, a vowel starts and stops).
pub const STEADY_RATIO: f32 = 2.0;
/// Relative width of a rotor cluster: a passing group within this fraction of a reported one's
/// BPF is reported with it before it has held for [`MIN_AGE`] analyses (rotor trims and a
/// centre of gravity off the middle spread one airframe's rotor speeds by a few per cent;
/// the Mambo's four lines lie within ±5 %).
pub const CLUSTER: f32 = 0.08;
/// Fraction of `Config::bpf_min_quality` at which a comb already reported continues.
pub const HOLD_QUALITY: f32 = 0.5;
/// Most fundamental candidates examined per analysis.
pub const MAX_CANDIDATES: usize = 8;
/// Harmonics of a candidate examined for the shaft/blade decision.
const CHECK_HARMONICS: usize = 12;

/// Groups that passed the detection test in the previous analysis, with how many consecutive
/// analyses each has passed (continuity).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct History {
    hz: [f32; 4],
    /// Level of each group (the units of [`crate::Peak::amplitude`]).
    amplitude: [f32; 4],
    age: [u8; 4],
    /// Carried over from an analysis that did not find it.
    missed: [bool; 4],
    count: usize,
}

impl History {
    /// No previous analysis.
    pub const fn new() -> Self {
        Self { hz: [0.0; 4], amplitude: [0.0; 4], age: [0; 4], missed: [false; 4], count: 0 }
    }

    /// Consecutive analyses a group at `hz` with level `amplitude` has passed
    /// before this one (0: none within `tolerance_hz` that is reported already or whose
    /// amplitude is within [`STEADY_RATIO`] of it either way).
    fn age_of(&self, hz: f32, amplitude: f32, tolerance_hz: f32) -> u8 {
        (0..self.count)
            .filter(|&i| {
                let a = self.amplitude[i];
                libm::fabsf(self.hz[i] - hz) <= tolerance_hz
                    && (self.age[i] >= MIN_AGE
                        || (amplitude <= STEADY_RATIO * a && a <= STEADY_RATIO * amplitude))
            })
            .map(|i| self.age[i])
            .max()
            .unwrap_or(0)
    }

    fn holds(&self, hz: f32, tolerance_hz: f32) -> bool {
        self.hz[..self.count].iter().any(|&p| libm::fabsf(p - hz) <= tolerance_hz)
    }
}

/// Writes the whitened level `|X(k)| / floor(k)` of `mags[k]` into `white[k]` for `lo ≤ k < top`
/// (0 elsewhere; `1 / floor` is interpolated linearly between block centres).
pub fn whiten(mags: &[f32], white: &mut [f32], lo: usize, top: usize) {
    let blocks = (top - lo) / FLOOR_BLOCK;
    let mut floors = [0.0f32; 64];
    let blocks = blocks.min(floors.len());
    for (b, f) in floors[..blocks].iter_mut().enumerate() {
        let seg = &mags[lo + b * FLOOR_BLOCK..lo + (b + 1) * FLOOR_BLOCK];
        let mean = seg.iter().sum::<f32>() * (1.0 / FLOOR_BLOCK as f32);
        let cut = 2.0 * mean;
        let (mut s, mut n) = (0.0f32, 0u32);
        for &m in seg {
            if m <= cut {
                s += m;
                n += 1;
            }
        }
        *f = if n > 0 { s / n as f32 } else { mean };
    }
    // A block crowded with lines (several rotors' BPFs within 62.5 Hz) raises its own
    // estimate: take the median of each block and its two neighbours.
    let mut prev = floors[0];
    for b in 0..blocks {
        let next = if b + 1 < blocks { floors[b + 1] } else { floors[b] };
        let cur = floors[b];
        let med = cur.min(prev).max(cur.max(prev).min(next));
        prev = cur;
        floors[b] = med;
    }
    // Reciprocal floors: the per-bin work below is one multiply-add and one multiply.
    let tiny = f32::MIN_POSITIVE * 1e6;
    for f in &mut floors[..blocks] {
        *f = 1.0 / f.max(tiny);
    }
    let end = lo + blocks * FLOOR_BLOCK;
    white[..lo].fill(0.0);
    white[end..].fill(0.0);
    let half = FLOOR_BLOCK / 2;
    for b in 0..blocks {
        // Bins from this block's centre to the next one's: linear between the two floors.
        let f0 = floors[b];
        let f1 = if b + 1 < blocks { floors[b + 1] } else { f0 };
        let start = if b == 0 { lo } else { lo + b * FLOOR_BLOCK + half };
        let stop = if b + 1 < blocks { lo + (b + 1) * FLOOR_BLOCK + half } else { end };
        let c0 = (lo + b * FLOOR_BLOCK + half) as f32;
        let slope = (f1 - f0) * (1.0 / FLOOR_BLOCK as f32);
        // Between the centres the reciprocal is interpolated; outside them (the band's
        // edges) it is held.
        let mut inv = f0 + slope * (start as f32 - c0);
        let (lo_inv, hi_inv) = (f0.min(f1), f0.max(f1));
        for k in start..stop {
            // Compared by hand: `f32::clamp` panics on run-time bounds (its message links
            // core::fmt's float formatting, about 20 KB of flash) and `max`/`min` handle NaN
            // (0.15 M instructions per second more on the M4F).
            let r = if inv < lo_inv {
                lo_inv
            } else if inv > hi_inv {
                hi_inv
            } else {
                inv
            };
            white[k] = mags[k] * r;
            inv += slope;
        }
    }
}

/// The spectrum an analysis works on: magnitudes, whitened levels and the band.
pub struct Spectrum<'a> {
    /// Magnitudes, bins of `bin_hz`.
    pub mags: &'a [f32],
    /// Whitened levels ([`whiten`]).
    pub white: &'a [f32],
    /// Bin spacing, Hz.
    pub bin_hz: f32,
    /// One past the highest bin analysed.
    pub top: usize,
}

/// A line near a bin position: the bin of the largest whitened level within ±r, if it is a
/// local maximum of at least [`LINE_RATIO`].
#[derive(Debug, Clone, Copy)]
struct Line {
    bin: usize,
    white: f32,
}

impl Spectrum<'_> {
    fn search_radius(&self, centre: f32) -> usize {
        1 + (centre * LINE_SEARCH) as usize
    }

    fn line(&self, centre: f32) -> Option<Line> {
        let r = self.search_radius(centre);
        let c = (centre + 0.5) as usize;
        if c < r + 1 || c + r + 2 > self.top {
            return None;
        }
        let w = self.white;
        let mut best = c - r;
        for i in c - r + 1..=c + r {
            if w[i] > w[best] {
                best = i;
            }
        }
        let v = w[best];
        (v >= LINE_RATIO && v >= w[best - 1] && v >= w[best + 1])
            .then_some(Line { bin: best, white: v })
    }

    fn strength(&self, centre: f32) -> f32 {
        self.line(centre).map_or(0.0, |l| l.white)
    }

    /// Whether a comb at `bin` lies in the band for harmonic `h`.
    fn in_band(&self, centre: f32) -> bool {
        centre + self.search_radius(centre) as f32 + 2.5 < self.top as f32
    }

    /// The blade-passing fundamental (bins) of a candidate line at `bin`, or `None` when the
    /// comb's fundamental lies below `min_bin`.
    fn resolve(&self, bin: f32, min_bin: f32, max_bin: f32) -> Option<f32> {
        let mut l = [0.0f32; CHECK_HARMONICS + 1];
        let mut n = 0;
        for (h, slot) in l.iter_mut().enumerate().skip(1) {
            let c = h as f32 * bin;
            if !self.in_band(c) {
                break;
            }
            *slot = self.strength(c);
            n = h;
        }
        // Up: a shaft line whose multiples m carry the comb.
        let mut best: Option<(f32, usize)> = None;
        for m in 2..=3usize {
            // The blade line is the rotor's strongest: a shaft line is weaker than its
            // multiple.
            if m as f32 * bin > max_bin || n < 2 * m || l[m] <= l[1] {
                continue;
            }
            // No line in between to compare with: a multiple twice as strong decides alone.
            let r = between_ratio(&l[..=n.min(3 * m)], m).unwrap_or(if l[m] >= 2.0 * l[1] {
                0.0
            } else {
                1.0
            });
            if r < SHAFT_RATIO && best.is_none_or(|(b, _)| r < b) {
                best = Some((r, m));
            }
        }
        if let Some((_, m)) = best {
            let c = m as f32 * bin;
            return Some(self.line(c).map_or(c, |line| refine_peak(self.mags, line.bin).0));
        }
        // Down: a harmonic of a lower fundamental, whose lines between this comb's are as
        // strong as this comb's own.
        for d in [2usize, 3] {
            let sub = bin / d as f32;
            // A line below the search range at least as strong as this one (by magnitude):
            // this is a harmonic of a fan's, a pump's or an engine's fundamental, its own
            // strongest line (a rotor's shaft lines lie 8–12 dB under its blade line).
            if sub < min_bin
                && self
                    .line(sub)
                    .zip(self.line(bin))
                    .is_some_and(|(s, c)| self.mags[s.bin] >= self.mags[c.bin])
            {
                return None;
            }
            let mut ls = [0.0f32; 3 * CHECK_HARMONICS / 2 + 1];
            let mut ns = 0;
            for (j, slot) in ls.iter_mut().enumerate().skip(1) {
                let c = j as f32 * sub;
                if j > 3 * d || !self.in_band(c) {
                    break;
                }
                *slot = if j % d == 0 { l[j / d] } else { self.strength(c) };
                ns = j;
            }
            if ns >= 2 * d {
                if let Some(r) = between_ratio(&ls[..=ns], d) {
                    if r >= SHAFT_RATIO {
                        return (sub >= min_bin).then_some(sub);
                    }
                }
            }
        }
        Some(bin)
    }

    /// The blade line of a comb at `bin`: the rotor's strongest line. When its second or
    /// third harmonic is [`BLADE_DOMINANCE`] times stronger than the line at `bin` (a shaft
    /// line: several rotors a few per cent apart fill a shaft comb's gaps, so the
    /// between-lines test of [`Self::resolve`] cannot tell), that multiple.
    fn blade_line(&self, bin: f32, max_bin: f32) -> f32 {
        // Line strengths as magnitudes: the whitening floor differs between the lines' blocks.
        let s1 = self.line(bin).map_or(0.0, |l| self.mags[l.bin]);
        let mut best = (bin, BLADE_DOMINANCE * s1);
        for m in [2.0f32, 3.0] {
            let c = m * bin;
            if c > max_bin {
                break;
            }
            if let Some(line) = self.line(c) {
                if self.mags[line.bin] > best.1 {
                    best = (refine_peak(self.mags, line.bin).0, self.mags[line.bin]);
                }
            }
        }
        best.0
    }

    /// Scores the comb at `bin` over `harmonics` harmonics.
    fn comb(&self, bin: f32, harmonics: usize) -> Group {
        let (mut num, mut den, mut score, mut found, mut expected) =
            (0.0f32, 0.0f32, 0.0f32, 0u32, 0u32);
        // The group's level: root-sum-square of its found lines' amplitudes. One line (the
        // fundamental) can sit in a room's interference notch 15 dB deep while its neighbours
        // do not; the comb's total level compares rotor groups with each other and over time.
        let mut power = 0.0f32;
        let mut first = [0.0f32; 3];
        for h in 1..=harmonics.min(MAX_HARMONICS) {
            let centre = h as f32 * bin;
            if !self.in_band(centre) {
                break;
            }
            expected += 1;
            let Some(line) = self.line(centre) else { continue };
            let (bh, ah) = refine_peak(self.mags, line.bin);
            if libm::fabsf(bh - centre) > self.search_radius(centre) as f32 + 0.5 {
                continue;
            }
            if h <= first.len() {
                first[h - 1] = self.mags[line.bin];
            }
            power += ah * ah;
            num += ah * bh / h as f32;
            den += ah;
            score += line.white.min(LINE_CAP);
            found += 1;
        }
        let hz = if den > 0.0 { num / den * self.bin_hz } else { bin * self.bin_hz };
        let amplitude = if power > 0.0 {
            libm::sqrtf(power)
        } else if bin >= 1.0 {
            refine_peak(self.mags, (bin + 0.5) as usize).1
        } else {
            0.0
        };
        let harmonicity = found as f32 / expected.max(1) as f32;
        let quality = harmonicity * score / (score + QUALITY_SCALE);
        let passes = found >= MIN_LINES.min(expected.max(1)) && harmonicity >= MIN_HARMONICITY;
        Group { hz, amplitude, harmonicity, score, quality, first, passes }
    }
}

/// One harmonic group of an analysis.
#[derive(Debug, Clone, Copy, Default)]
struct Group {
    hz: f32,
    amplitude: f32,
    harmonicity: f32,
    score: f32,
    quality: f32,
    /// Magnitudes of the lines at the fundamental, its double and its triple (0 when not
    /// found).
    first: [f32; 3],
    /// Line count and harmonicity pass the test (quality is tested against the config).
    passes: bool,
}

/// Finds the rotor groups of one analysis. `spec` holds magnitudes and whitened levels,
/// `hop_s` is the time between analyses, `history` the previous analysis's passing groups
/// (updated).
pub fn detect(spec: &Spectrum, config: &Config, hop_s: f32, history: &mut History) -> Peaks {
    let bin_hz = spec.bin_hz;
    let k_min = (libm::floorf(config.bpf_min_hz / bin_hz) as usize).max(2);
    let k_max = (libm::ceilf(config.bpf_max_hz / bin_hz) as usize).min(spec.top - 2);
    let (min_bin, max_bin) = (config.bpf_min_hz / bin_hz, config.bpf_max_hz / bin_hz);

    // Candidates: whitened local maxima, strongest kept.
    let mut cands = [(0usize, 0.0f32); MAX_CANDIDATES];
    let mut n_cands = 0usize;
    let w = spec.white;
    for k in k_min..=k_max {
        let v = w[k];
        if v >= config.peak_floor_ratio && v >= w[k - 1] && v > w[k + 1] {
            insert_strongest(&mut cands, &mut n_cands, (k, v));
        }
    }
    // Resolved and scored groups, strongest score first, duplicates merged.
    let mut groups = [Group::default(); MAX_CANDIDATES];
    let mut n_groups = 0usize;
    for &(k, _) in &cands[..n_cands] {
        let b1 = refine_peak(spec.mags, k).0;
        let Some(b) = spec.resolve(b1, min_bin, max_bin) else { continue };
        let b = spec.blade_line(b, max_bin);
        if b < min_bin || b > max_bin {
            continue;
        }
        let g = spec.comb(b, config.harmonics);
        let dup = groups[..n_groups].iter().position(|o| libm::fabsf(o.hz - g.hz) < 1.5 * bin_hz);
        match dup {
            Some(i) if groups[i].score >= g.score => {}
            Some(i) => groups[i] = g,
            None => {
                groups[n_groups] = g;
                n_groups += 1;
            }
        }
    }
    let groups = &mut groups[..n_groups];
    groups.sort_unstable_by(|a, b| b.score.total_cmp(&a.score));

    let mut out = Peaks::default();
    let mut next = History::new();
    let best = groups.iter().find(|g| g.passes).map_or(0.0, |g| g.score);
    let tolerance = 1.5 * bin_hz;
    let rate_hz_per_hz = config.bpf_max_rate_per_s * hop_s;
    // The groups entered in `next` (the same order), as they would be reported.
    let mut passing = [Peak::default(); 4];
    let mut passing_first = [[0.0f32; 3]; 4];
    let mut n_passing = 0usize;
    for g in groups.iter() {
        let allowed = 2.0 * bin_hz + rate_hz_per_hz * g.hz;
        let prior = history.age_of(g.hz, g.amplitude, allowed);
        // Hysteresis: a comb already reported, or one in the rotor cluster of one reported in
        // the previous analysis (another rotor pair of the same airframe), continues at half
        // the quality that starts one.
        let in_reported_cluster = (0..history.count)
            .any(|i| history.age[i] >= MIN_AGE && in_cluster(history.hz[i], g.hz));
        let min_quality = if prior >= MIN_AGE || in_reported_cluster {
            HOLD_QUALITY * config.bpf_min_quality
        } else {
            config.bpf_min_quality
        };
        if !g.passes || g.quality < min_quality || g.score < config.peak_relative_score * best {
            continue;
        }
        let related = next.hz[..next.count].iter().any(|&a| {
            let (lo, hi) = if g.hz > a { (a, g.hz) } else { (g.hz, a) };
            let n = libm::roundf(hi / lo);
            libm::fabsf(hi - n * lo) < tolerance * n.max(1.0)
        });
        if related || next.count == next.hz.len() {
            continue;
        }
        let age = prior.saturating_add(1);
        next.hz[next.count] = g.hz;
        next.amplitude[next.count] = g.amplitude;
        next.age[next.count] = age;
        next.count += 1;
        passing[n_passing] = Peak {
            hz: g.hz,
            amplitude: g.amplitude,
            harmonicity: g.harmonicity,
            quality: g.quality,
        };
        passing_first[n_passing] = g.first;
        n_passing += 1;
    }
    // Reported: the groups that held for MIN_AGE analyses, and with them the passing groups
    // of the same rotor cluster (within CLUSTER of one of them) still settling: continuity
    // decides whether a rotor signature is there, not which of its rotors' groups count (a
    // rotor pair whose fundamental dipped for one analysis would otherwise be missing for
    // MIN_AGE − 1 frames, and a frame with one pair of two reads as a thrust change).
    let aged = |i: usize| next.age[i] >= MIN_AGE;
    let eligible = |i: usize| {
        aged(i) || (0..n_passing).any(|j| aged(j) && in_cluster(passing[j].hz, passing[i].hz))
    };
    // A shaft comb: twice or three times its frequency falls in the rotor cluster of another
    // reported group, and that group's first line or its own line at the multiple is
    // [`SHAFT_DOMINANCE`] times as strong as its first line (a rotor's blade line is its
    // strongest; several rotors' shaft lines fill the gaps between blade lines,
    // so [`Spectrum::resolve`] cannot always tell, and one rotor's blade line may sit in the
    // room's interference notch while another's does not).
    let shaft = |i: usize| {
        let own = passing_first[i];
        (0..n_passing).any(|j| {
            let a = passing[j].hz;
            j != i
                && eligible(j)
                && [2usize, 3].iter().any(|&m| {
                    in_cluster(a, m as f32 * passing[i].hz)
                        && own[0] > 0.0
                        && (passing_first[j][0] >= SHAFT_DOMINANCE * own[0]
                            || own[m - 1] >= SHAFT_DOMINANCE * own[0])
                })
        })
    };
    // A shaft comb whose double or triple is stronger than its first line, with no blade
    // group passing in this analysis but one reported in the previous one there: the blade
    // lines are that multiple.
    let promoted = |i: usize| {
        let own = passing_first[i];
        [2usize, 3].into_iter().find(|&m| {
            let b = m as f32 * passing[i].hz;
            own[0] > 0.0
                && own[m - 1] >= SHAFT_DOMINANCE * own[0]
                && (0..history.count).any(|k| {
                    history.age[k] >= MIN_AGE && !history.missed[k] && in_cluster(history.hz[k], b)
                })
        })
    };
    for (i, &group) in passing[..n_passing].iter().enumerate() {
        if eligible(i) && !shaft(i) && (out.count as usize) < out.peaks.len() {
            let mut peak = group;
            if let Some(m) = promoted(i) {
                peak.hz *= m as f32;
            }
            out.peaks[out.count as usize] = peak;
            out.count += 1;
        }
    }
    // A reported comb missed in one analysis (a wind gust, a reflection's notch) keeps its
    // place for the next.
    for i in 0..history.count {
        let (hz, age) = (history.hz[i], history.age[i]);
        let tol = 2.0 * bin_hz + rate_hz_per_hz * hz;
        if age < MIN_AGE || history.missed[i] || next.count == next.hz.len() || next.holds(hz, tol)
        {
            continue;
        }
        next.hz[next.count] = hz;
        next.amplitude[next.count] = history.amplitude[i];
        next.age[next.count] = age;
        next.missed[next.count] = true;
        next.count += 1;
    }
    *history = next;
    out.rotor = out.count > 0;
    out.bpf_hz = out.peaks[0].hz;
    out
}

/// Whether `hz` lies in the rotor cluster of a group at `reference_hz` (within [`CLUSTER`] of
/// it).
fn in_cluster(reference_hz: f32, hz: f32) -> bool {
    libm::fabsf(reference_hz - hz) <= CLUSTER * reference_hz
}

/// The median, over the lines `l[j]` with `j > m` not a multiple of `m`, of their level relative to
/// the stronger of the neighbouring multiples of `m` (`l[0]` unused; a missing line is 0; a
/// ratio is capped at 2; a line whose neighbouring multiples are both missing is left out).
/// `None` when no line has a neighbour to compare with.
fn between_ratio(l: &[f32], m: usize) -> Option<f32> {
    let n = l.len() - 1;
    let mut r = [0.0f32; 24];
    let mut k = 0;
    // The first line is left out: below the blade fundamental, several rotors' shaft lines
    // fall into one bin and add up, so it says nothing about the comb's pattern.
    for j in m + 1..=n {
        if j % m == 0 || k == r.len() {
            continue;
        }
        let below = if j >= m { l[j / m * m] } else { 0.0 };
        let above = if (j / m + 1) * m <= n { l[(j / m + 1) * m] } else { 0.0 };
        let reference = below.max(above);
        // A missing reference line says nothing: several rotors a few per cent apart and a
        // speed wandering within the window smear a comb's upper lines out of the search.
        if reference > 0.0 {
            r[k] = (l[j] / reference).min(2.0);
            k += 1;
        }
    }
    if k == 0 {
        return None;
    }
    let r = &mut r[..k];
    r.sort_unstable_by(f32::total_cmp);
    Some(if k % 2 == 1 { r[k / 2] } else { 0.5 * (r[k / 2 - 1] + r[k / 2]) })
}

fn insert_strongest(cands: &mut [(usize, f32); MAX_CANDIDATES], n: &mut usize, c: (usize, f32)) {
    if *n < cands.len() {
        cands[*n] = c;
        *n += 1;
        return;
    }
    let (weakest, _) =
        cands
            .iter()
            .enumerate()
            .fold((0, f32::INFINITY), |acc, (i, x)| if x.1 < acc.1 { (i, x.1) } else { acc });
    if cands[weakest].1 < c.1 {
        cands[weakest] = c;
    }
}
