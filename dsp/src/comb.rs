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
//!    `f`, the level `L(h)` of each harmonic `h ≤ 12` in the band is the natural log of the
//!    largest whitened level within the line search around `h·f` (at least 0, the noise). The
//!    comb's extent is its highest found line within [`EXTENT_LOG`] of its strongest: past it,
//!    what passes the line test is noise, distortion or leakage. The contrast for a multiple
//!    `m` is the median, over the lines `j > m` between the multiples of `m` whose neighbouring
//!    multiples lie within the extent, of the mean level of those two multiples minus `L(j)`;
//!    the lowest line is left out (there several rotors' shaft lines add up in one bin, and
//!    the room may raise it to the blade line's level).
//!    - **Up:** contrast ≥ [`SHAFT_CONTRAST`] for `m = 2` or `3` (the larger wins, `m·f` in the
//!      search range): `f` is a shaft line and `m·f` the BPF.
//!    - **Down:** for `f/d` (d = 2, 3), with `f`'s levels at the multiples of `d`: contrast
//!      < [`OWN_HARMONIC_CONTRAST`] makes `f` a harmonic of `f/d`. Then `f/d`, itself tested
//!      as a shaft line (up), if it is in the search range; else the candidate is dropped
//!      (engines, mains hum, fans whose fundamental lies below the rotor range). A candidate
//!      is also dropped when the line at `f/d` lies below the search range and is at least as
//!      strong as `f` by magnitude (a fan's fundamental; a rotor's shaft lines are 8–12 dB
//!      weaker).
//!    - **Dominant multiple** (`Spectrum::blade_line`): a second or third harmonic
//!      [`BLADE_DOMINANCE`] times as strong as `f` by magnitude is the BPF, unless the
//!      contrast at that multiple, with its own level replaced by its neighbours' mean, is
//!      below [`BLADE_VETO`] (a blade comb with one line raised by the room).
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
//!    within [`STEADY_RATIO`] of the previous one's while it is not yet reported: a source must hold a comb for four
//!    analyses (1.28 s) before it is called a rotor; notes and vowels rarely do. A comb once
//!    reported continues at [`HOLD_QUALITY`] of the starting quality (hysteresis), and a
//!    reported comb missed by one analysis keeps its place in the history for the next.
//!    Groups are taken strongest score first (between equal scores, the louder: clean
//!    recordings cap every line), those continuing a reported comb before all others: a
//!    harmonically related comb of one analysis (a shaft comb, or the comb at twice the BPF,
//!    read from one noisy spectrum) is dropped as related to the reported one instead of
//!    pushing it out.
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
/// Shaft-line test (`Spectrum::resolve`): a candidate is a shaft line, and its multiple `m`
/// the blade line, when the lines between the multiples of `m` lie at least this far (natural
/// log, 0.45 = 3.9 dB) under the mean of their neighbouring multiples (the median contrast).
/// Chosen among 0.3–0.9 on the BPF bench's tuning seeds 1–16 (BENCHMARKS.md issue 19, session
/// 40: 0.35 gave 79.15 % within 2 Hz and 1.04 % octave errors, 0.55 81.85 % and 1.30 %, with
/// that session's version of the test; landed in session 41).
pub const SHAFT_CONTRAST: f32 = 0.45;
/// Own-harmonic test: a candidate is a harmonic of its sub-multiple `f/d` when the lines
/// between its own lie less than this far (natural log, 0.3 = 2.6 dB) under them (measured at
/// 0.15–0.45 on the same seeds).
pub const OWN_HARMONIC_CONTRAST: f32 = 0.3;
/// The blade-line promotion (`Spectrum::blade_line`) is vetoed when the comb's contrast at
/// the multiple, with the promoted line's own level replaced by its neighbours' mean, is
/// below this (natural log): the lines between its multiples are stronger than they, so the
/// comb is a blade comb with one line raised by the room (measured off and at −0.5…−0.1).
pub const BLADE_VETO: f32 = -0.3;
/// A comb's lines count for the contrast up to its highest found line within this factor
/// (natural log, 3.4 ≈ 30×) of its strongest: past a comb's last strong line, what passes the
/// line test is noise, distortion or leakage, which would decide the edge triples.
pub const EXTENT_LOG: f32 = 3.4;
/// A comb's second or third harmonic this many times stronger than its first makes it the blade
/// line (`Spectrum::blade_line`).
pub const BLADE_DOMINANCE: f32 = 2.5;
/// A passing group whose double or triple lies in another's rotor cluster is a shaft comb when
/// that one's first line, or its own line at the multiple, is this many times as strong as
/// its own first line: the blade-passing line is a rotor's strongest, the shaft-rate lines
/// (imbalance) are weaker. Measured at 0.5, 0.7, 1.0, 1.4 and 2.0 on the BPF bench's tuning
/// seeds 1–8 (BENCHMARKS.md issue 19, session 16); 1.0 had the fewest octave errors without
/// losing frames.
pub const SHAFT_DOMINANCE: f32 = 1.0;
/// Consecutive analyses a group must pass before it is reported (4: the comb held steady for
/// 1.28 s; a sung note or a vowel rarely does, a rotor always). Was 3 (1.02 s); 4 with the
/// lower start thresholds of `Config::peak_floor_ratio` 4 and `Config::bpf_min_quality` 0.2
/// keeps the weak combs of far or masked rotors that 3 with the stricter thresholds lost, and
/// lets through far fewer held notes (BENCHMARKS.md issue 19, session 43; fresh seeds
/// 1101–1108: within 2 Hz 82.3 → 82.9 %, octave 1.16 → 1.03 %, non-drone frames 1.93 → 0.80 %,
/// the music-like source 16.0 → 2.5 %). The price is latency: a comb is reported one analysis
/// (0.256 s) later after it starts or returns.
pub const MIN_AGE: u8 = 4;
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

    /// The bin of the largest whitened level within the line search around `centre`, and
    /// that level (`None` when the search reaches past the band).
    fn window_peak(&self, centre: f32) -> Option<(usize, f32)> {
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
        Some((best, w[best]))
    }

    /// The line at a window peak: a local maximum of at least [`LINE_RATIO`].
    fn line_at(&self, best: usize, v: f32) -> Option<Line> {
        let w = self.white;
        (v >= LINE_RATIO && v >= w[best - 1] && v >= w[best + 1])
            .then_some(Line { bin: best, white: v })
    }

    fn line(&self, centre: f32) -> Option<Line> {
        self.window_peak(centre).and_then(|(best, v)| self.line_at(best, v))
    }

    /// The line near `centre` ([`Self::line`]) and the level of the search window: the
    /// natural log of its largest whitened level, the noise's level (1) at least.
    fn line_and_level(&self, centre: f32) -> (Option<Line>, f32) {
        match self.window_peak(centre) {
            Some((best, v)) => (self.line_at(best, v), if v > 1.0 { libm::logf(v) } else { 0.0 }),
            None => (None, 0.0),
        }
    }

    /// Levels of the comb at `bin`: harmonics 1 ..= [`CHECK_HARMONICS`] in the band.
    fn levels(&self, bin: f32) -> Levels {
        let mut lv = Levels::default();
        for h in 1..=CHECK_HARMONICS {
            let c = h as f32 * bin;
            if !self.in_band(c) {
                break;
            }
            let (line, level) = self.line_and_level(c);
            lv.level[h] = level;
            lv.found[h] = line.is_some();
            lv.n = h;
        }
        lv
    }

    /// Whether a comb at `bin` lies in the band for harmonic `h`.
    fn in_band(&self, centre: f32) -> bool {
        centre + self.search_radius(centre) as f32 + 2.5 < self.top as f32
    }

    /// The blade-passing fundamental (bins) of a candidate line at `bin`, or `None` when the
    /// comb's fundamental lies below `min_bin` (module doc, point 3).
    fn resolve(&self, bin: f32, min_bin: f32, max_bin: f32) -> Option<f32> {
        let lv = self.levels(bin);
        if let Some(m) = shaft_multiple(&lv, bin, max_bin) {
            return Some(self.refined(m as f32 * bin));
        }
        // Down: a harmonic of a lower fundamental, whose lines between this comb's are nearly
        // as strong as this comb's own.
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
            let mut ls = Levels::default();
            for j in 1..=CHECK_HARMONICS {
                let c = j as f32 * sub;
                if !self.in_band(c) || (j % d == 0 && j / d > lv.n) {
                    break;
                }
                if j % d == 0 {
                    (ls.level[j], ls.found[j]) = (lv.level[j / d], lv.found[j / d]);
                } else {
                    let (line, level) = self.line_and_level(c);
                    (ls.level[j], ls.found[j]) = (level, line.is_some());
                }
                ls.n = j;
            }
            if contrast(&ls, d).is_some_and(|c| c < OWN_HARMONIC_CONTRAST) {
                if sub < min_bin {
                    return None;
                }
                // The sub-multiple may itself be a shaft line: a candidate at a shaft comb's
                // third line would otherwise be moved down to the shaft rate.
                return Some(
                    shaft_multiple(&ls, sub, max_bin).map_or(sub, |m| self.refined(m as f32 * sub)),
                );
            }
        }
        Some(bin)
    }

    /// The refined position of the line near `centre`, or `centre` when there is none.
    fn refined(&self, centre: f32) -> f32 {
        self.line(centre).map_or(centre, |line| refine_peak(self.mags, line.bin).0)
    }

    /// The blade line of a comb at `bin`: the rotor's strongest line. When its second or
    /// third harmonic is [`BLADE_DOMINANCE`] times stronger than the line at `bin` (a shaft
    /// line: several rotors a few per cent apart fill a shaft comb's gaps, so the contrast test
    /// of [`Self::resolve`] cannot tell), that multiple, unless the lines between the
    /// multiples are stronger than they with that one line discounted ([`BLADE_VETO`]: a blade
    /// comb with one line raised by the room).
    fn blade_line(&self, bin: f32, max_bin: f32) -> f32 {
        // Line strengths as magnitudes: the whitening floor differs between the lines' blocks.
        let s1 = self.line(bin).map_or(0.0, |l| self.mags[l.bin]);
        let mut best = (bin, BLADE_DOMINANCE * s1, 1usize);
        for m in [2usize, 3] {
            let c = m as f32 * bin;
            if c > max_bin {
                break;
            }
            if let Some(line) = self.line(c) {
                if self.mags[line.bin] > best.1 {
                    best = (refine_peak(self.mags, line.bin).0, self.mags[line.bin], m);
                }
            }
        }
        let m = best.2;
        if m > 1 {
            let mut lv = self.levels(bin);
            if lv.n > m {
                lv.level[m] = 0.5 * (lv.level[m - 1] + lv.level[m + 1]);
                if contrast(&lv, m).is_some_and(|c| c < BLADE_VETO) {
                    return bin;
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
        Group { hz, amplitude, harmonicity, score, quality, first, passes, prior: 0 }
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
    /// Consecutive analyses before this one the group has passed ([`History::age_of`]).
    prior: u8,
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
    let rate_hz_per_hz = config.bpf_max_rate_per_s * hop_s;
    for g in groups.iter_mut() {
        let allowed = 2.0 * bin_hz + rate_hz_per_hz * g.hz;
        g.prior = history.age_of(g.hz, g.amplitude, allowed);
    }
    // Groups that continue a reported comb first, then the others, each strongest score first
    // (between combs of equal score, every line at the cap in clean recordings, the louder):
    // a comb of the analysis related to a reported one (its shaft comb, read from one noisy
    // spectrum) does not push that one out.
    groups.sort_unstable_by(|a, b| {
        (b.prior >= MIN_AGE)
            .cmp(&(a.prior >= MIN_AGE))
            .then(b.score.total_cmp(&a.score))
            .then(b.amplitude.total_cmp(&a.amplitude))
    });

    let mut out = Peaks::default();
    let mut next = History::new();
    let best = groups.iter().filter(|g| g.passes).map(|g| g.score).fold(0.0, f32::max);
    let tolerance = 1.5 * bin_hz;
    // The groups entered in `next` (the same order), as they would be reported.
    let mut passing = [Peak::default(); 4];
    let mut passing_first = [[0.0f32; 3]; 4];
    let mut n_passing = 0usize;
    for g in groups.iter() {
        let prior = g.prior;
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

/// Levels of a comb's lines ([`Spectrum::levels`]).
#[derive(Debug, Clone, Copy, Default)]
struct Levels {
    /// Natural log of the largest whitened level in each harmonic's search window, at least
    /// 0 (index 0 unused).
    level: [f32; CHECK_HARMONICS + 1],
    /// Whether a line was found there.
    found: [bool; CHECK_HARMONICS + 1],
    /// Highest harmonic in the band.
    n: usize,
}

impl Levels {
    /// The comb's extent: its highest found line within [`EXTENT_LOG`] of its strongest found
    /// line (0 when none is found).
    fn extent(&self) -> usize {
        let top =
            (1..=self.n).filter(|&h| self.found[h]).map(|h| self.level[h]).fold(0.0, f32::max);
        (1..=self.n)
            .rev()
            .find(|&h| self.found[h] && self.level[h] >= top - EXTENT_LOG)
            .unwrap_or(0)
    }
}

/// The multiple `m` (2 or 3, at most `max_bin / bin`) of a comb at `bin` whose lines carry it,
/// when the lines between the multiples are weak ([`SHAFT_CONTRAST`]): `bin` is a shaft line.
fn shaft_multiple(lv: &Levels, bin: f32, max_bin: f32) -> Option<usize> {
    let mut best: Option<(f32, usize)> = None;
    for m in 2..=3usize {
        if m as f32 * bin > max_bin {
            continue;
        }
        if let Some(c) = contrast(lv, m) {
            if c >= SHAFT_CONTRAST && best.is_none_or(|(b, _)| c > b) {
                best = Some((c, m));
            }
        }
    }
    best.map(|(_, m)| m)
}

/// The median contrast of a comb's multiples of `m` over the lines between them: for each
/// line `j > m` not a multiple of `m` whose neighbouring multiples lie within the comb's extent
/// ([`Levels::extent`]), the mean level of the two multiples minus the line's own (natural
/// log). The lowest line is left out: below the blade
/// fundamental, several rotors' shaft lines fall into one bin and add up, so it says nothing
/// about the comb's pattern. `None` when no triple qualifies.
fn contrast(lv: &Levels, m: usize) -> Option<f32> {
    let n = lv.extent();
    let mut c = [0.0f32; CHECK_HARMONICS];
    let mut k = 0;
    for j in m + 1..=n {
        let below = j / m * m;
        let above = below + m;
        if j % m == 0 || above > n {
            continue;
        }
        c[k] = 0.5 * (lv.level[below] + lv.level[above]) - lv.level[j];
        k += 1;
    }
    if k == 0 {
        return None;
    }
    let c = &mut c[..k];
    c.sort_unstable_by(f32::total_cmp);
    Some(if k % 2 == 1 { c[k / 2] } else { 0.5 * (c[k / 2 - 1] + c[k / 2]) })
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
