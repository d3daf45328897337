//! Drone-identification features of one audio frame (ALGORITHMS.md §10): a log-mel spectrum,
//! 13 MFCC and blade-passing-frequency (BPF) harmonic features, all from the frame's power
//! spectrum. The host's `aim id` computes them with this code, so a chip computing them from
//! the same frames gives the same bits (all maths through `libm`, no allocation).
//!
//! The frame is [`FRAME_LEN`] samples at [`SAMPLE_RATE_HZ`] (64 ms; a 48 kHz stream is
//! decimated by 3 first), Hann-windowed and transformed (microfft `rfft_1024`, 15.6 Hz bins):
//!
//! - **log-mel**: [`MEL_BANDS`] triangular bands, equally spaced on the mel scale
//!   (`mel = 2595 log10(1 + f/700)`) between [`MEL_LOW_HZ`] and [`MEL_HIGH_HZ`], unit peak (HTK
//!   style), energies in dB (10 log10) with a floor 100 dB below the frame's total power;
//! - **MFCC**: the orthonormal DCT-II of the log-mel vector, coefficients 0..[`MFCC_COUNT`]
//!   (c0 carries the level; a level-free classifier drops it);
//! - **harmonic**: the spectrum is whitened (each bin's power over the local noise floor, the
//!   smallest 3-bin mean within ±[`WHITEN_HALF_WIDTH`] bins, in dB, clamped to 0..=[`WHITE_MAX_DB`]) and a harmonic sum over fundamentals
//!   [`F0_LOW_HZ`]..[`F0_HIGH_HZ`] (1/24-octave grid, [`HARMONICS`] harmonics weighted 1/√h)
//!   picks the frame's comb fundamental f0 — the BPF of a multirotor. The features are
//!   `log2(f0 / 250 Hz)`, the comb's salience (mean whitened dB on its harmonics), the whitened
//!   level halfway and a third of the way between harmonics (a 2-blade propeller's shaft lines
//!   sit at f0/2 multiples, a 3-blade's at f0/3), and harmonics 2..=6 in dB relative to the
//!   first (the spectral envelope of the comb). See [`HarmonicFeatures`].
use core::f32::consts::PI;

/// Frame length, samples.
pub const FRAME_LEN: usize = 1024;
/// Sample rate the features are defined at, Hz.
pub const SAMPLE_RATE_HZ: f32 = 16_000.0;
/// Power-spectrum bins used (0 ..= Nyquist − 1 bin), one per 15.625 Hz.
pub const BINS: usize = FRAME_LEN / 2;
/// Width of one bin, Hz.
pub const BIN_HZ: f32 = SAMPLE_RATE_HZ / FRAME_LEN as f32;
/// Number of mel bands.
pub const MEL_BANDS: usize = 32;
/// Lower edge of the lowest mel band, Hz.
pub const MEL_LOW_HZ: f32 = 60.0;
/// Upper edge of the highest mel band, Hz.
pub const MEL_HIGH_HZ: f32 = 6_000.0;
/// Number of MFCC (c0 included).
pub const MFCC_COUNT: usize = 13;
/// Lowest comb fundamental searched, Hz.
pub const F0_LOW_HZ: f32 = 80.0;
/// Highest comb fundamental searched, Hz.
pub const F0_HIGH_HZ: f32 = 1_400.0;
/// Harmonics summed per fundamental candidate.
pub const HARMONICS: usize = 8;
/// Half-width of the whitening window, bins.
pub const WHITEN_HALF_WIDTH: usize = 12;
/// Largest whitened level, dB (a line in a silent spectrum counts as a clear line, no more).
pub const WHITE_MAX_DB: f32 = 60.0;
/// Number of harmonic features ([`HarmonicFeatures::to_array`]).
pub const HARMONIC_FEATURES: usize = 9;
/// Fundamental candidates: 1/24 octave from [`F0_LOW_HZ`] to [`F0_HIGH_HZ`].
const F0_CANDIDATES: usize = 100;

/// Reference of the comb fundamental's octave scale, Hz: `log2_f0` is `log2(f0 / F0_REF_HZ)`.
pub const F0_REF_HZ: f32 = 250.0;

/// The BPF harmonic features of one frame (units in the names; dB are whitened levels).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HarmonicFeatures {
    /// Comb fundamental, octaves re [`F0_REF_HZ`] (250 Hz): `log2(f0 / 250)`.
    pub log2_f0: f32,
    /// Mean whitened level on the comb's harmonics, dB.
    pub salience_db: f32,
    /// Mean whitened level at the half-way points `(h + ½) f0`, dB (2-blade shaft lines).
    pub half_db: f32,
    /// Mean whitened level at the third-way points `(h + ⅓) f0`, `(h + ⅔) f0`, dB (3-blade).
    pub third_db: f32,
    /// Raw level of harmonics 2..=6 relative to harmonic 1, dB.
    pub envelope_db: [f32; 5],
}

impl HarmonicFeatures {
    /// The features as a flat array, in field order.
    pub fn to_array(&self) -> [f32; HARMONIC_FEATURES] {
        let e = self.envelope_db;
        [self.log2_f0, self.salience_db, self.half_db, self.third_db, e[0], e[1], e[2], e[3], e[4]]
    }

    /// The comb fundamental, Hz.
    pub fn f0_hz(&self) -> f32 {
        F0_REF_HZ * libm::powf(2.0, self.log2_f0)
    }
}

/// All features of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameFeatures {
    /// Mel band energies, dB (arbitrary reference: the input's units squared).
    pub log_mel_db: [f32; MEL_BANDS],
    /// MFCC, orthonormal DCT-II of `log_mel_db`, dB.
    pub mfcc: [f32; MFCC_COUNT],
    /// BPF harmonic features.
    pub harmonic: HarmonicFeatures,
}

/// Precomputed tables: the mel filterbank (per bin: its segment and the rising weight), the
/// Hann window, the DCT matrix and the fundamental candidates.
#[derive(Clone, Debug)]
pub struct Extractor {
    /// Per bin, the mel segment it falls in (band `seg` rising, band `seg − 1` falling), or
    /// `u8::MAX` outside the filterbank.
    segment: [u8; BINS],
    /// Per bin, the rising weight in its segment (the falling one is `1 − w`).
    rise: [f32; BINS],
    window: [f32; FRAME_LEN],
    dct: [[f32; MEL_BANDS]; MFCC_COUNT],
    f0_bins: [f32; F0_CANDIDATES],
}

impl Default for Extractor {
    fn default() -> Self {
        Self::new()
    }
}

fn hz_to_mel(hz: f32) -> f32 {
    2595.0 * libm::log10f(1.0 + hz / 700.0)
}

impl Extractor {
    /// Builds the tables.
    pub fn new() -> Self {
        let mut segment = [u8::MAX; BINS];
        let mut rise = [0.0f32; BINS];
        let (m_lo, m_hi) = (hz_to_mel(MEL_LOW_HZ), hz_to_mel(MEL_HIGH_HZ));
        let step = (m_hi - m_lo) / (MEL_BANDS + 1) as f32;
        for k in 0..BINS {
            let m = hz_to_mel(k as f32 * BIN_HZ);
            if m < m_lo || m >= m_hi {
                continue;
            }
            let x = (m - m_lo) / step;
            let seg = (x as usize).min(MEL_BANDS);
            segment[k] = seg as u8;
            rise[k] = x - seg as f32;
        }
        let mut window = [0.0f32; FRAME_LEN];
        crate::window::hann(&mut window);
        let mut dct = [[0.0f32; MEL_BANDS]; MFCC_COUNT];
        let n = MEL_BANDS as f32;
        for (c, row) in dct.iter_mut().enumerate() {
            let scale = if c == 0 { libm::sqrtf(1.0 / n) } else { libm::sqrtf(2.0 / n) };
            for (b, v) in row.iter_mut().enumerate() {
                *v = scale * libm::cosf(PI * c as f32 * (b as f32 + 0.5) / n);
            }
        }
        let mut f0_bins = [0.0f32; F0_CANDIDATES];
        for (i, f) in f0_bins.iter_mut().enumerate() {
            let hz = F0_LOW_HZ * libm::powf(2.0, i as f32 / 24.0);
            *f = hz.min(F0_HIGH_HZ) / BIN_HZ;
        }
        Self { segment, rise, window, dct, f0_bins }
    }

    /// Power spectrum of one frame: Hann window, real FFT, `|X_k|²` for bins `0..BINS`.
    /// `frame` is overwritten.
    pub fn power_spectrum(&self, frame: &mut [f32; FRAME_LEN], power: &mut [f32; BINS]) {
        for (x, w) in frame.iter_mut().zip(&self.window) {
            *x *= w;
        }
        let spectrum = microfft::real::rfft_1024(frame);
        for (p, c) in power.iter_mut().zip(spectrum.iter()) {
            *p = c.re * c.re + c.im * c.im;
        }
        // microfft packs the Nyquist term into bin 0's imaginary part: bin 0 is DC only.
        power[0] = spectrum[0].re * spectrum[0].re;
    }

    /// The features of one frame's power spectrum (`power_spectrum`'s output).
    pub fn features(&self, power: &[f32; BINS]) -> FrameFeatures {
        let total: f32 = power.iter().sum();
        let floor = total * 1e-10 + 1e-30;
        // Mel energies.
        let mut mel = [0.0f32; MEL_BANDS];
        for ((&seg, &w), &p) in self.segment.iter().zip(&self.rise).zip(power) {
            if seg == u8::MAX {
                continue;
            }
            let seg = seg as usize;
            if seg < MEL_BANDS {
                mel[seg] += w * p;
            }
            if seg >= 1 {
                mel[seg - 1] += (1.0 - w) * p;
            }
        }
        let mut log_mel_db = [0.0f32; MEL_BANDS];
        for (l, e) in log_mel_db.iter_mut().zip(&mel) {
            *l = 10.0 * libm::log10f(e + floor);
        }
        let mut mfcc = [0.0f32; MFCC_COUNT];
        for (c, row) in mfcc.iter_mut().zip(&self.dct) {
            *c = row.iter().zip(&log_mel_db).map(|(a, b)| a * b).sum();
        }
        FrameFeatures { log_mel_db, mfcc, harmonic: self.harmonic(power, floor) }
    }

    /// The BPF harmonic features (module docs).
    fn harmonic(&self, power: &[f32; BINS], floor: f32) -> HarmonicFeatures {
        // Whitened spectrum, dB ≥ 0: each bin over the local noise floor, the smallest 3-bin
        // mean within ±WHITEN_HALF_WIDTH bins (lines stand out above it, weak ones too).
        let mut smooth = [0.0f32; BINS];
        for (k, s) in smooth.iter_mut().enumerate() {
            let lo = k.saturating_sub(1);
            let hi = (k + 2).min(BINS);
            *s = power[lo..hi].iter().sum::<f32>() / (hi - lo) as f32;
        }
        let mut white = [0.0f32; BINS];
        for (k, w) in white.iter_mut().enumerate() {
            let lo = k.saturating_sub(WHITEN_HALF_WIDTH);
            let hi = (k + WHITEN_HALF_WIDTH + 1).min(BINS);
            let noise = smooth[lo..hi].iter().cloned().fold(f32::MAX, f32::min);
            *w = (10.0 * libm::log10f((power[k] + floor) / (noise + floor)))
                .clamp(0.0, WHITE_MAX_DB);
        }
        // Level near a fractional bin: the largest of the two bins around it and the nearest
        // neighbours (a line between bins spreads over both).
        let near = |spec: &[f32; BINS], bin: f32| -> Option<f32> {
            let k = libm::floorf(bin) as usize;
            if k + 1 >= BINS {
                return None;
            }
            Some(spec[k].max(spec[k + 1]))
        };
        // Harmonic sum of whitened amplitudes (√(P / floor) − 1): a weak shaft line adds
        // little, so the comb of the BPF beats the shaft-rate comb below it.
        let mut amp = [0.0f32; BINS];
        for (a, w) in amp.iter_mut().zip(&white) {
            *a = libm::powf(10.0, w / 20.0) - 1.0;
        }
        let mut best = (0usize, f32::MIN);
        for (i, &b) in self.f0_bins.iter().enumerate() {
            let mut sum = 0.0f32;
            for h in 1..=HARMONICS {
                let Some(v) = near(&amp, b * h as f32) else { break };
                sum += v / libm::sqrtf(h as f32);
            }
            if sum > best.1 {
                best = (i, sum);
            }
        }
        let b0 = self.f0_bins[best.0];
        let salience_db = {
            let (mut sum, mut wsum) = (0.0f32, 0.0f32);
            for h in 1..=HARMONICS {
                let Some(v) = near(&white, b0 * h as f32) else { break };
                let w = 1.0 / libm::sqrtf(h as f32);
                sum += w * v;
                wsum += w;
            }
            if wsum > 0.0 {
                sum / wsum
            } else {
                0.0
            }
        };
        let mean_at = |offsets: &[f32]| -> f32 {
            let (mut sum, mut n) = (0.0f32, 0u32);
            for h in 0..HARMONICS {
                for o in offsets {
                    if let Some(v) = near(&white, b0 * (h as f32 + o)) {
                        sum += v;
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
        let mut envelope_db = [0.0f32; 5];
        let first = near(power, b0).unwrap_or(0.0) + floor;
        for (i, e) in envelope_db.iter_mut().enumerate() {
            let p = near(power, b0 * (i + 2) as f32).unwrap_or(0.0) + floor;
            *e = 10.0 * libm::log10f(p / first);
        }
        HarmonicFeatures {
            log2_f0: libm::log2f(b0 * BIN_HZ / F0_REF_HZ),
            salience_db,
            half_db: mean_at(&[0.5]),
            third_db: mean_at(&[1.0 / 3.0, 2.0 / 3.0]),
            envelope_db,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame of harmonics of `f0` with amplitudes `amps`, plus shaft lines at `f0 / blades`
    /// multiples 20 dB down, plus white noise (uniform, RMS 0.03).
    fn comb(f0: f32, amps: &[f32], blades: usize) -> [f32; FRAME_LEN] {
        let mut x = [0.0f32; FRAME_LEN];
        let mut lcg = 12345u32;
        for (n, v) in x.iter_mut().enumerate() {
            lcg = lcg.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *v = 0.1 * ((lcg >> 8) as f32 / (1u32 << 24) as f32 - 0.5);
            let t = n as f32 / SAMPLE_RATE_HZ;
            for (h, a) in amps.iter().enumerate() {
                *v += a * libm::sinf(2.0 * PI * f0 * (h + 1) as f32 * t + h as f32);
            }
            for m in 1..blades * amps.len() {
                if m % blades != 0 {
                    *v += 0.1 * libm::sinf(2.0 * PI * f0 * m as f32 / blades as f32 * t);
                }
            }
        }
        x
    }

    fn features_of(mut x: [f32; FRAME_LEN]) -> FrameFeatures {
        let e = Extractor::new();
        let mut p = [0.0f32; BINS];
        e.power_spectrum(&mut x, &mut p);
        e.features(&p)
    }

    #[test]
    fn harmonic_sum_finds_the_comb_fundamental() {
        for f0 in [140.0f32, 328.0, 560.0, 900.0] {
            let f = features_of(comb(f0, &[1.0, 0.7, 0.5, 0.35, 0.25, 0.2, 0.15, 0.1], 2));
            let found = f.harmonic.f0_hz();
            // 1/24-octave grid: within 3 %.
            assert!((found / f0 - 1.0).abs() < 0.03, "f0 {f0}: found {found}");
            assert!(f.harmonic.salience_db > 10.0, "{:?}", f.harmonic);
        }
    }

    #[test]
    fn shaft_lines_tell_two_from_three_blades() {
        let amps = [1.0, 0.7, 0.5, 0.35, 0.25, 0.2];
        let two = features_of(comb(300.0, &amps, 2)).harmonic;
        let three = features_of(comb(300.0, &amps, 3)).harmonic;
        assert!(two.half_db > two.third_db + 3.0, "{two:?}");
        assert!(three.third_db > three.half_db + 3.0, "{three:?}");
        // The envelope follows the amplitudes: harmonic 2 at 20 log10(0.7) = −3.1 dB.
        assert!((two.envelope_db[0] + 3.1).abs() < 1.5, "{two:?}");
    }

    #[test]
    fn mel_band_energy_of_a_tone_and_mfcc_of_a_flat_spectrum() {
        // A flat power spectrum: every band's energy is its filter's sum, and with equal log
        // energies only c0 would be nonzero; check the DCT is orthonormal instead: c0 of a
        // constant vector L is L·√n.
        let e = Extractor::new();
        let p = [1.0f32; BINS];
        let f = e.features(&p);
        let mut constant = f.log_mel_db;
        constant.fill(3.0);
        let c: f32 = e.dct[0].iter().zip(&constant).map(|(a, b)| a * b).sum();
        assert!((c - 3.0 * libm::sqrtf(MEL_BANDS as f32)).abs() < 1e-4);
        for row in &e.dct[1..] {
            let c: f32 = row.iter().zip(&constant).map(|(a, b)| a * b).sum();
            assert!(c.abs() < 1e-4);
        }
        // A single tone lands in the band(s) whose triangle covers it, nowhere else.
        let mut x = [0.0f32; FRAME_LEN];
        for (n, v) in x.iter_mut().enumerate() {
            *v = libm::sinf(2.0 * PI * 1000.0 * n as f32 / SAMPLE_RATE_HZ);
        }
        let f = features_of(x);
        let top = f.log_mel_db.iter().cloned().fold(f32::MIN, f32::max);
        let loud: usize = f.log_mel_db.iter().filter(|&&l| l > top - 30.0).count();
        assert!((1..=3).contains(&loud), "{:?}", f.log_mel_db);
        let centre = |b: usize| {
            let (lo, hi) = (hz_to_mel(MEL_LOW_HZ), hz_to_mel(MEL_HIGH_HZ));
            let m = lo + (hi - lo) * (b + 1) as f32 / (MEL_BANDS + 1) as f32;
            700.0 * (libm::powf(10.0, m / 2595.0) - 1.0)
        };
        let arg = (0..MEL_BANDS).find(|&b| f.log_mel_db[b] == top).unwrap();
        assert!((centre(arg) / 1000.0 - 1.0).abs() < 0.12, "band {arg} at {} Hz", centre(arg));
    }
}
