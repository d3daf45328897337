//! Test signals: exact fractional delays (frequency domain), white noise with a fixed seed, and
//! conversion to TDM words as a 24-bit microphone would deliver them.
#![allow(dead_code)]

use rustfft::num_complex::Complex64;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// xorshift64* with Box–Muller Gaussians: deterministic, no dependencies.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

/// A periodic test signal of `n` samples (a power of two) defined by its spectrum, so that any
/// fractional delay is exact: bin k is multiplied by e^{−j2πk·d/n}.
pub struct PeriodicSignal {
    spectrum: Vec<Complex64>,
}

impl PeriodicSignal {
    /// Empty spectrum of `n` bins.
    pub fn new(n: usize) -> Self {
        Self { spectrum: vec![Complex64::new(0.0, 0.0); n] }
    }

    pub fn len(&self) -> usize {
        self.spectrum.len()
    }

    /// Adds white Gaussian noise band-limited to [f_lo, f_hi] Hz with RMS `rms`.
    pub fn add_broadband(&mut self, fs: f64, f_lo: f64, f_hi: f64, rms: f64, rng: &mut Rng) {
        let n = self.len();
        let k_lo = (f_lo / fs * n as f64).ceil() as usize;
        let k_hi = (f_hi / fs * n as f64).floor() as usize;
        let bins = (k_hi - k_lo + 1) as f64;
        // Real signal: power = 2 · Σ |X_k|² / n² over positive bins.
        let a = rms * n as f64 / (2.0 * bins).sqrt();
        for k in k_lo..=k_hi {
            let z = Complex64::new(rng.gauss(), rng.gauss()) * (a / 2f64.sqrt());
            self.spectrum[k] += z;
        }
    }

    /// Adds a sinusoid of amplitude `amp` at bin `k` (frequency k·fs/n) with phase `phase`.
    pub fn add_tone_bin(&mut self, k: usize, amp: f64, phase: f64) {
        let n = self.len() as f64;
        self.spectrum[k] += Complex64::from_polar(amp * n / 2.0, phase);
    }

    /// The signal delayed by `delay` samples (circularly), real.
    pub fn delayed(&self, delay: f64) -> Vec<f64> {
        let n = self.len();
        let mut buf: Vec<Complex64> = vec![Complex64::new(0.0, 0.0); n];
        for k in 1..n / 2 {
            let z = self.spectrum[k]
                * Complex64::from_polar(1.0, -2.0 * PI * k as f64 * delay / n as f64);
            buf[k] = z;
            buf[n - k] = z.conj();
        }
        FftPlanner::new().plan_fft_inverse(n).process(&mut buf);
        buf.iter().map(|z| z.re / n as f64).collect()
    }
}

/// Adds white Gaussian noise of RMS `rms` to `x`.
pub fn add_noise(x: &mut [f64], rms: f64, rng: &mut Rng) {
    for v in x {
        *v += rms * rng.gauss();
    }
}

pub fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Channels (fractions of full scale) → interleaved TDM words, `slots` per frame: 24-bit
/// samples, rounded and saturated, left-justified in i32.
pub fn to_tdm(channels: &[Vec<f64>], slots: usize) -> Vec<i32> {
    let n = channels[0].len();
    let mut words = vec![0i32; n * slots];
    for (c, ch) in channels.iter().enumerate() {
        for (t, &v) in ch.iter().enumerate() {
            let s = (v * 8_388_608.0).round().clamp(-8_388_608.0, 8_388_607.0) as i32;
            words[t * slots + c] = s << 8;
        }
    }
    words
}

/// Runs a pipeline over TDM words in uneven chunks (as DMA half-buffers of varying size would
/// arrive) and collects the outputs.
pub fn run(pipeline: &mut aim_dsp::Pipeline, words: &[i32]) -> Vec<aim_dsp::Output> {
    let mut out = Vec::new();
    let mut rest = words;
    let mut chunk = 1usize;
    while !rest.is_empty() {
        let take = chunk.min(rest.len());
        pipeline.push(&rest[..take], &mut |o| out.push(o));
        rest = &rest[take..];
        chunk = (chunk * 7 + 3) % 5003 + 1; // deliberately not a multiple of the frame size
    }
    out
}

/// Channels of a plane wave from (`az_deg`, `zen_deg`) over `geometry`'s microphones, exact
/// delays at 343 m/s: band-limited noise (150 Hz to `high_hz`, rms 0.02) plus 8 harmonics of the
/// bin nearest `f0_hz` (0.02 each, random phases), and 0.004 rms of noise per microphone.
/// `frames` samples at `fs`, periodic, seeded by `seed`.
pub fn plane_wave(
    geometry: &aim_dsp::Geometry,
    fs: f64,
    frames: usize,
    (az_deg, zen_deg): (f64, f64),
    f0_hz: usize,
    high_hz: f64,
    seed: u64,
) -> Vec<Vec<f64>> {
    let mut rng = Rng::new(seed);
    let mut s = PeriodicSignal::new(frames);
    s.add_broadband(fs, 150.0, high_hz, 0.02, &mut rng);
    let comb = frames * f0_hz / fs as usize;
    for h in 1..=8 {
        s.add_tone_bin(comb * h, 0.02, rng.uniform() * std::f64::consts::TAU);
    }
    let (az, zen) = (az_deg.to_radians(), zen_deg.to_radians());
    let u = [zen.sin() * az.cos(), zen.sin() * az.sin()];
    geometry
        .positions()
        .iter()
        .map(|p| {
            let mut x = s.delayed(-(p[0] as f64 * u[0] + p[1] as f64 * u[1]) / 343.0 * fs);
            add_noise(&mut x, 0.004, &mut rng);
            x
        })
        .collect()
}

/// The `Doa` outputs among `outputs`, in order.
pub fn doas(outputs: &[aim_dsp::Output]) -> Vec<aim_dsp::Doa> {
    outputs
        .iter()
        .filter_map(|o| if let aim_dsp::Output::Doa(d) = o { Some(*d) } else { None })
        .collect()
}
