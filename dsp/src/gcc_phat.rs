//! GCC-PHAT: unit-magnitude (PHAT) spectra, averaged cross spectra over the band, and the delay
//! search within the physical lag range with exact sub-sample refinement.
//!
//! For microphones i, j the averaged cross spectrum over band bins k = k0 .. k0 + B is
//! `G(k) = Σ_blocks U_j(k) · conj(U_i(k))` with `U = X / |X|`. Its band-limited correlation
//!
//! ```text
//!     R(τ) = Σ_k Re( G(k) · e^{j 2π k τ / K} )         (K = FFT length, τ in samples)
//! ```
//!
//! peaks at τ = t_j − t_i, the arrival at j minus the arrival at i. R is evaluated directly, by
//! sums over the band bins, at the integer lags |τ| ≤ L (L = pair distance / c · fs + 1) only —
//! far cheaper than an inverse FFT per pair — and the best lag is refined by a parabola through
//! three lags followed by Newton steps on R'(τ) = 0, which are exact for this band-limited R.

use core::f32::consts::PI;
use microfft::Complex32;

/// Exact sines and cosines of 2π·m/1024 for integer m (a quarter-wave table): the phasors of
/// the integer-lag correlation sums without a `sinf`/`cosf` call each.
#[derive(Debug, Clone)]
pub struct Twiddles {
    quarter: [f32; TWIDDLE_QUARTER + 1],
}

const TWIDDLE_GRID: usize = 1024;
const TWIDDLE_QUARTER: usize = TWIDDLE_GRID / 4;

impl Twiddles {
    /// The table (257 `libm::cosf` calls).
    pub fn new() -> Self {
        let mut t = Self::empty();
        for (i, c) in t.quarter.iter_mut().enumerate() {
            *c = libm::cosf(2.0 * PI * i as f32 / TWIDDLE_GRID as f32);
        }
        t
    }

    /// An all-zero table, for `const` initialisation; fill with [`Twiddles::new`].
    pub const fn empty() -> Self {
        Self { quarter: [0.0; TWIDDLE_QUARTER + 1] }
    }

    /// (sin, cos) of 2π·m/k for integer m, where k divides 1024.
    pub fn sin_cos(&self, m: usize, k: usize) -> (f32, f32) {
        let i = (m % k) * (TWIDDLE_GRID / k);
        let (q, r) = (i / TWIDDLE_QUARTER, i % TWIDDLE_QUARTER);
        let (a, b) = (self.quarter[r], self.quarter[TWIDDLE_QUARTER - r]); // cos r, sin r
        match q {
            0 => (b, a),
            1 => (a, -b),
            2 => (-b, -a),
            _ => (-a, b),
        }
    }
}

impl Twiddles {
    /// (sin, cos) of 2π·u/1024 for real `u` (|u| < 2^22): the nearest grid point from the
    /// table, rotated by the remainder δ (|δ| ≤ π/1024) with sin δ ≈ δ − δ³/6,
    /// cos δ ≈ 1 − δ²/2 + δ⁴/24 (truncation below 10⁻¹⁴). Plain f32 arithmetic: libm's `sinf`
    /// and `cosf` reduce in f64, which the Cortex-M4F emulates in software (hundreds of
    /// instructions a call).
    pub fn sin_cos_grid(&self, u: f32) -> (f32, f32) {
        let m = libm::floorf(u + 0.5);
        let d = (u - m) * (2.0 * PI / TWIDDLE_GRID as f32);
        let d2 = d * d;
        let (sd, cd) = (d - d * d2 * (1.0 / 6.0), 1.0 - 0.5 * d2 + d2 * d2 * (1.0 / 24.0));
        let index = (m as i32).rem_euclid(TWIDDLE_GRID as i32) as usize;
        let (sg, cg) = self.sin_cos(index, TWIDDLE_GRID);
        (sg * cd + cg * sd, cg * cd - sg * sd)
    }
}

impl Default for Twiddles {
    fn default() -> Self {
        Self::new()
    }
}

/// Lag step of the coarse search, samples of the spatial rate (24 kHz at 48 kHz input: a
/// quarter period of the 6 kHz band edge).
pub const COARSE_STEP: usize = 1;
/// Most Newton steps of the sub-sample refinement.
const NEWTON_STEPS: usize = 3;

/// Magnitude below which a bin carries no phase (PHAT would divide by ~0): it contributes zero.
pub const PHAT_EPSILON: f32 = 1e-20;

/// 1/√x for x > 0 in four multiplies per Newton step (relative error below 5·10⁻⁶): the
/// Cortex-M4F's FPU has VSQRT but libm's `sqrtf` is a software routine of ~100 instructions,
/// and `forbid(unsafe_code)` rules out the intrinsic. Plain f32 arithmetic, so the host computes
/// the same bits.
///
/// ```
/// let r = aim_dsp::gcc_phat::rsqrt(2.0);
/// assert!((r - 0.70710678).abs() < 5e-6);
/// ```
#[inline(always)]
pub fn rsqrt(x: f32) -> f32 {
    let y = f32::from_bits(0x5F37_5A86 - (x.to_bits() >> 1));
    let y = y * (1.5 - 0.5 * x * y * y);
    y * (1.5 - 0.5 * x * y * y)
}

/// Writes the PHAT-weighted (unit-magnitude) band bins of `spectrum` into `out` as interleaved
/// `re, im` pairs: `out[2b], out[2b+1]` = X(first_bin + b) / |X(first_bin + b)|.
pub fn phat_band(spectrum: &[Complex32], first_bin: usize, out: &mut [f32]) {
    for (o, x) in out.chunks_exact_mut(2).zip(&spectrum[first_bin..]) {
        phat_unit(*x, o);
    }
}

/// Writes `x / |x|` into `o[0], o[1]` (`0, 0` for a bin below [`PHAT_EPSILON`]): one bin of
/// [`phat_band`].
#[inline(always)]
pub fn phat_unit(x: Complex32, o: &mut [f32]) {
    let p = x.re * x.re + x.im * x.im;
    if p > PHAT_EPSILON * PHAT_EPSILON {
        let inv = rsqrt(p);
        o[0] = x.re * inv;
        o[1] = x.im * inv;
    } else {
        o[0] = 0.0;
        o[1] = 0.0;
    }
}

/// `acc(b) += U_j(b) · conj(U_i(b))` for interleaved unit spectra `ui`, `uj`.
pub fn accumulate_cross(acc: &mut [Complex32], ui: &[f32], uj: &[f32]) {
    for ((a, i), j) in acc.iter_mut().zip(ui.chunks_exact(2)).zip(uj.chunks_exact(2)) {
        a.re += j[0] * i[0] + j[1] * i[1];
        a.im += j[1] * i[0] - j[0] * i[1];
    }
}

/// [`accumulate_cross`] for two pairs sharing microphone i, (i, j) into `acc_j` and (i, k) into
/// `acc_k`, in one pass (U_i loaded once); the same bits as two calls.
pub fn accumulate_cross_two(
    acc_j: &mut [Complex32],
    acc_k: &mut [Complex32],
    ui: &[f32],
    uj: &[f32],
    uk: &[f32],
) {
    let bins = acc_j.iter_mut().zip(acc_k.iter_mut()).zip(ui.chunks_exact(2));
    for (((a, b), i), (j, k)) in bins.zip(uj.chunks_exact(2).zip(uk.chunks_exact(2))) {
        a.re += j[0] * i[0] + j[1] * i[1];
        a.im += j[1] * i[0] - j[0] * i[1];
        b.re += k[0] * i[0] + k[1] * i[1];
        b.im += k[1] * i[0] - k[0] * i[1];
    }
}

/// Weights each averaged PHAT bin by its magnitude coherence |G(k)| / blocks (0–1): bins whose
/// phase wandered from block to block (noise) count less than bins with a steady phase.
/// The result keeps the scale of `g` (a fully coherent bin is unchanged).
pub fn weight_by_coherence(g: &mut [Complex32], blocks: u32) {
    let inv = 1.0 / blocks.max(1) as f32;
    for x in g {
        let p = x.re * x.re + x.im * x.im;
        let m = if p > 0.0 { p * rsqrt(p) * inv } else { 0.0 };
        x.re *= m;
        x.im *= m;
    }
}

/// A pair delay estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DelayEstimate {
    /// τ = t_j − t_i, samples (positive: the sound reaches j after i).
    pub delay_samples: f32,
    /// Height of the correlation peak over its maximum possible value (all bins in phase in
    /// every block), 0–1.
    pub coherence: f32,
    /// 1 − (largest other local maximum in the lag range) / (peak), 0–1.
    pub peak_margin: f32,
}

impl DelayEstimate {
    /// Weight of this pair in the direction fit: coherence × peak margin, 0–1.
    pub fn quality(&self) -> f32 {
        self.coherence * self.peak_margin
    }
}

/// R(τ) and its first two derivatives (per sample, per sample²) at a real lag τ; `fft_len`
/// divides 1024 (phases from `tw`).
pub fn correlation_derivatives(
    g: &[Complex32],
    first_bin: usize,
    fft_len: usize,
    tau: f32,
    tw: &Twiddles,
) -> [f32; 3] {
    let w = 2.0 * PI / fft_len as f32;
    let grid_per_bin = (TWIDDLE_GRID / fft_len) as f32;
    // Phase of the first bin reduced exactly for the integer part of k0·τ.
    let (s0, c0) = phase(first_bin, fft_len, tau, tw);
    let (ss, cs) = tw.sin_cos_grid(tau * grid_per_bin);
    let (mut s, mut c) = (s0, c0);
    let (mut r, mut r1, mut r2) = (0.0f32, 0.0f32, 0.0f32);
    let mut omega = w * first_bin as f32;
    for x in g {
        let re = x.re * c - x.im * s;
        let im = x.re * s + x.im * c;
        r += re;
        r1 -= omega * im;
        r2 -= omega * omega * re;
        let c2 = c * cs - s * ss;
        s = s * cs + c * ss;
        c = c2;
        omega += w;
    }
    [r, r1, r2]
}

/// R(+lag) and R(−lag) at an integer lag ≥ 0 in one pass: with c, s = cos, sin(2πk·lag/K),
/// R(±lag) = Σ Re(G)·c ∓ Σ Im(G)·s.
fn correlation_pm(
    g: &[Complex32],
    first_bin: usize,
    fft_len: usize,
    lag: usize,
    tw: &Twiddles,
) -> (f32, f32) {
    let (s0, c0) = tw.sin_cos(first_bin * lag, fft_len);
    let (ss, cs) = tw.sin_cos(lag, fft_len);
    let (mut s, mut c) = (s0, c0);
    let (mut p, mut q) = (0.0f32, 0.0f32);
    for x in g {
        p += x.re * c;
        q += x.im * s;
        let c2 = c * cs - s * ss;
        s = s * cs + c * ss;
        c = c2;
    }
    (p - q, p + q)
}

/// sin, cos of 2π·k·τ/K, with the integer part of k·τ reduced modulo K first (K divides 1024).
fn phase(k: usize, fft_len: usize, tau: f32, tw: &Twiddles) -> (f32, f32) {
    let whole = libm::floorf(tau);
    let frac = tau - whole;
    let int_phase = ((k as i32).wrapping_mul(whole as i32).rem_euclid(fft_len as i32)) as f32;
    // The scale to the 1024 grid is a power of two: exact.
    tw.sin_cos_grid((int_phase + k as f32 * frac) * (TWIDDLE_GRID / fft_len) as f32)
}

/// Finds the delay of one pair from its averaged cross spectrum.
///
/// `g`: band bins starting at `first_bin` of a `fft_len`-point transform, summed over
/// `blocks` blocks of unit-magnitude cross spectra. `max_lag`: search |τ| ≤ `max_lag` samples
/// (at most [`crate::MAX_LAG`]). `tw`: the phasor table ([`Twiddles::new`]).
///
/// ```
/// use microfft::Complex32;
/// use aim_dsp::gcc_phat::{estimate_delay, Twiddles};
/// // A pure delay of 2.3 samples: G(k) = e^{-j2πk·2.3/K} over bins 5..130 of K = 1024.
/// let g: Vec<Complex32> = (5..130)
///     .map(|k| {
///         let a = -2.0 * core::f32::consts::PI * k as f32 * 2.3 / 1024.0;
///         Complex32::new(a.cos(), a.sin())
///     })
///     .collect();
/// let d = estimate_delay(&g, 5, 1024, 8, 1, &Twiddles::new());
/// assert!((d.delay_samples - 2.3).abs() < 1e-3);
/// assert!(d.coherence > 0.99);
/// ```
pub fn estimate_delay(
    g: &[Complex32],
    first_bin: usize,
    fft_len: usize,
    max_lag: usize,
    blocks: u32,
    tw: &Twiddles,
) -> DelayEstimate {
    // Coarse grid every COARSE_STEP samples over ±max_lag (rounded up to the grid): the
    // PHAT-band correlation has no detail finer than a quarter period of the top band edge
    // (6 kHz at the 24 kHz spatial rate: 1 sample), and Newton refines below.
    let half = max_lag.min(crate::MAX_LAG).div_ceil(COARSE_STEP);
    let n = 2 * half + 1;
    let mut r = [0.0f32; 2 * crate::MAX_LAG / COARSE_STEP + 3];
    for m in 0..=half {
        let (plus, minus) = correlation_pm(g, first_bin, fft_len, m * COARSE_STEP, tw);
        r[half + m] = plus;
        r[half - m] = minus;
    }
    let mut best = 0usize;
    for i in 1..n {
        if r[i] > r[best] {
            best = i;
        }
    }
    let peak = r[best];
    if peak.is_nan() || peak <= 0.0 || g.is_empty() {
        return DelayEstimate::default();
    }
    // Largest local maximum other than the peak; the range ends count when they rise outwards.
    let mut second = 0.0f32;
    for i in 0..n {
        if i == best {
            continue;
        }
        let left_ok = i == 0 || r[i] >= r[i - 1];
        let right_ok = i + 1 == n || r[i] >= r[i + 1];
        if left_ok && right_ok {
            second = second.max(r[i]);
        }
    }
    let step = COARSE_STEP as f32;
    let max_lag = (half * COARSE_STEP) as i32;
    // Parabola through the three lags around the peak, then Newton on R'(τ) = 0.
    let mut tau = (best as f32 - half as f32) * step;
    if best > 0 && best + 1 < n {
        let (a, b, c) = (r[best - 1], r[best], r[best + 1]);
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            tau += step * (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    let centre = tau;
    let mut height = peak;
    for _ in 0..NEWTON_STEPS {
        let [v, d1, d2] = correlation_derivatives(g, first_bin, fft_len, tau, tw);
        height = v;
        if d2.is_nan() || d2 >= 0.0 {
            break;
        }
        let delta = (-d1 / d2).clamp(-0.5, 0.5);
        // max/min, not `clamp`: run-time bounds would link a panic message with float
        // formatting (~20 KB of flash).
        tau = (tau + delta).max(centre - step).min(centre + step);
        if libm::fabsf(delta) < 1e-4 {
            break;
        }
    }
    let tau = tau.max(-(max_lag as f32)).min(max_lag as f32);
    let full = (g.len() as f32) * blocks.max(1) as f32;
    DelayEstimate {
        delay_samples: tau,
        coherence: (height.max(peak) / full).clamp(0.0, 1.0),
        peak_margin: (1.0 - second / peak).clamp(0.0, 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI as PI64;

    /// Naive DFT bin k of a real sequence, f64: the oracle for microfft and the PHAT band.
    fn dft(x: &[f32], k: usize) -> (f64, f64) {
        let n = x.len() as f64;
        x.iter().enumerate().fold((0.0, 0.0), |(re, im), (t, &v)| {
            let a = -2.0 * PI64 * k as f64 * t as f64 / n;
            (re + v as f64 * a.cos(), im + v as f64 * a.sin())
        })
    }

    #[test]
    fn phat_band_matches_naive_dft_phases() {
        let mut state = 12345u32;
        let x: Vec<f32> = (0..1024)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 8) as f32 / (1 << 24) as f32 - 0.5
            })
            .collect();
        let mut buf: [f32; 1024] = x.clone().try_into().unwrap();
        let mut unit = [0.0f32; 2 * 128];
        phat_band(microfft::real::rfft_1024(&mut buf), 5, &mut unit);
        for b in 0..128 {
            let (re, im) = dft(&x, 5 + b);
            let m = (re * re + im * im).sqrt();
            assert!((unit[2 * b] as f64 - re / m).abs() < 1e-4, "bin {}", 5 + b);
            assert!((unit[2 * b + 1] as f64 - im / m).abs() < 1e-4, "bin {}", 5 + b);
        }
    }

    #[test]
    fn twiddles_are_sines_and_cosines_of_the_grid() {
        let tw = Twiddles::new();
        for k in [512usize, 1024] {
            for m in [0usize, 1, 7, 127, 128, 255, 256, 300, 511, 512, 777, 1023, 5000] {
                let (s, c) = tw.sin_cos(m, k);
                let a = 2.0 * PI64 * m as f64 / k as f64;
                assert!(
                    (s as f64 - a.sin()).abs() < 1e-6 && (c as f64 - a.cos()).abs() < 1e-6,
                    "{m}/{k}"
                );
            }
        }
    }

    #[test]
    fn two_pairs_at_once_give_the_bits_of_two_calls() {
        let u = |seed: f32| -> Vec<f32> { (0..64).map(|b| libm::sinf(seed * b as f32)).collect() };
        let (ui, uj, uk) = (u(0.3), u(1.7), u(2.9));
        let start: Vec<Complex32> = (0..32).map(|b| Complex32::new(b as f32, -0.5)).collect();
        let (mut a1, mut b1) = (start.clone(), start.clone());
        accumulate_cross(&mut a1, &ui, &uj);
        accumulate_cross(&mut b1, &ui, &uk);
        let (mut a2, mut b2) = (start.clone(), start);
        accumulate_cross_two(&mut a2, &mut b2, &ui, &uj, &uk);
        let bits = |v: &[Complex32]| -> Vec<(u32, u32)> {
            v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
        };
        assert_eq!(bits(&a1), bits(&a2));
        assert_eq!(bits(&b1), bits(&b2));
    }

    #[test]
    fn grid_sines_and_cosines_match_f64() {
        let tw = Twiddles::new();
        let mut worst = 0.0f64;
        for i in -20_000..20_000 {
            let u = i as f32 * 0.0731;
            let (s, c) = tw.sin_cos_grid(u);
            let (es, ec) = (2.0 * PI64 * u as f64 / 1024.0).sin_cos();
            worst = worst.max((s as f64 - es).abs()).max((c as f64 - ec).abs());
        }
        assert!(worst < 3e-7, "worst error {worst}");
    }

    #[test]
    fn correlation_and_derivatives_match_direct_evaluation() {
        let g: Vec<Complex32> = (0..120)
            .map(|b| Complex32::new(libm::cosf(0.37 * b as f32), libm::sinf(1.3 * b as f32) * 0.5))
            .collect();
        let tw = Twiddles::new();
        for &tau in &[-11.3f32, -2.5, 0.0, 0.71, 6.04, 13.9] {
            let [r, r1, r2] = correlation_derivatives(&g, 7, 1024, tau, &tw);
            let (mut dr, mut dr1, mut dr2) = (0.0f64, 0.0f64, 0.0f64);
            for (b, x) in g.iter().enumerate() {
                let w = 2.0 * PI64 * (7 + b) as f64 / 1024.0;
                let (s, c) = (w * tau as f64).sin_cos();
                let re = x.re as f64 * c - x.im as f64 * s;
                let im = x.re as f64 * s + x.im as f64 * c;
                dr += re;
                dr1 -= w * im;
                dr2 -= w * w * re;
            }
            assert!((r as f64 - dr).abs() < 1e-3, "R({tau}) {r} vs {dr}");
            assert!((r1 as f64 - dr1).abs() < 1e-3 * (1.0 + dr1.abs()), "R'({tau})");
            assert!((r2 as f64 - dr2).abs() < 1e-3 * (1.0 + dr2.abs()), "R''({tau})");
        }
    }

    fn pure_delay(delay: f32, first: usize, bins: usize) -> Vec<Complex32> {
        (first..first + bins)
            .map(|k| {
                let a = -2.0 * core::f32::consts::PI * k as f32 * delay / 1024.0;
                Complex32::new(libm::cosf(a), libm::sinf(a))
            })
            .collect()
    }

    #[test]
    fn pure_delays_are_recovered_across_the_lag_range() {
        for i in 0..=60 {
            let d = -14.5 + 29.0 * i as f32 / 60.0;
            let e = estimate_delay(&pure_delay(d, 5, 124), 5, 1024, 16, 1, &Twiddles::new());
            assert!((e.delay_samples - d).abs() < 2e-3, "delay {d}: got {}", e.delay_samples);
            assert!(e.coherence > 0.999 && e.peak_margin > 0.3, "{e:?}");
        }
    }

    #[test]
    fn a_second_path_lowers_the_peak_margin() {
        let direct = pure_delay(2.0, 5, 124);
        let echo = pure_delay(-9.0, 5, 124);
        let mixed: Vec<Complex32> = direct.iter().zip(&echo).map(|(a, b)| a + b * 0.8).collect();
        let tw = Twiddles::new();
        let clean = estimate_delay(&direct, 5, 1024, 16, 1, &tw);
        let two = estimate_delay(&mixed, 5, 1024, 16, 1, &tw);
        // The echo's side lobes pull the peak a little (physics, not error): still the direct path.
        assert!((two.delay_samples - 2.0).abs() < 0.3, "{two:?}");
        assert!(
            two.peak_margin < 0.3 && two.peak_margin < clean.peak_margin,
            "{two:?} vs {clean:?}"
        );
        // No coherent peak at all: nothing.
        assert_eq!(
            estimate_delay(&[Complex32::new(0.0, 0.0); 50], 5, 1024, 16, 1, &tw).quality(),
            0.0
        );
    }
}
