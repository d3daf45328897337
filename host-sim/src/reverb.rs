//! Late reverberation: the statistical tail of a shoebox room's impulse response beyond the
//! image sources the renderer simulates exactly (a hybrid image-source / stochastic model).
//!
//! **Energy.** An image source at distance r = c t has pressure gain `g / r` (g: the product of
//! the walls' β along the path, as the renderer applies it), and images fill space at one per
//! room volume V. Over a shell the expected squared impulse response is therefore
//! `E(t) = 4π c ⟨g²⟩(t) / V` per second, with `⟨g²⟩` averaged over directions u: along u a
//! path of length r crosses the walls normal to axis i `r |u_i| / L_i` times, alternating
//! between the two, so `ln g² = r Σ_i |u_i| / L_i · ½ ln((1 − α_lo,i)(1 − α_hi,i))`, and it has
//! order `r Σ_i |u_i| / L_i`. The tail carries the part of E whose order exceeds the order
//! rendered exactly, so images and tail add up to the whole image model in expectation (with
//! uniform α and the directional mean replaced by its mean exponent this is Eyring's decay).
//! Air absorption multiplies each octave band by `10^(−a f_b² c t / 10)` (the quadratic law of
//! `Air::absorption_quadratic_coefficient`, the same the per-path smoother follows).
//!
//! **Signal.** Per array, white Gaussian noise is given the diffuse field's inter-microphone
//! coherence `sin(k d) / (k d)` bin by bin (a Cholesky factor of the coherence matrix), split
//! into octave bands by amplitude-complementary cos² crossovers, each band weighted by
//! `sqrt(E_band(t) / fs)` and summed: one tail impulse response per microphone, indexed by the
//! time since emission. The diffuse tail does not depend on where the source is, so a moving
//! source's tail is its emitted signal convolved with these responses (the reflections'
//! Doppler is not modelled in the tail); the convolution runs per output block by FFT
//! (overlap-save), each block on the source's sample grid at the block's first sample (a
//! clock's drift shifts the tail by under 5 samples per second of output, immaterial for a
//! random tail). The microphones of different arrays get independent tails.
use std::sync::Arc;

use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::SeedableRng as _;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use crate::filter::Gaussian;
use crate::propagation::{OutsideWindow, SourceView};
use crate::room::Room;

/// Octave band centres of the tail's decay, Hz.
pub const BAND_CENTRES_HZ: [f64; 8] =
    [125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0, 16000.0];

/// Directions the energy average runs over (a Fibonacci sphere).
const DIRECTIONS: usize = 2048;

/// Envelope grid step, s (the energy is interpolated linearly in between).
const GRID_S: f64 = 0.001;

/// Level below the tail's peak where it is cut, dB (energy).
const CUT_DB: f64 = 65.0;

/// Longest tail simulated, s.
pub const MAX_TAIL_S: f64 = 4.0;

/// The expected energy decay of a room's image model.
#[derive(Clone, Debug)]
pub struct Decay {
    /// Per direction: (Σ |u_i| / L_i in 1/m, the energy exponent per metre).
    dirs: Vec<(f64, f64)>,
    volume_m3: f64,
    c_mps: f64,
}

impl Decay {
    /// The decay of `room` at speed of sound `c_mps`.
    pub fn new(room: &Room, c_mps: f64) -> Self {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let l = room.size_m;
        let a = room.absorption;
        let per_axis: Vec<f64> = (0..3)
            .map(|i| 0.5 * ((1.0 - a[2 * i]) * (1.0 - a[2 * i + 1])).max(1e-300).ln())
            .collect();
        let dirs = (0..DIRECTIONS)
            .map(|k| {
                let z = 1.0 - (2.0 * k as f64 + 1.0) / DIRECTIONS as f64;
                let rho = (1.0 - z * z).sqrt();
                let (s, c) = (golden * k as f64).sin_cos();
                let u = [rho * c, rho * s, z];
                let crossings: f64 = (0..3).map(|i| u[i].abs() / l[i]).sum();
                let exponent: f64 = (0..3).map(|i| u[i].abs() / l[i] * per_axis[i]).sum();
                (crossings, exponent)
            })
            .collect();
        Self { dirs, volume_m3: l[0] * l[1] * l[2], c_mps }
    }

    /// Expected squared impulse response per second at `t_s` after emission (pressure gain
    /// re 1 m, squared, per s) of the images of order above `order` (None: of every order),
    /// without air absorption.
    pub fn energy_rate(&self, t_s: f64, order: Option<u32>) -> f64 {
        let r = self.c_mps * t_s;
        let k = order.map_or(-1.0, f64::from);
        let sum: f64 =
            self.dirs.iter().filter(|d| r * d.0 > k).map(|d| (r * d.1).exp()).sum::<f64>();
        4.0 * std::f64::consts::PI * self.c_mps * sum / (self.dirs.len() as f64 * self.volume_m3)
    }

    /// The time the whole image model's energy takes to fall 60 dB, s, fitted on its decay
    /// from −5 to −35 dB as T30 is measured (Schroeder integral of [`Self::energy_rate`]).
    pub fn t30_s(&self) -> f64 {
        // Out to where the rate has fallen 60 dB (the EDC's −35 dB is well inside).
        let start = self.energy_rate(0.0, None);
        let mut e = Vec::new();
        let mut i = 0;
        while i < 200_000 {
            let x = self.energy_rate((i as f64 + 0.5) * GRID_S, None);
            e.push(x);
            if x < start * 1e-6 {
                break;
            }
            i += 1;
        }
        t30_from_energy(&e, 1.0 / GRID_S).unwrap_or(f64::NAN)
    }
}

/// Absorption coefficient that gives reverberation time `rt60_s` in `room` (its walls all
/// alike) by Eyring's formula `T = 0.161 V / (−S ln(1 − α))` (0.161 s/m at 343 m/s, scaled to
/// `c_mps`).
pub fn eyring_absorption(size_m: [f64; 3], rt60_s: f64, c_mps: f64) -> f64 {
    let [x, y, z] = size_m;
    let v = x * y * z;
    let s = 2.0 * (x * y + x * z + y * z);
    let k = 24.0 * std::f64::consts::LN_10 / c_mps;
    1.0 - (-k * v / (s * rt60_s)).exp()
}

/// How long after emission a room's late tail reaches at 343 m/s without air absorption (the
/// longest it gets), s. For memory estimates; the renderer uses its own tail's length.
pub fn tail_reach_estimate_s(room: &Room) -> f64 {
    envelopes(room, 343.0, 0.0, 1000.0).end as f64 / 1000.0
}

/// Absorption coefficient (all walls alike) whose image model decays with T30 = `rt60_s` in a
/// room of `size_m` (without air absorption). With all walls alike the energy is a function of
/// `t · (−ln(1 − α))` alone, so one evaluation of T30 at Eyring's α scales to the answer. The
/// image model decays slower than Eyring's formula (by 10–35 % in the rooms tested: paths along
/// the long axes meet fewer walls), so this α is larger than Eyring's.
pub fn absorption_for_t30(size_m: [f64; 3], rt60_s: f64, c_mps: f64) -> f64 {
    let eyring = eyring_absorption(size_m, rt60_s, c_mps);
    let room = Room { size_m, absorption: [eyring; 6], reflection_order: 0, late_tail: true };
    let model = Decay::new(&room, c_mps).t30_s();
    let rate = -(1.0 - eyring).ln() * model / rt60_s;
    (1.0 - (-rate).exp()).clamp(0.0, 1.0)
}

/// Eyring's reverberation time of `room` from its mean absorption (area-weighted), s.
pub fn eyring_rt60_s(room: &Room, c_mps: f64) -> f64 {
    let [x, y, z] = room.size_m;
    let areas = [y * z, y * z, x * z, x * z, x * y, x * y];
    let s: f64 = areas.iter().sum();
    let mean = areas.iter().zip(room.absorption).map(|(a, al)| a * al).sum::<f64>() / s;
    24.0 * std::f64::consts::LN_10 / c_mps * x * y * z / (-s * (1.0 - mean).ln())
}

/// Sabine's reverberation time of `room`, `T = 0.161 V / Σ S_i α_i` (scaled to `c_mps`), s.
pub fn sabine_rt60_s(room: &Room, c_mps: f64) -> f64 {
    let [x, y, z] = room.size_m;
    let areas = [y * z, y * z, x * z, x * z, x * y, x * y];
    let a: f64 = areas.iter().zip(room.absorption).map(|(a, al)| a * al).sum();
    24.0 * std::f64::consts::LN_10 / c_mps * x * y * z / a
}

/// T30 of an energy envelope `e` (squared response per sample at `rate_hz`), s: the Schroeder
/// backward integral, a straight line fitted (least squares) from −5 to −35 dB, extrapolated
/// to −60 dB. None if the decay never reaches −35 dB.
pub fn t30_from_energy(e: &[f64], rate_hz: f64) -> Option<f64> {
    let mut edc = vec![0.0; e.len()];
    let mut acc = 0.0;
    for i in (0..e.len()).rev() {
        acc += e[i];
        edc[i] = acc;
    }
    let total = edc.first().copied().filter(|&t| t > 0.0)?;
    let db: Vec<f64> = edc.iter().map(|&x| 10.0 * (x / total).max(1e-300).log10()).collect();
    let i0 = db.iter().position(|&d| d <= -5.0)?;
    let i1 = db.iter().position(|&d| d <= -35.0)?;
    let pts: Vec<(f64, f64)> = (i0..=i1).map(|i| (i as f64 / rate_hz, db[i])).collect();
    let n = pts.len() as f64;
    let (mx, my) =
        (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let slope = sxy / sxx;
    (slope < 0.0).then(|| -60.0 / slope)
}

/// Source and receiver pairs the rendered images' expected energy is averaged over.
const PAIRS: usize = 128;

/// The tail's energy rate (squared pressure gain re 1 m per s) on a grid of [`GRID_S`] from
/// emission, without air absorption: the whole image model's expected rate
/// ([`Decay::energy_rate`]) less the expected rate of the images rendered exactly (order ≤
/// `room.reflection_order`), the latter counted exactly over [`PAIRS`] source and receiver
/// positions drawn uniformly in the room (fixed draw) and smoothed over 9 ms; never negative
/// and never above the directional estimate of the images above that order (which is zero
/// before the first image of higher order can arrive, where the average is too coarse).
/// Counting the rendered images exactly matters where few orders are rendered: the directional
/// estimate of an image's order is biased high near the walls' crossings.
pub fn tail_energy_rate(room: &Room, c_mps: f64) -> Vec<f64> {
    let decay = Decay::new(room, c_mps);
    let n = (MAX_TAIL_S / GRID_S) as usize + 2;
    let mut early = vec![0.0; n];
    let mut rng = StdRng::seed_from_u64(0x5eed_7a11);
    let images = room.images();
    let draw =
        |rng: &mut StdRng| Vector3::from_fn(|i, _| rand::Rng::random::<f64>(rng) * room.size_m[i]);
    for _ in 0..PAIRS {
        let (s, m) = (draw(&mut rng), draw(&mut rng));
        for im in &images {
            let d = (im.apply(&s) - m).norm().max(0.05);
            let i = (d / c_mps / GRID_S).round() as usize;
            if i < n {
                early[i] += (im.reflection_gain / d).powi(2) / (PAIRS as f64 * GRID_S);
            }
        }
    }
    // Triangular smoothing over ±4 grid steps.
    let kernel: Vec<f64> = (-4i32..=4).map(|k| f64::from(5 - k.abs()) / 25.0).collect();
    (0..n)
        .map(|i| {
            let e: f64 = kernel
                .iter()
                .enumerate()
                .filter_map(|(j, w)| {
                    (i + j).checked_sub(4).and_then(|k| early.get(k)).map(|x| w * x)
                })
                .sum();
            let t = i as f64 * GRID_S;
            let upper = decay.energy_rate(t, Some(room.reflection_order));
            (decay.energy_rate(t, None) - e).min(upper).max(0.0)
        })
        .collect()
}

/// Per octave band, the tail's energy rate (per s) on a grid of [`GRID_S`] from time 0, and the
/// first and one-past-last sample of the tail at `fs`.
struct Envelopes {
    bands: Vec<Vec<f64>>,
    first: usize,
    end: usize,
}

fn envelopes(room: &Room, c_mps: f64, air_db_per_m_hz2: f64, fs: f64) -> Envelopes {
    let broad = tail_energy_rate(room, c_mps);
    let n = broad.len();
    let bands: Vec<Vec<f64>> = BAND_CENTRES_HZ
        .iter()
        .map(|f| {
            let per_s = air_db_per_m_hz2 * f * f * c_mps / 10.0;
            broad
                .iter()
                .enumerate()
                .map(|(i, e)| e * 10f64.powf(-per_s * i as f64 * GRID_S))
                .collect()
        })
        .collect();
    let peak = broad.iter().copied().fold(0.0, f64::max);
    let floor = peak * 10f64.powf(-CUT_DB / 10.0);
    let first_g = broad.iter().position(|&e| e > floor).unwrap_or(n);
    let last_g = broad.iter().rposition(|&e| e > floor).map_or(first_g, |i| i + 1);
    let to_samples = |g: usize| (g as f64 * GRID_S * fs).round() as usize;
    Envelopes { bands, first: to_samples(first_g), end: to_samples(last_g.min(n - 1)) }
}

/// Amplitude-complementary octave weights of frequency `f_hz` (`Σ_b w_b = 1`, cos² and sin²
/// crossovers in log frequency): the bands' signals add back to the whole.
fn band_weights(f_hz: f64) -> [f64; 8] {
    let mut w = [0.0; 8];
    let x = (f_hz.max(1e-9) / BAND_CENTRES_HZ[0]).log2();
    if x <= 0.0 {
        w[0] = 1.0;
    } else if x >= 7.0 {
        w[7] = 1.0;
    } else {
        let b = x.floor() as usize;
        let frac = x - b as f64;
        w[b] = (std::f64::consts::FRAC_PI_2 * frac).cos().powi(2);
        w[b + 1] = (std::f64::consts::FRAC_PI_2 * frac).sin().powi(2);
    }
    w
}

/// Cholesky factor (lower) of the symmetric positive-definite `a` (n × n, row-major).
fn cholesky(a: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum();
            if i == j {
                l[i * n + i] = (a[i * n + i] - s).max(1e-12).sqrt();
            } else {
                l[i * n + j] = (a[i * n + j] - s) / l[j * n + j];
            }
        }
    }
    l
}

/// Tail impulse responses of one array's microphones at `positions` (m), indexed from time 0
/// (emission): `(first, responses)` where response m's sample k is the tail at
/// `(first + k) / fs`.
pub fn tail_responses(
    room: &Room,
    c_mps: f64,
    air_db_per_m_hz2: f64,
    fs: f64,
    positions: &[Vector3<f64>],
    seed: u64,
) -> (usize, Vec<Vec<f32>>) {
    let env = envelopes(room, c_mps, air_db_per_m_hz2, fs);
    let len = env.end.saturating_sub(env.first);
    let m = positions.len();
    if len == 0 || m == 0 {
        return (env.first, vec![Vec::new(); m]);
    }
    let n_fft = len.next_power_of_two();
    let mut planner = FftPlanner::<f64>::new();
    let ifft = planner.plan_fft_inverse(n_fft);
    let mut g = Gaussian::new(StdRng::seed_from_u64(seed));
    // Coherent spectra, bins 0..=n/2 (the rest by symmetry).
    let half = n_fft / 2;
    let mut spectra = vec![vec![Complex::new(0.0, 0.0); n_fft]; m];
    let mut gamma = vec![0.0; m * m];
    for k in 0..=half {
        let f = k as f64 * fs / n_fft as f64;
        let wave = 2.0 * std::f64::consts::PI * f / c_mps;
        for i in 0..m {
            for j in 0..m {
                let x = wave * (positions[i] - positions[j]).norm();
                gamma[i * m + j] = if x.abs() < 1e-9 { 1.0 } else { x.sin() / x };
            }
            gamma[i * m + i] += 1e-9;
        }
        let l = cholesky(&gamma, m);
        let real_bin = k == 0 || k == half;
        let z: Vec<Complex<f64>> = (0..m)
            .map(|_| {
                if real_bin {
                    Complex::new(g.sample(), 0.0)
                } else {
                    Complex::new(g.sample(), g.sample()) * std::f64::consts::FRAC_1_SQRT_2
                }
            })
            .collect();
        for i in 0..m {
            let x: Complex<f64> = (0..=i).map(|j| z[j] * l[i * m + j]).sum();
            spectra[i][k] = x;
            if k != 0 && k != half {
                spectra[i][n_fft - k] = x.conj();
            }
        }
    }
    let scale = 1.0 / (n_fft as f64).sqrt();
    let weights: Vec<[f64; 8]> =
        (0..n_fft).map(|k| band_weights(k.min(n_fft - k) as f64 * fs / n_fft as f64)).collect();
    let mut out = Vec::with_capacity(m);
    let mut buf = vec![Complex::new(0.0, 0.0); n_fft];
    for spec in &spectra {
        let mut h = vec![0.0f64; len];
        for (b, band) in env.bands.iter().enumerate() {
            for (k, y) in buf.iter_mut().enumerate() {
                *y = spec[k] * weights[k][b];
            }
            ifft.process(&mut buf);
            for (i, y) in h.iter_mut().enumerate() {
                let t = (env.first + i) as f64 / fs / GRID_S;
                let gi = (t.floor() as usize).min(band.len() - 2);
                let fr = t - gi as f64;
                let e = band[gi] * (1.0 - fr) + band[gi + 1] * fr;
                *y += buf[i].re * scale * (e / fs).sqrt();
            }
        }
        out.push(h.into_iter().map(|x| x as f32).collect());
    }
    (env.first, out)
}

/// A static impulse response of `room` from `source` to `mic` (m) at `fs` (Hz), pressure gain
/// re 1 m per sample: every image of order ≤ `room.reflection_order` at its nearest sample
/// (gain `g / r`), plus the late tail (seed `seed`) when the room has one. No air absorption.
/// For checks of the room model (energy decay, direct-to-reverberant ratio), not for rendering.
pub fn impulse_response(
    room: &Room,
    c_mps: f64,
    source: &Vector3<f64>,
    mic: &Vector3<f64>,
    fs: f64,
    seed: u64,
) -> Vec<f64> {
    let (first, tail) = if room.late_tail {
        let (f, mut r) = tail_responses(room, c_mps, 0.0, fs, std::slice::from_ref(mic), seed);
        (f, r.pop().unwrap_or_default())
    } else {
        (0, Vec::new())
    };
    let images: Vec<(usize, f64)> = room
        .images()
        .iter()
        .map(|im| {
            let d = (im.apply(source) - mic).norm().max(0.05);
            ((d / c_mps * fs).round() as usize, im.reflection_gain / d)
        })
        .collect();
    let len = images.iter().map(|i| i.0 + 1).max().unwrap_or(0).max(first + tail.len());
    let mut h = vec![0.0; len];
    for (k, g) in images {
        h[k] += g;
    }
    for (k, x) in tail.iter().enumerate() {
        h[first + k] += f64::from(*x);
    }
    h
}

/// The late tail of every microphone of a simulation, ready to convolve block by block.
pub struct LateTail {
    /// First tail sample after emission.
    first: usize,
    /// Tail length, samples.
    len: usize,
    /// Output samples per block the FFT size allows.
    block: usize,
    fft: Arc<dyn Fft<f32>>,
    ifft: Arc<dyn Fft<f32>>,
    /// Per microphone, the spectrum of its tail (FFT size `fft.len()`), scaled by 1/N.
    spectra: Vec<Vec<Complex<f32>>>,
}

impl std::fmt::Debug for LateTail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LateTail")
            .field("first", &self.first)
            .field("len", &self.len)
            .field("mics", &self.spectra.len())
            .finish()
    }
}

impl LateTail {
    /// Tails for the microphones of each array in `arrays` (positions, m; one seed per array),
    /// for output blocks of up to `block` samples, in the order the arrays and their
    /// microphones are listed.
    pub fn new(
        room: &Room,
        c_mps: f64,
        air_db_per_m_hz2: f64,
        fs: f64,
        arrays: &[(Vec<Vector3<f64>>, u64)],
        block: usize,
    ) -> Self {
        let mut first = 0;
        let mut responses = Vec::new();
        for (positions, seed) in arrays {
            let (f, r) = tail_responses(room, c_mps, air_db_per_m_hz2, fs, positions, *seed);
            first = f;
            responses.extend(r);
        }
        let len = responses.first().map_or(0, Vec::len);
        let n_fft = (block + len).next_power_of_two();
        let mut planner = FftPlanner::<f32>::new();
        let fft = planner.plan_fft_forward(n_fft);
        let ifft = planner.plan_fft_inverse(n_fft);
        let spectra = responses
            .iter()
            .map(|h| {
                let mut buf: Vec<Complex<f32>> = (0..n_fft)
                    .map(|i| Complex::new(h.get(i).copied().unwrap_or(0.0) / n_fft as f32, 0.0))
                    .collect();
                fft.process(&mut buf);
                buf
            })
            .collect();
        Self { first, len, block, fft, ifft, spectra }
    }

    /// The longest delay the tail reads back from a block's first sample, s.
    pub fn reach_s(&self, fs: f64) -> f64 {
        (self.first + self.len) as f64 / fs
    }

    /// Adds microphone `mic`'s tail of the sum of `sources` to `out` (one output block whose
    /// first sample hears the source grid at signal index `q0`).
    pub fn add(
        &self,
        mic: usize,
        sources: &[&SourceView],
        q0: isize,
        out: &mut [f32],
    ) -> Result<(), OutsideWindow> {
        if self.len == 0 || sources.is_empty() {
            return Ok(());
        }
        assert!(out.len() <= self.block, "block longer than the tail was planned for");
        let n_fft = self.fft.len();
        // Input: signal indices q0 − first − (len − 1) .. q0 − first + out.len().
        let lo = q0 - self.first as isize - (self.len as isize - 1);
        let count = self.len - 1 + out.len();
        let mut buf = vec![Complex::new(0.0f32, 0.0); n_fft];
        for v in sources {
            let (start, end) = (v.start as isize, (v.start + v.samples.len()) as isize);
            let (a, b) = (lo.max(0), (lo + count as isize).min(v.total as isize));
            if a < b && (a < start || b > end) {
                return Err(OutsideWindow { needed_from: lo, needed_to: lo + count as isize - 1 });
            }
            for q in a..b {
                buf[(q - lo) as usize].re += v.samples[(q - start) as usize];
            }
        }
        self.fft.process(&mut buf);
        for (x, h) in buf.iter_mut().zip(&self.spectra[mic]) {
            *x *= h;
        }
        self.ifft.process(&mut buf);
        for (y, x) in out.iter_mut().zip(&buf[self.len - 1..]) {
            *y += x.re;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room(absorption: f64, order: u32) -> Room {
        Room {
            size_m: [7.0, 5.0, 3.0],
            absorption: [absorption; 6],
            reflection_order: order,
            late_tail: true,
        }
    }

    #[test]
    fn tail_energy_matches_the_exact_image_sum() {
        // Oracle: every lattice image (order ≤ 60) of a source and a receiver in the room,
        // energy (g / r)² summed in 20 ms bins, against the tail's energy above order 2.
        let r = Room { reflection_order: 60, ..room(0.25, 2) };
        let (s, m) = (Vector3::new(2.1, 1.7, 1.1), Vector3::new(4.9, 3.2, 1.6));
        let c = 343.0;
        let bin = 0.02;
        let mut hist = [0.0; 12];
        for im in r.images() {
            if im.order <= 2 {
                continue;
            }
            let d = (im.apply(&s) - m).norm();
            let i = (d / c / bin) as usize;
            if i < hist.len() {
                hist[i] += (im.reflection_gain / d).powi(2);
            }
        }
        let rate = tail_energy_rate(&room(0.25, 2), c);
        let per_bin = (bin / GRID_S).round() as usize;
        for (i, &h) in hist.iter().enumerate().skip(3) {
            let want: f64 = rate[i * per_bin..(i + 1) * per_bin].iter().sum::<f64>() * GRID_S;
            let db = 10.0 * (h / want).log10();
            assert!(db.abs() < 1.0, "bin {i}: exact {h:.3e}, model {want:.3e} ({db:.2} dB)");
        }
    }

    #[test]
    fn uniform_absorption_decays_at_eyrings_rate_first_and_never_faster() {
        // Physical law: the image model's energy is the mean over directions of exp(r d_u);
        // its initial decay rate is the mean exponent, Eyring's, and by Jensen's inequality it
        // never falls below Eyring's exponential, so T30 ≥ Eyring's time.
        let c = 343.0;
        for alpha in [0.1, 0.3, 0.6] {
            let r = room(alpha, 1);
            let decay = Decay::new(&r, c);
            let eyring = eyring_rt60_s(&r, c);
            let (t0, t1) = (0.0, 0.002);
            let db = 10.0 * (decay.energy_rate(t1, None) / decay.energy_rate(t0, None)).log10();
            let initial_rt60 = -60.0 * (t1 - t0) / db;
            assert!(
                (initial_rt60 / eyring - 1.0).abs() < 0.01,
                "α {alpha}: initial decay {initial_rt60:.3} s, Eyring {eyring:.3} s"
            );
            let t30 = decay.t30_s();
            assert!(t30 >= eyring, "α {alpha}: T30 {t30:.3} s below Eyring {eyring:.3} s");
            let back = eyring_absorption(r.size_m, eyring, c);
            assert!((back - alpha).abs() < 1e-12);
            // Sabine's time exceeds Eyring's.
            assert!(sabine_rt60_s(&r, c) > eyring);
        }
    }

    #[test]
    fn rt60_absorption_gives_that_t30() {
        let c = 343.0;
        for (size, t) in
            [([7.0, 5.0, 3.0], 0.5), ([20.0, 15.0, 5.0], 0.8), ([40.0, 8.0, 10.0], 1.8)]
        {
            let a = absorption_for_t30(size, t, c);
            let r = Room { size_m: size, absorption: [a; 6], reflection_order: 0, late_tail: true };
            let got = Decay::new(&r, c).t30_s();
            assert!((got / t - 1.0).abs() < 0.01, "{size:?}: T30 {got:.3} s for {t} s");
            assert!(a > eyring_absorption(size, t, c));
        }
    }

    #[test]
    fn tails_have_the_diffuse_coherence() {
        // Two microphones 10 cm apart: the tails' coherence follows sin(kd)/(kd).
        let r = room(0.1, 1);
        let fs = 16_000.0;
        let d = 0.1;
        let pos = [Vector3::new(3.0, 2.0, 1.0), Vector3::new(3.0 + d, 2.0, 1.0)];
        let (_, h) = tail_responses(&r, 343.0, 0.0, fs, &pos, 7);
        // Welch coherence in 256-sample frames over the first 0.4 s.
        let n = 256;
        let frames = (0.4 * fs) as usize / n;
        let mut planner = FftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(n);
        let mut sxx = vec![0.0; n / 2];
        let mut syy = vec![0.0; n / 2];
        let mut sxy = vec![Complex::new(0.0, 0.0); n / 2];
        for f in 0..frames {
            let spec = |x: &[f32]| {
                let mut b: Vec<Complex<f64>> = (0..n)
                    .map(|i| {
                        let w =
                            0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
                        Complex::new(f64::from(x[f * n + i]) * w, 0.0)
                    })
                    .collect();
                fft.process(&mut b);
                b
            };
            let (a, b) = (spec(&h[0]), spec(&h[1]));
            for k in 0..n / 2 {
                sxx[k] += a[k].norm_sqr();
                syy[k] += b[k].norm_sqr();
                sxy[k] += a[k] * b[k].conj();
            }
        }
        for hz in [500.0, 1500.0, 3000.0, 5000.0] {
            let k = (hz / fs * n as f64).round() as usize;
            // Average 5 bins around k.
            let (mut c, mut w) = (0.0, 0.0);
            for kk in k - 2..=k + 2 {
                c += sxy[kk].re / (sxx[kk] * syy[kk]).sqrt();
                w += 1.0;
            }
            let got = c / w;
            let x = 2.0 * std::f64::consts::PI * hz * d / 343.0;
            let want = x.sin() / x;
            assert!((got - want).abs() < 0.15, "{hz} Hz: coherence {got:.3}, diffuse {want:.3}");
        }
    }

    #[test]
    fn tail_responses_carry_the_envelope_energy() {
        // The realized tail's energy over 50 ms windows follows its energy rate within 1 dB.
        let r = Room { size_m: [10.0, 8.0, 4.0], ..room(0.35, 3) };
        let fs = 16_000.0;
        let (first, h) = tail_responses(&r, 343.0, 0.0, fs, &[Vector3::new(3.0, 2.5, 0.8)], 5);
        let rate = tail_energy_rate(&r, 343.0);
        let w = (0.05 * fs) as usize;
        for k in [0.06, 0.1, 0.2, 0.3] {
            let i0 = (k * fs) as usize - first;
            let got: f64 = h[0][i0..i0 + w].iter().map(|x| f64::from(*x).powi(2)).sum();
            let g0 = (k / GRID_S).round() as usize;
            let want: f64 = rate[g0..g0 + 50].iter().sum::<f64>() * GRID_S;
            let db = 10.0 * (got / want).log10();
            assert!(db.abs() < 1.0, "{k} s: realized {got:.3e}, rate {want:.3e} ({db:.2} dB)");
        }
    }

    #[test]
    fn band_weights_are_amplitude_complementary() {
        for f in [10.0, 125.0, 300.0, 1000.0, 5000.0, 16000.0, 23000.0] {
            let s: f64 = band_weights(f).iter().sum();
            assert!((s - 1.0).abs() < 1e-12, "{f} Hz: {s}");
        }
    }
}
