//! Radix-4 FFTs for the two transforms the 48 kHz pipeline runs most: the spatial path's
//! 512-point real FFT (one per microphone per block) and the beacon's 512-point complex
//! correlation (two per hop).
//!
//! microfft (used for every other size) is radix-2: nine passes over the data for 512 points,
//! each complex butterfly reloading its twiddle from a quarter-wave table through index
//! arithmetic. Here a radix-4 butterfly does two radix-2 passes' work with three complex
//! multiplications instead of four and half the loads and stores, and twiddles come from one
//! full table of W₅₁₂ᵏ = e^{−2πik/512} (k < 384, 3 KiB of flash) and, for the radix-4 passes,
//! each butterfly's three twiddles side by side (2 KiB).
//!
//! - [`dif_512`] / [`dit_512`]: forward transforms, natural order in → scrambled order out,
//!   and scrambled in → natural out (radix 2 then radix 4 ⁴, and the mirror). A fast
//!   convolution needs no reordering: DIF, multiply by a spectrum also computed by DIF, DIT.
//! - [`rfft_512_bins`]: chosen bins of a 512-point real FFT (the spatial path's band), from a
//!   256-point radix-4 DIF of the packed pairs and the real-to-complex recombination of each
//!   bin read from its two scrambled positions. The bins differ from microfft's `rfft_512` by
//!   rounding only (tested against rustfft and microfft).
//!
//! The transforms are unnormalised: `X[k] = Σₙ x[n] e^{−2πikn/N}`.
//!
//! "Scrambled" for 512 points: position `256·h + r(d)` holds bin `2d + h`, where `r` reverses
//! the four base-4 digits of `d < 256` ([`scrambled_position`]).

use microfft::Complex32;

/// Length of the complex transforms [`dif_512`] and [`dit_512`], and of the real input of
/// [`rfft_512_bins`].
pub const N: usize = 512;

/// Twiddles W₅₁₂ᵏ = e^{−2πik/512} for k < 384 (the largest index used: 3·2·63 = 378 in the
/// 256-point stage; the radix-2 stage and the recombination use k < 256).
static TWIDDLES: [Complex32; 384] = twiddle_table();

const fn twiddle_table() -> [Complex32; 384] {
    let mut table = [Complex32::new(0.0, 0.0); 384];
    let mut k = 0;
    while k < 384 {
        // Reduce to |x| ≤ π: e^{−iθ} with θ = 2πk/512 = π·k/256; for k > 256 use θ − 2π.
        let k_signed = if k > 256 { k as i64 - 512 } else { k as i64 };
        let theta = core::f64::consts::PI * k_signed as f64 / 256.0;
        let (c, s) = crate::trig::cos_sin(theta);
        table[k] = Complex32::new(c as f32, -s as f32);
        k += 1;
    }
    table
}

/// The three twiddles of a radix-4 pass over groups of `4·Q` points, side by side:
/// `[W^n, W^2n, W^3n]` with W = e^{−2πi/(4Q)}, n < Q (one load stream in the butterfly loop
/// instead of three strided ones).
const fn pass_twiddles<const Q: usize>() -> [[Complex32; 3]; Q] {
    let stride = N / (4 * Q);
    let mut t = [[Complex32::new(0.0, 0.0); 3]; Q];
    let mut n = 0;
    while n < Q {
        t[n] = [TWIDDLES[n * stride], TWIDDLES[2 * n * stride], TWIDDLES[3 * n * stride]];
        n += 1;
    }
    t
}

static PASS_256: [[Complex32; 3]; 64] = pass_twiddles::<64>();
static PASS_64: [[Complex32; 3]; 16] = pass_twiddles::<16>();
static PASS_16: [[Complex32; 3]; 4] = pass_twiddles::<4>();

#[inline(always)]
fn mul(a: Complex32, w: Complex32) -> Complex32 {
    Complex32::new(a.re * w.re - a.im * w.im, a.re * w.im + a.im * w.re)
}

/// `a − j·b`.
#[inline(always)]
fn sub_j(a: Complex32, b: Complex32) -> Complex32 {
    Complex32::new(a.re + b.im, a.im - b.re)
}

/// `a + j·b`.
#[inline(always)]
fn add_j(a: Complex32, b: Complex32) -> Complex32 {
    Complex32::new(a.re - b.im, a.im + b.re)
}

/// Runs `butterfly(a, b, c, d, [w¹, w², w³])` on every quadruple `n, n + Q, n + 2Q, n + 3Q` of
/// every group of `4Q` points, `Q = tw.len()`, with that `n`'s twiddles from
/// [`pass_twiddles`].
#[inline(always)]
fn radix4_pass(
    x: &mut [Complex32],
    tw: &[[Complex32; 3]],
    butterfly: impl Fn(&mut Complex32, &mut Complex32, &mut Complex32, &mut Complex32, &[Complex32; 3]),
) {
    let q = tw.len();
    for group in x.chunks_exact_mut(4 * q) {
        let (a, rest) = group.split_at_mut(q);
        let (b, rest) = rest.split_at_mut(q);
        let (c, d) = rest.split_at_mut(q);
        for (((a, b), (c, d)), w) in
            a.iter_mut().zip(b.iter_mut()).zip(c.iter_mut().zip(d.iter_mut())).zip(tw)
        {
            butterfly(a, b, c, d, w);
        }
    }
}

/// One radix-4 decimation-in-frequency pass (groups of 16 points or more).
#[inline(always)]
fn dif4_pass(x: &mut [Complex32], tw: &[[Complex32; 3]]) {
    radix4_pass(x, tw, |a, b, c, d, [w1, w2, w3]| {
        let (t0, t1) = (*a + *c, *a - *c);
        let (t2, t3) = (*b + *d, *b - *d);
        *a = t0 + t2;
        *b = mul(sub_j(t1, t3), *w1);
        *c = mul(t0 - t2, *w2);
        *d = mul(add_j(t1, t3), *w3);
    });
}

/// The last radix-4 DIF pass (groups of 4, every twiddle 1).
#[inline(always)]
fn dif4_last(x: &mut [Complex32]) {
    for g in x.chunks_exact_mut(4) {
        let (t0, t1) = (g[0] + g[2], g[0] - g[2]);
        let (t2, t3) = (g[1] + g[3], g[1] - g[3]);
        g[0] = t0 + t2;
        g[1] = sub_j(t1, t3);
        g[2] = t0 - t2;
        g[3] = add_j(t1, t3);
    }
}

/// One radix-4 decimation-in-time pass (groups of 16 points or more).
#[inline(always)]
fn dit4_pass(x: &mut [Complex32], tw: &[[Complex32; 3]]) {
    radix4_pass(x, tw, |a, b, c, d, [w1, w2, w3]| {
        let (bb, cc, dd) = (mul(*b, *w1), mul(*c, *w2), mul(*d, *w3));
        let (t0, t1) = (*a + cc, *a - cc);
        let (t2, t3) = (bb + dd, bb - dd);
        *a = t0 + t2;
        *b = sub_j(t1, t3);
        *c = t0 - t2;
        *d = add_j(t1, t3);
    });
}

/// The first radix-4 DIT pass (groups of 4, every twiddle 1): the same butterfly as
/// [`dif4_last`].
#[inline(always)]
fn dit4_first(x: &mut [Complex32]) {
    dif4_last(x);
}

/// 256-point radix-4 DIF: natural order in, base-4 digit-reversed order out. Out of line:
/// one copy serves the real FFT and both halves of [`dif_512`] (inlined, each copy is ≈ 3.5 KiB
/// of flash).
#[inline(never)]
fn dif_256(x: &mut [Complex32]) {
    dif4_pass(x, &PASS_256);
    dif4_pass(x, &PASS_64);
    dif4_pass(x, &PASS_16);
    dif4_last(x);
}

/// 256-point radix-4 DIT: base-4 digit-reversed order in, natural order out (out of line).
#[inline(never)]
fn dit_256(x: &mut [Complex32]) {
    dit4_first(x);
    dit4_pass(x, &PASS_16);
    dit4_pass(x, &PASS_64);
    dit4_pass(x, &PASS_256);
}

/// The four base-4 digits of `d` (< 256) reversed.
pub const fn digit_reverse_256(d: usize) -> usize {
    ((d & 3) << 6) | ((d & 12) << 2) | ((d & 48) >> 2) | ((d & 192) >> 6)
}

/// Where [`dif_512`] leaves bin `k` (< 512), and where [`dit_512`] expects input sample `k`.
pub const fn scrambled_position(k: usize) -> usize {
    (k & 1) * 256 + digit_reverse_256(k >> 1)
}

/// `digit_reverse_256` as a table (256 B of flash; one load instead of eight operations).
static DIGIT_REVERSE_256: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut d = 0;
    while d < 256 {
        t[d] = digit_reverse_256(d) as u8;
        d += 1;
    }
    t
};

/// Forward 512-point DFT, natural order in, scrambled order out ([`scrambled_position`]).
#[inline(never)]
pub fn dif_512(x: &mut [Complex32; N]) {
    let (lo, hi) = x.split_at_mut(N / 2);
    for ((a, b), w) in lo.iter_mut().zip(hi.iter_mut()).zip(TWIDDLES.iter()) {
        let (s, t) = (*a + *b, *a - *b);
        *a = s;
        *b = mul(t, *w);
    }
    dif_256(lo);
    dif_256(hi);
}

/// Forward 512-point DFT, scrambled order in ([`scrambled_position`]), natural order out.
#[inline(never)]
pub fn dit_512(x: &mut [Complex32; N]) {
    let (lo, hi) = x.split_at_mut(N / 2);
    dit_256(lo);
    dit_256(hi);
    for ((a, b), w) in lo.iter_mut().zip(hi.iter_mut()).zip(TWIDDLES.iter()) {
        let t = mul(*b, *w);
        (*a, *b) = (*a + t, *a - t);
    }
}

/// Bins `first .. first + count` of the 512-point real FFT of `x` (1 ≤ `first`,
/// `first + count` ≤ 257: bin 256 is the Nyquist bin), passed to `bin` in order; `x` is left
/// holding the scrambled 256-point transform of its pairs.
///
/// The spatial path needs only its band (≈ 124 of 256 bins at 24 kHz): each bin is recombined
/// from the two scrambled positions it needs, with no reordering pass and no work for bins
/// outside the band.
#[inline(always)]
pub fn rfft_512_bins(x: &mut [f32; N], first: usize, count: usize, mut bin: impl FnMut(Complex32)) {
    debug_assert!(first >= 1 && first + count <= N / 2 + 1);
    let z: &mut [Complex32; N / 2] = bytemuck::cast_mut(x);
    dif_256(z);
    let z = &*z;
    let end = (first + count).min(N / 2 + 1);
    // X[k] = E + W₅₁₂ᵏ·O with E = (z[k] + z̄[256−k]) / 2 and O = −j (z[k] − z̄[256−k]) / 2
    // (z = FFT₂₅₆ of the packed pairs). At k = 256 the same formula gives the Nyquist bin
    // (z[0] with itself, W = −1).
    for (k, w) in TWIDDLES.iter().enumerate().take(end).skip(first) {
        let a = z[usize::from(DIGIT_REVERSE_256[k & (N / 2 - 1)])];
        let b = z[usize::from(DIGIT_REVERSE_256[(N / 2 - k) & (N / 2 - 1)])].conj();
        let e = (a + b) * 0.5;
        let o = Complex32::new(a.im - b.im, b.re - a.re) * 0.5;
        bin(e + mul(o, *w));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rustfft::num_complex::Complex64;

    fn reference(x: &[Complex64]) -> Vec<Complex64> {
        let mut y = x.to_vec();
        rustfft::FftPlanner::<f64>::new().plan_fft_forward(y.len()).process(&mut y);
        y
    }

    fn noise(n: usize, seed: u64) -> Vec<Complex64> {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f64 / (1u64 << 24) as f64) * 2.0 - 1.0
        };
        (0..n).map(|_| Complex64::new(next(), next())).collect()
    }

    /// `x` rounded to f32.
    fn to_f32(x: &[Complex64]) -> [Complex32; N] {
        let mut b = [Complex32::new(0.0, 0.0); N];
        for (b, v) in b.iter_mut().zip(x) {
            *b = Complex32::new(v.re as f32, v.im as f32);
        }
        b
    }

    /// Largest |error| relative to the rms of the reference spectrum.
    fn rel_err(got: &[Complex32], want: &[Complex64]) -> f64 {
        let rms = (want.iter().map(|w| w.norm_sqr()).sum::<f64>() / want.len() as f64).sqrt();
        got.iter()
            .zip(want)
            .map(|(g, w)| (Complex64::new(g.re.into(), g.im.into()) - w).norm())
            .fold(0.0, f64::max)
            / rms
    }

    #[test]
    fn twiddles_are_the_roots_of_unity() {
        for (k, w) in TWIDDLES.iter().enumerate() {
            let theta = -2.0 * std::f64::consts::PI * k as f64 / 512.0;
            // Exact f32 roundings of cos and sin, but for values within 10⁻¹⁵ of zero.
            for (got, want) in [(w.re, theta.cos()), (w.im, theta.sin())] {
                if want.abs() < 1e-15 {
                    assert!(f64::from(got).abs() < 1e-15, "k = {k}: {got} for {want}");
                } else {
                    assert_eq!(got, want as f32, "k = {k}");
                }
            }
        }
    }

    #[test]
    fn scrambled_positions_are_a_permutation() {
        let mut seen = [false; N];
        for k in 0..N {
            let p = scrambled_position(k);
            assert!(!seen[p], "position {p} twice");
            seen[p] = true;
        }
        assert_eq!(digit_reverse_256(0b00_01_10_11), 0b11_10_01_00);
    }

    #[test]
    fn dif_512_matches_rustfft_in_scrambled_order() {
        for seed in 1..4 {
            let x = noise(N, seed);
            let want = reference(&x);
            let mut buf = to_f32(&x);
            dif_512(&mut buf);
            let natural: Vec<Complex32> = (0..N).map(|k| buf[scrambled_position(k)]).collect();
            let e = rel_err(&natural, &want);
            assert!(e < 2e-6, "seed {seed}: relative error {e}");
        }
    }

    #[test]
    fn dit_512_matches_rustfft_from_scrambled_order() {
        for seed in 4..7 {
            let x = noise(N, seed);
            let want = reference(&x);
            let mut buf = [Complex32::new(0.0, 0.0); N];
            for (k, v) in x.iter().enumerate() {
                buf[scrambled_position(k)] = Complex32::new(v.re as f32, v.im as f32);
            }
            dit_512(&mut buf);
            let e = rel_err(&buf, &want);
            assert!(e < 2e-6, "seed {seed}: relative error {e}");
        }
    }

    /// Bins `first .. first + count` of `rfft_512_bins` of the real samples `x`.
    fn bins(x: &[f32], first: usize, count: usize) -> Vec<Complex32> {
        let mut buf = [0.0f32; N];
        buf.copy_from_slice(x);
        let mut got = Vec::new();
        rfft_512_bins(&mut buf, first, count, |c| got.push(c));
        assert_eq!(got.len(), count);
        got
    }

    #[test]
    fn rfft_512_bins_match_rustfft_and_microfft() {
        for seed in 7..10 {
            let x: Vec<f64> = noise(N / 2, seed).iter().flat_map(|c| [c.re, c.im]).collect();
            let want = reference(&x.iter().map(|&v| Complex64::new(v, 0.0)).collect::<Vec<_>>());
            let x32: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            // Bins 1 … 256 (256: Nyquist, real).
            let got = bins(&x32, 1, N / 2);
            let e = rel_err(&got, &want[1..=N / 2]);
            assert!(e < 2e-6, "seed {seed}: relative error {e}");
            // microfft's rfft_512, which the spatial path used: the same bins but for rounding
            // (its bin 0 packs DC and Nyquist).
            let mut micro = [0.0f32; N];
            micro.copy_from_slice(&x32);
            let m = microfft::real::rfft_512(&mut micro);
            let mut expect = want[..N / 2].to_vec();
            expect[0] = Complex64::new(want[0].re, want[N / 2].re);
            let e = rel_err(m, &expect);
            assert!(e < 2e-6, "microfft, seed {seed}: relative error {e}");
            assert!((got[N / 2 - 1].re - m[0].im).abs() <= 1e-5 * m[0].im.abs().max(1.0));
        }
    }

    #[test]
    fn a_band_of_rfft_512_bins_is_the_same_bins_of_the_whole() {
        let x: Vec<f32> =
            noise(N / 2, 21).iter().flat_map(|c| [c.re as f32, c.im as f32]).collect();
        let whole = bins(&x, 1, N / 2);
        for (first, count) in [(5, 124), (100, 157), (128, 1), (255, 2)] {
            assert_eq!(bins(&x, first, count), whole[first - 1..first - 1 + count]);
        }
    }

    #[test]
    fn dif_then_dit_is_a_circular_correlation() {
        // conj(DIT(conj(DIF y) · DIF r)) / N = Σₙ y[n + m] r̄[n]: the beacon's use.
        let (y, r) = (noise(N, 11), noise(N, 12));
        let (mut yb, mut rb) = (to_f32(&y), to_f32(&r));
        dif_512(&mut yb);
        dif_512(&mut rb);
        for (a, b) in yb.iter_mut().zip(&rb) {
            *a = a.conj() * b;
        }
        dit_512(&mut yb);
        let got: Vec<Complex32> = yb.iter().map(|c| c.conj() / N as f32).collect();
        let want: Vec<Complex64> = (0..N)
            .map(|m| (0..N).map(|n| y[(n + m) % N] * r[n].conj()).sum::<Complex64>())
            .collect();
        let e = rel_err(&got, &want);
        assert!(e < 4e-6, "relative error {e}");
    }
}
