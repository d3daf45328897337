//! Drone-identification features of the BPF path's long spectrum (issue 16, ALGORITHMS.md §10):
//! what the chip sends in an MFCC frame.
//!
//! The spectral path ([`crate::bpf`]) already transforms the last 0.512 s of the mono signal at
//! 8 kHz (`rfft_4096`, 1.953 Hz bins) every 0.256 s and whitens it ([`crate::comb::whiten`]).
//! These features reuse that spectrum, so they cost no transform of their own (a separate
//! 16 kHz stream for [`crate::features`] would need a 24 → 16 kHz resampler and an `rfft_1024`
//! per frame, several times the 0.2 M instructions per second the Cortex-M4F budget has left):
//!
//! - **log-mel**: [`MEL_BANDS`] triangular bands (unit peak, linear in Hz between centres
//!   equally spaced on the mel scale `2595 log10(1 + f/700)`) from [`MEL_LOW_HZ`] to
//!   [`MEL_HIGH_HZ`] (inside the decimator's flat pass band at 16 and 48 kHz input), band
//!   energies of the power spectrum in dB relative to a full-scale sine (a sine of amplitude
//!   `a`, fraction of full scale, at a band's centre reads `20 log10 a` there), floored at
//!   [`FLOOR_DB`];
//! - **MFCC**: the orthonormal DCT-II of the log-mel vector, coefficients 0..[`MFCC_COUNT`];
//! - **harmonic**: the comb fundamental f0 with the largest harmonic sum over the whitened
//!   spectrum (candidates: the [`CANDIDATES`] strongest local maxima of the whitened spectrum
//!   between `Config::bpf_min_hz` and `Config::bpf_max_hz`, refined below one bin; a line's
//!   level is the largest whitened level within ±(1 + 0.2 % of its frequency) bins, less the
//!   floor's 1, harmonics 1..=[`HARMONICS`] weighted 1/√h), then the same
//!   nine numbers as [`crate::features::HarmonicFeatures`]: `log2(f0 / 250 Hz)`, the comb's
//!   salience (weighted mean line level, dB over the floor), the mean levels halfway and a
//!   third of the way between harmonics (2- and 3-blade shaft lines), and harmonics 2..=6 in
//!   dB relative to the first (magnitudes);
//! - **second comb**: the same nine numbers for the strongest comb whose fundamental is not
//!   the first source's: outside the rotor cluster (±8 %) of ¼, ⅓, ½, 1, 2 and 3 times the
//!   first fundamental and off the first comb's harmonics and shaft lines (its own candidates:
//!   the strongest such local maxima). Beside a louder fan or pump the first comb
//!   is that source's, and the drone's is this one (its blade-passing comb, or its shaft comb
//!   at a half or a third of it when that comb's sum also takes in lines of the other source).
//!
//! State-free: the features of one analysis depend on its spectrum only (not on the comb's
//! continuity), so a clip and a live stream give the same numbers for the same window.

use core::f32::consts::PI;

use crate::bpf::{refine_peak, ANALYSIS_LEN, DECIMATED_RATE_HZ};
use crate::features::{HarmonicFeatures, F0_REF_HZ};
use crate::Config;

/// Number of mel bands.
pub const MEL_BANDS: usize = 24;
/// Lower edge of the lowest mel band, Hz.
pub const MEL_LOW_HZ: f32 = 60.0;
/// Upper edge of the highest mel band, Hz.
pub const MEL_HIGH_HZ: f32 = 3_500.0;
/// Number of MFCC (c0 included).
pub const MFCC_COUNT: usize = 13;
/// Harmonics summed per fundamental candidate.
pub const HARMONICS: usize = 8;
/// Fundamental candidates scored per analysis.
pub const CANDIDATES: usize = 6;
/// Lowest log-mel level, dB (relative to a full-scale sine).
pub const FLOOR_DB: f32 = -150.0;
/// Bin width of the spectrum, Hz.
const BIN_HZ: f32 = DECIMATED_RATE_HZ as f32 / ANALYSIS_LEN as f32;

/// The identification features of one BPF analysis (units in the names).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IdFeatures {
    /// Index of the (input-rate) sample at which the analysis window starts (as the `Peaks`
    /// of the same analysis).
    pub sample_index: u64,
    /// Input-rate samples covered by the analysis window.
    pub span_samples: u32,
    /// Mel band energies, dB relative to a full-scale sine at the band's centre.
    pub log_mel_db: [f32; MEL_BANDS],
    /// MFCC, orthonormal DCT-II of `log_mel_db`, dB.
    pub mfcc_db: [f32; MFCC_COUNT],
    /// BPF comb features of the window: the comb with the largest harmonic sum.
    pub harmonic: HarmonicFeatures,
    /// The same features of the strongest comb whose fundamental is not the first source's (not
    /// in the rotor cluster of its fundamental, its octaves, a third or quarter of it, nor on
    /// its harmonics or shaft lines): a second tonal source beside the drone, or the drone
    /// beside a louder one; all 0 when no candidate is left. (In noise it is the best comb of
    /// noise maxima, with a low salience.)
    pub second: HarmonicFeatures,
}

/// Precomputed tables: mel band edges (bins) and the DCT matrix. `const`-constructible empty,
/// filled by [`IdExtractor::configure`].
#[derive(Debug, Clone)]
pub struct IdExtractor {
    /// Bin of each band's lower edge, centre and upper edge: band b spans
    /// `edges[b]..edges[b + 2]` with its peak at `edges[b + 1]`.
    edges: [u16; MEL_BANDS + 2],
    dct: [[f32; MEL_BANDS]; MFCC_COUNT],
}

fn hz_to_mel(hz: f32) -> f32 {
    2595.0 * libm::log10f(1.0 + hz / 700.0)
}

fn mel_to_hz(mel: f32) -> f32 {
    700.0 * (libm::powf(10.0, mel / 2595.0) - 1.0)
}

impl IdExtractor {
    /// Empty tables (all bands empty); [`IdExtractor::configure`] fills them.
    pub const fn empty() -> Self {
        Self { edges: [0; MEL_BANDS + 2], dct: [[0.0; MEL_BANDS]; MFCC_COUNT] }
    }

    /// Builds the tables.
    pub fn configure(&mut self) {
        let (lo, hi) = (hz_to_mel(MEL_LOW_HZ), hz_to_mel(MEL_HIGH_HZ));
        for (i, e) in self.edges.iter_mut().enumerate() {
            let hz = mel_to_hz(lo + (hi - lo) * i as f32 / (MEL_BANDS + 1) as f32);
            *e = libm::roundf(hz / BIN_HZ) as u16;
        }
        let n = MEL_BANDS as f32;
        for (c, row) in self.dct.iter_mut().enumerate() {
            let scale = if c == 0 { libm::sqrtf(1.0 / n) } else { libm::sqrtf(2.0 / n) };
            for (b, v) in row.iter_mut().enumerate() {
                *v = scale * libm::cosf(PI * c as f32 * (b as f32 + 0.5) / n);
            }
        }
    }

    /// The features of one analysis: `mags` the magnitude spectrum and `white` the whitened
    /// one, both [`ANALYSIS_LEN`] / 2 bins (the two halves of the buffer [`crate::bpf::find_peaks`]
    /// leaves). `sample_index` and `span_samples` are left 0.
    pub fn compute(&self, mags: &[f32], white: &[f32], config: &Config) -> IdFeatures {
        let mut out = IdFeatures::default();
        // A full-scale sine on a bin: |X| = N/4 there and N/8 on both neighbours (Hann), so
        // 1.5 (N/4)² in all.
        let norm = {
            let full = ANALYSIS_LEN as f32 / 4.0;
            1.0 / (1.5 * full * full)
        };
        let floor = libm::powf(10.0, FLOOR_DB / 10.0);
        // One pass over the bins: the bins between edges s and s + 1 rise in band s and fall
        // in band s − 1 (weights r and 1 − r, r from 0 at edge s).
        let mut mel = [0.0f32; MEL_BANDS];
        for s in 0..=MEL_BANDS {
            let (a, b) = (self.edges[s] as usize, self.edges[s + 1] as usize);
            if b <= a {
                continue;
            }
            let step = 1.0 / (b - a) as f32;
            let (mut r, mut up, mut all) = (0.0f32, 0.0f32, 0.0f32);
            for &m in &mags[a..b] {
                let p = m * m;
                up += r * p;
                all += p;
                r += step;
            }
            if s < MEL_BANDS {
                mel[s] += up;
            }
            if s >= 1 {
                mel[s - 1] += all - up;
            }
        }
        for (l, e) in out.log_mel_db.iter_mut().zip(&mel) {
            *l = 10.0 * libm::log10f(e * norm + floor);
        }
        for (c, row) in out.mfcc_db.iter_mut().zip(&self.dct) {
            *c = row.iter().zip(&out.log_mel_db).map(|(a, b)| a * b).sum();
        }
        (out.harmonic, out.second) = harmonic(mags, white, config);
        out
    }
}

/// Largest value of `spec` within ±(1 + 0.2 % of the bin) bins of fractional bin `bin`, or
/// `None` past the spectrum's end.
#[inline]
fn line(spec: &[f32], bin: f32) -> Option<f32> {
    let k = (bin + 0.5) as usize;
    let r = 1 + (bin * 0.002) as usize;
    if k + r >= spec.len() || k < r {
        return None;
    }
    let mut best = 0.0f32;
    for &v in &spec[k - r..=k + r] {
        if v > best {
            best = v;
        }
    }
    Some(best)
}

/// Whitened magnitude ratio to dB over the floor, ≥ 0.
#[inline]
fn white_db(w: f32) -> f32 {
    if w > 1.0 {
        20.0 * libm::log10f(w)
    } else {
        0.0
    }
}

/// Whether fundamental bin `b` belongs to the source of fundamental bin `b0`: within the rotor
/// cluster (±[`CLUSTER`] of it, one bin more) of `r · b0` for `r` in [`CLUSTER_RATIOS`] (the
/// other rotors of the same drone, their octaves and a shaft comb's fundamental), or within
/// ±(1 + 0.3 % of `b`) bins of a multiple of `b0 / q`, q = 1..=3 (its harmonics and its 2- and
/// 3-blade shaft lines).
#[inline]
fn related(b: f32, b0: f32) -> bool {
    let in_cluster = CLUSTER_RATIOS.iter().any(|&r| (b - r * b0).abs() <= 1.0 + CLUSTER * r * b0);
    let tol = 1.0 + 0.003 * b;
    in_cluster
        || (1..=3).any(|q| {
            let step = b0 / q as f32;
            let n = libm::roundf(b / step);
            n >= 1.0 && (b - n * step).abs() <= tol
        })
}

/// Half-width of a drone's rotor cluster, fraction of its frequency (the rotors of one
/// airframe turn within a few per cent of each other).
const CLUSTER: f32 = 0.08;
/// Multiples of the first comb's fundamental around which [`related`] takes the whole rotor
/// cluster as the first source's.
const CLUSTER_RATIOS: [f32; 6] = [0.25, 1.0 / 3.0, 0.5, 1.0, 2.0, 3.0];

/// The [`CANDIDATES`] strongest local maxima of the whitened spectrum between `lo` and `hi`
/// (bins) that `keep` accepts, strongest first (unused entries `(0, 0.0)`).
fn candidates(
    white: &[f32],
    lo: usize,
    hi: usize,
    keep: impl Fn(usize) -> bool,
) -> [(usize, f32); CANDIDATES] {
    let mut cand = [(0usize, 0.0f32); CANDIDATES];
    for k in lo..=hi {
        let v = white[k];
        if v > cand[CANDIDATES - 1].1 && v >= white[k - 1] && v > white[k + 1] && keep(k) {
            let mut i = CANDIDATES - 1;
            while i > 0 && cand[i - 1].1 < v {
                cand[i] = cand[i - 1];
                i -= 1;
            }
            cand[i] = (k, v);
        }
    }
    cand
}

/// The candidate with the largest harmonic sum, on its refined fundamental (bin), or 0.0.
fn strongest_comb(mags: &[f32], white: &[f32], cand: &[(usize, f32)]) -> f32 {
    let mut best = (0.0f32, f32::MIN);
    for &(k, v) in cand {
        if v <= 0.0 {
            break;
        }
        let b = refine_peak(mags, k).0;
        let mut sum = 0.0f32;
        for h in 1..=HARMONICS {
            let Some(l) = line(white, b * h as f32) else { break };
            // Amplitude over the floor, uncapped: the strong blade-passing lines outweigh the
            // weak shaft lines between them, so the sub-multiple does not win.
            sum += (l - 1.0).max(0.0) * INV_SQRT[h - 1];
        }
        if sum > best.1 {
            best = (b, sum);
        }
    }
    best.0
}

/// The strongest comb and the strongest comb not [`related`] to it.
fn harmonic(mags: &[f32], white: &[f32], config: &Config) -> (HarmonicFeatures, HarmonicFeatures) {
    let lo = ((config.bpf_min_hz / BIN_HZ) as usize).max(2);
    let hi = ((config.bpf_max_hz / BIN_HZ) as usize).min(white.len() - 2);
    let b0 = strongest_comb(mags, white, &candidates(white, lo, hi, |_| true));
    if b0 <= 0.0 {
        return Default::default();
    }
    let b1 = strongest_comb(mags, white, &candidates(white, lo, hi, |k| !related(k as f32, b0)));
    (comb_features(mags, white, b0), comb_features(mags, white, b1))
}

/// The nine numbers of the comb of fundamental bin `b0` (all 0 for `b0` ≤ 0).
fn comb_features(mags: &[f32], white: &[f32], b0: f32) -> HarmonicFeatures {
    if b0 <= 0.0 {
        return HarmonicFeatures::default();
    }
    let (mut sum, mut wsum) = (0.0f32, 0.0f32);
    for h in 1..=HARMONICS {
        let Some(l) = line(white, b0 * h as f32) else { break };
        sum += INV_SQRT[h - 1] * white_db(l);
        wsum += INV_SQRT[h - 1];
    }
    let salience_db = if wsum > 0.0 { sum / wsum } else { 0.0 };
    let mean_at = |offsets: &[f32]| -> f32 {
        let (mut sum, mut n) = (0.0f32, 0u32);
        for h in 0..HARMONICS {
            for o in offsets {
                if let Some(l) = line(white, b0 * (h as f32 + o)) {
                    sum += white_db(l);
                    n += 1;
                }
            }
        }
        if n > 0 {
            sum / n as f32
        } else {
            0.0
        }
    };
    let tiny = 1e-12f32;
    let first = line(mags, b0).unwrap_or(0.0) + tiny;
    let mut envelope_db = [0.0f32; 5];
    for (i, e) in envelope_db.iter_mut().enumerate() {
        let m = line(mags, b0 * (i + 2) as f32).unwrap_or(0.0) + tiny;
        *e = 20.0 * libm::log10f(m / first);
    }
    HarmonicFeatures {
        log2_f0: libm::log2f(b0 * BIN_HZ / F0_REF_HZ),
        salience_db,
        half_db: mean_at(&[0.5]),
        third_db: mean_at(&[1.0 / 3.0, 2.0 / 3.0]),
        envelope_db,
    }
}

/// 1/√h for h = 1..=8.
const INV_SQRT: [f32; HARMONICS] =
    [1.0, 0.707_106_77, 0.577_350_26, 0.5, 0.447_213_6, 0.408_248_3, 0.377_964_47, 0.353_553_38];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bpf::{find_peaks, ANALYSIS_LEN};

    /// The features of an 8 kHz window: harmonics of `f0` with amplitudes `amps` (fraction of
    /// full scale), shaft lines at `f0 / blades` multiples 20 dB below the first harmonic, and
    /// white noise (RMS 0.001).
    fn features_of(f0: f32, amps: &[f32], blades: usize) -> IdFeatures {
        features_of_two(f0, amps, blades, 0.0, &[])
    }

    /// As [`features_of`], plus a second comb of fundamental `f1` (no shaft lines).
    fn features_of_two(f0: f32, amps: &[f32], blades: usize, f1: f32, amps1: &[f32]) -> IdFeatures {
        let mut x = [0.0f32; ANALYSIS_LEN];
        let mut lcg = 99u32;
        let fs = DECIMATED_RATE_HZ as f32;
        for (n, v) in x.iter_mut().enumerate() {
            lcg = lcg.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *v = 0.0035 * ((lcg >> 8) as f32 / (1u32 << 24) as f32 - 0.5);
            let t = n as f32 / fs;
            for (h, a) in amps.iter().enumerate() {
                *v += a * libm::sinf(2.0 * PI * f0 * (h + 1) as f32 * t + h as f32);
            }
            for (h, a) in amps1.iter().enumerate() {
                *v += a * libm::sinf(2.0 * PI * f1 * (h + 1) as f32 * t + 0.5 * h as f32);
            }
            for m in 1..blades * amps.len() {
                if m % blades != 0 {
                    *v += 0.1 * amps[0] * libm::sinf(2.0 * PI * f0 * m as f32 / blades as f32 * t);
                }
            }
        }
        crate::window::apply_hann(&mut x, &crate::gcc_phat::Twiddles::new());
        let config = Config::new(crate::Geometry::respeaker_4mic(), 48_000);
        let _ = find_peaks(&mut x, &config, &mut crate::comb::History::new());
        let mut e = IdExtractor::empty();
        e.configure();
        let (mags, white) = x.split_at(ANALYSIS_LEN / 2);
        e.compute(mags, white, &config)
    }

    #[test]
    fn the_comb_fundamental_and_its_envelope_are_found() {
        let amps = [0.1, 0.05, 0.025, 0.0125, 0.00625, 0.003];
        for f0 in [165.0f32, 328.0, 560.0, 900.0] {
            let h = features_of(f0, &amps, 2).harmonic;
            let found = h.f0_hz();
            // Refined below one bin (1.95 Hz).
            assert!((found - f0).abs() < 0.5, "f0 {f0}: found {found}");
            assert!(h.salience_db > 20.0, "{h:?}");
            // Harmonic h+1 is 6.02 dB per step below the first, where in the 3.8 kHz band.
            for (i, e) in h.envelope_db.iter().enumerate() {
                if f0 * (i + 2) as f32 <= 3_700.0 {
                    let want = -6.02 * (i + 1) as f32;
                    // Hann scalloping: up to 1.42 dB between on- and half-bin lines.
                    assert!((e - want).abs() < 1.5, "f0 {f0}: env {i} {e} want {want}");
                }
            }
        }
    }

    #[test]
    fn the_second_comb_is_the_other_source_not_the_first_ones_lines() {
        // A loud 230 Hz pump comb and a drone 12 dB below it at 328 Hz (2-blade shaft lines):
        // the pump is the first comb and the second is the drone's: its blade-passing comb or
        // its shaft comb (164 Hz, which also sums the pump's line at 1150 Hz), not the pump's.
        let pump = [0.2, 0.1, 0.05, 0.025, 0.0125, 0.006];
        let drone = [0.05, 0.025, 0.0125, 0.006];
        let f = features_of_two(328.0, &drone, 2, 230.0, &pump);
        assert!((f.harmonic.f0_hz() - 230.0).abs() < 0.5, "{:?}", f.harmonic);
        let second = f.second.f0_hz();
        let on_drone = [328.0, 164.0].iter().any(|d| (second - d).abs() < 0.5);
        assert!(on_drone && f.second.salience_db > 15.0, "{second} Hz: {:?}", f.second);
        assert!(!related(second / BIN_HZ, 230.0 / BIN_HZ));
        // Its strongest line is the drone's blade-passing line (harmonic 2 of a shaft comb).
        if (second - 164.0).abs() < 0.5 {
            assert!(f.second.envelope_db[0] > 10.0, "{:?}", f.second);
        }
        // The drone alone: its comb first; the second is a comb of noise maxima, found but far
        // weaker (none of the drone's own lines, which would sum near the first's salience).
        let f = features_of(328.0, &drone, 2);
        assert!((f.harmonic.f0_hz() - 328.0).abs() < 0.5, "{:?}", f.harmonic);
        assert!(f.second.salience_db > 0.0, "{f:?}");
        assert!(f.second.salience_db + 15.0 < f.harmonic.salience_db, "{f:?}");
    }

    #[test]
    fn related_combs_are_the_cluster_octaves_harmonics_and_shaft_lines() {
        let b0 = 300.0 / BIN_HZ;
        for hz in
            [300.0, 318.0, 282.0, 150.0, 600.0, 640.0, 900.0, 100.0, 75.0, 1500.0, 450.0, 700.0]
        {
            assert!(related(hz / BIN_HZ, b0), "{hz} Hz");
        }
        for hz in [220.0, 250.0, 370.0, 520.0, 430.0] {
            assert!(!related(hz / BIN_HZ, b0), "{hz} Hz");
        }
    }

    #[test]
    fn shaft_lines_tell_two_from_three_blades() {
        let amps = [0.1, 0.07, 0.05, 0.035, 0.025, 0.02];
        let two = features_of(300.0, &amps, 2).harmonic;
        let three = features_of(300.0, &amps, 3).harmonic;
        assert!(two.half_db > two.third_db + 6.0, "{two:?}");
        assert!(three.third_db > three.half_db + 6.0, "{three:?}");
    }

    #[test]
    fn a_tone_lands_in_its_band_at_its_level_and_the_dct_is_orthonormal() {
        // One 0.1 full-scale tone at a band's centre: that band reads 20 log10 0.1 = −20 dB
        // (the main lobe's neighbours sit a bin off the triangle's peak: −0.03 dB).
        let mut e = IdExtractor::empty();
        e.configure();
        let b = 10;
        let f = e.edges[b + 1] as f32 * BIN_HZ;
        let out = features_of(f, &[0.1], 2);
        assert!((out.log_mel_db[b] + 20.0).abs() < 0.1, "{:?}", out.log_mel_db);
        let top = out.log_mel_db.iter().cloned().fold(f32::MIN, f32::max);
        assert_eq!(top, out.log_mel_db[b]);
        // c0 of a constant vector L is L·√n, the others vanish.
        for (c, row) in e.dct.iter().enumerate() {
            let s: f32 = row.iter().map(|v| v * 3.0).sum();
            let want = if c == 0 { 3.0 * libm::sqrtf(MEL_BANDS as f32) } else { 0.0 };
            assert!((s - want).abs() < 1e-4, "c{c}: {s}");
        }
    }
}
