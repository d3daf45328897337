//! Sounds of a real room that a propeller comb is not: non-drone sources with tones (the
//! negatives of the BPF detector), the room's own background, a hall's reverberation, and the
//! motor whine of a drone. All mono, pressure in pascals at the listener, on a uniform grid.
//!
//! The non-drone sources ([`Negative`]) are built from their physics, each with the features
//! that fool a comb detector:
//! - **pink noise**: 1/f power, 50 Hz – 7 kHz (Voss–McCartney-free: a 3-pole pinking filter).
//! - **desk fan**: 5 blades at 18–22 Hz (BPF 90–110 Hz, harmonics falling 6 dB each), motor hum
//!   at 100 Hz, broadband airflow.
//! - **pump**: induction motor at 24.3 Hz (1458 rpm) with shaft harmonics, six-vane impeller
//!   (vane-pass 146 Hz, one strong line and a weak second), mains hum, flow noise.
//! - **vacuum cleaner**: universal motor at 550–620 Hz (two harmonics, wandering with load),
//!   loud tilted broadband.
//! - **machinery**: gear mesh at 340 Hz with ±12 Hz shaft sidebands and its harmonics,
//!   amplitude-modulated by a 1 Hz drum, mains hum.
//! - **vehicle**: four-cylinder engine idling at 700–900 rpm (firing 23–30 Hz) with a dense
//!   harmonic series up to 1 kHz, rpm drifting ±5 %.
//! - **speech-like**: voiced syllables (f0 90–230 Hz gliding ±15 %, 25 harmonics shaped by
//!   three formants) 120–350 ms long, with pauses.
//! - **music-like**: notes of a scale (110–880 Hz, 8 harmonics falling 4 dB each, slight
//!   vibrato) 0.15–0.6 s long, some overlapping.
//! - **mains hum**: 50 Hz and harmonics (100 Hz strongest) from a transformer.
//!
//! [`background`] is a room's own noise: brown below 200 Hz, pink above (a tilt of about
//! −6 dB/octave at the bottom, −3 dB/octave above), mains hum 12 dB below it. [`Hall`] is a
//! Freeverb-style reverberator (eight damped feedback combs, four all-passes) with the comb
//! gains set for a given RT60.
use rand::{rngs::StdRng, Rng, SeedableRng};

use crate::filter::{Biquad, Cascade, Gaussian};
use crate::sound::spl_to_rms_pa;

/// A non-drone source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Negative {
    /// Pink noise.
    PinkNoise,
    /// A desk fan.
    DeskFan,
    /// A centrifugal pump.
    Pump,
    /// A vacuum cleaner.
    Vacuum,
    /// Geared machinery.
    Machinery,
    /// An idling car engine.
    Vehicle,
    /// Voiced speech-like syllables.
    Speech,
    /// Music-like notes.
    Music,
    /// Mains hum.
    MainsHum,
}

impl Negative {
    /// Every kind, in a fixed order.
    pub const ALL: [Negative; 9] = [
        Negative::PinkNoise,
        Negative::DeskFan,
        Negative::Pump,
        Negative::Vacuum,
        Negative::Machinery,
        Negative::Vehicle,
        Negative::Speech,
        Negative::Music,
        Negative::MainsHum,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Negative::PinkNoise => "pink-noise",
            Negative::DeskFan => "desk-fan",
            Negative::Pump => "pump",
            Negative::Vacuum => "vacuum",
            Negative::Machinery => "machinery",
            Negative::Vehicle => "vehicle",
            Negative::Speech => "speech-like",
            Negative::Music => "music-like",
            Negative::MainsHum => "mains-hum",
        }
    }

    /// `len` samples at `fs` of this source, scaled to `spl_db` (RMS over the clip).
    pub fn signal(self, fs: f64, len: usize, spl_db: f64, seed: u64) -> Vec<f64> {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut x = match self {
            Negative::PinkNoise => pink(fs, len, &mut rng),
            Negative::DeskFan => {
                let rot = rng.random_range(18.0..22.0);
                let mut x = comb(fs, len, rot * 5.0, 8, -6.0, 0.002, &mut rng);
                add(&mut x, &comb(fs, len, 100.0, 3, -10.0, 0.0, &mut rng), 0.3);
                add(&mut x, &band(fs, len, 200.0, 3000.0, &mut rng), 1.0);
                x
            }
            Negative::Pump => {
                let shaft = 24.3;
                let mut x = comb(fs, len, shaft, 8, -4.0, 0.0005, &mut rng);
                add(&mut x, &comb(fs, len, 6.0 * shaft, 2, -12.0, 0.0005, &mut rng), 1.5);
                add(&mut x, &comb(fs, len, 100.0, 4, -8.0, 0.0, &mut rng), 0.5);
                add(&mut x, &band(fs, len, 100.0, 4000.0, &mut rng), 1.5);
                x
            }
            Negative::Vacuum => {
                let motor = rng.random_range(550.0..620.0);
                let mut x = comb(fs, len, motor, 2, -8.0, 0.01, &mut rng);
                add(&mut x, &pink(fs, len, &mut rng), 4.0);
                add(&mut x, &band(fs, len, 1000.0, 7000.0, &mut rng), 3.0);
                x
            }
            Negative::Machinery => {
                let mut x = vec![0.0; len];
                for (f, a) in [(340.0, 1.0), (328.0, 0.5), (352.0, 0.5), (680.0, 0.4)] {
                    add(&mut x, &comb(fs, len, f, 1, 0.0, 0.0, &mut rng), a);
                }
                for (t, v) in x.iter_mut().enumerate() {
                    *v *= 1.0 + 0.6 * (std::f64::consts::TAU * t as f64 / fs).sin();
                }
                add(&mut x, &comb(fs, len, 100.0, 3, -6.0, 0.0, &mut rng), 0.5);
                add(&mut x, &pink(fs, len, &mut rng), 1.0);
                x
            }
            Negative::Vehicle => {
                let firing = rng.random_range(23.0..30.0);
                let mut x = comb(fs, len, firing, 40, -0.8, 0.05, &mut rng);
                add(&mut x, &band(fs, len, 30.0, 2000.0, &mut rng), 0.7);
                x
            }
            Negative::Speech => speech(fs, len, &mut rng),
            Negative::Music => music(fs, len, &mut rng),
            Negative::MainsHum => {
                let mut x = vec![0.0; len];
                for (h, a) in [(1.0, 0.3), (2.0, 1.0), (3.0, 0.25), (4.0, 0.4), (6.0, 0.15)] {
                    add(&mut x, &comb(fs, len, 50.0 * h, 1, 0.0, 0.0, &mut rng), a);
                }
                add(&mut x, &pink(fs, len, &mut rng), 0.05);
                x
            }
        };
        scale_to_spl(&mut x, spl_db);
        x
    }
}

/// Adds `g · y` to `x`.
pub fn add(x: &mut [f64], y: &[f64], g: f64) {
    for (a, b) in x.iter_mut().zip(y) {
        *a += g * b;
    }
}

/// Scales `x` to an RMS of `spl_db`.
pub fn scale_to_spl(x: &mut [f64], spl_db: f64) {
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt();
    if rms > 0.0 {
        let g = spl_to_rms_pa(spl_db) / rms;
        x.iter_mut().for_each(|v| *v *= g);
    }
}

/// A harmonic series: fundamental `f0`, `n` harmonics falling `slope_db` each, random phases,
/// the fundamental wandering by a slow random walk of relative size `wander` (rms), unit RMS of
/// the fundamental's amplitude 1.
pub fn comb(
    fs: f64,
    len: usize,
    f0: f64,
    n: usize,
    slope_db: f64,
    wander: f64,
    rng: &mut StdRng,
) -> Vec<f64> {
    let phases: Vec<f64> = (0..n).map(|_| rng.random::<f64>()).collect();
    let amps: Vec<f64> = (0..n).map(|h| 10f64.powf(slope_db * h as f64 / 20.0)).collect();
    let mut drift = Ou::new(wander, 1.0, fs, rng.random());
    let mut phase = 0.0f64;
    let mut out = Vec::with_capacity(len);
    for _ in 0..len {
        let mut v = 0.0;
        for (h, (a, p)) in amps.iter().zip(&phases).enumerate() {
            let f = (h + 1) as f64 * f0;
            if f < 0.45 * fs {
                v += a * (std::f64::consts::TAU * ((h + 1) as f64 * phase + p)).sin();
            }
        }
        out.push(v);
        phase += f0 * (1.0 + drift.step()) / fs;
        phase -= phase.floor();
    }
    out
}

/// An Ornstein–Uhlenbeck process: stationary standard deviation `sigma`, correlation time
/// `tau_s`, one value per sample at `fs`.
pub struct Ou {
    x: f64,
    a: f64,
    b: f64,
    noise: Gaussian,
}

impl Ou {
    /// Starts at a random stationary value.
    pub fn new(sigma: f64, tau_s: f64, fs: f64, seed: u64) -> Self {
        let a = (-1.0 / (tau_s * fs)).exp();
        let mut noise = Gaussian::new(StdRng::seed_from_u64(seed));
        let x = sigma * noise.sample();
        Self { x, a, b: sigma * (1.0 - a * a).sqrt(), noise }
    }

    /// The next value.
    pub fn step(&mut self) -> f64 {
        self.x = self.a * self.x + self.b * self.noise.sample();
        self.x
    }
}

/// Band noise (two second-order sections at each edge), unit variance before filtering.
pub fn band(fs: f64, len: usize, low_hz: f64, high_hz: f64, rng: &mut StdRng) -> Vec<f64> {
    let mut g = Gaussian::new(StdRng::seed_from_u64(rng.random()));
    let q = std::f64::consts::FRAC_1_SQRT_2;
    let mut c = Cascade(vec![
        Biquad::highpass(low_hz, q, fs),
        Biquad::highpass(low_hz, q, fs),
        Biquad::lowpass(high_hz.min(0.45 * fs), q, fs),
        Biquad::lowpass(high_hz.min(0.45 * fs), q, fs),
    ]);
    (0..len).map(|_| c.process(g.sample())).collect()
}

/// Pink noise (Paul Kellett's refined pinking filter on white noise), 30 Hz high-pass.
pub fn pink(fs: f64, len: usize, rng: &mut StdRng) -> Vec<f64> {
    let mut g = Gaussian::new(StdRng::seed_from_u64(rng.random()));
    let mut b = [0.0f64; 7];
    let mut hp = Biquad::highpass(30.0, std::f64::consts::FRAC_1_SQRT_2, fs);
    (0..len)
        .map(|_| {
            let w = g.sample();
            b[0] = 0.99886 * b[0] + w * 0.0555179;
            b[1] = 0.99332 * b[1] + w * 0.0750759;
            b[2] = 0.96900 * b[2] + w * 0.1538520;
            b[3] = 0.86650 * b[3] + w * 0.3104856;
            b[4] = 0.55000 * b[4] + w * 0.5329522;
            b[5] = -0.7616 * b[5] - w * 0.0168980;
            let p = b[..6].iter().sum::<f64>() + b[6] + w * 0.5362;
            b[6] = w * 0.115926;
            hp.process(p)
        })
        .collect()
}

/// Brown noise (integrated white, leaky) high-passed at 20 Hz.
fn brown(fs: f64, len: usize, rng: &mut StdRng) -> Vec<f64> {
    let mut g = Gaussian::new(StdRng::seed_from_u64(rng.random()));
    let mut hp = Biquad::highpass(20.0, std::f64::consts::FRAC_1_SQRT_2, fs);
    let mut lp = Biquad::lowpass(200.0, std::f64::consts::FRAC_1_SQRT_2, fs);
    let mut acc = 0.0;
    (0..len)
        .map(|_| {
            acc = 0.995 * acc + g.sample();
            hp.process(lp.process(acc))
        })
        .collect()
}

/// A room's own noise at `spl_db`: brown below 200 Hz and pink above, equal power, plus
/// mains hum (100 Hz with 50, 150, 200 Hz) 12 dB below the whole.
pub fn background(fs: f64, len: usize, spl_db: f64, seed: u64) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut x = brown(fs, len, &mut rng);
    scale_to_spl(&mut x, 0.0);
    let mut p = pink(fs, len, &mut rng);
    scale_to_spl(&mut p, 0.0);
    add(&mut x, &p, 1.0);
    let mut hum = Negative::MainsHum.signal(fs, len, 0.0, rng.random());
    scale_to_spl(&mut hum, -12.0 + 3.0);
    add(&mut x, &hum, 1.0);
    scale_to_spl(&mut x, spl_db);
    x
}

/// Speech-like voiced syllables.
fn speech(fs: f64, len: usize, rng: &mut StdRng) -> Vec<f64> {
    let mut out = vec![0.0; len];
    let mut t = (rng.random::<f64>() * 0.2 * fs) as usize;
    let f_speaker = rng.random_range(90.0..230.0);
    while t < len {
        let dur = (rng.random_range(0.12..0.35) * fs) as usize;
        let f_start = f_speaker * rng.random_range(0.85..1.15);
        let f_end = f_start * rng.random_range(0.85..1.15);
        let formants = [
            rng.random_range(300.0..800.0),
            rng.random_range(900.0..2200.0),
            rng.random_range(2300.0..3200.0),
        ];
        let mut phase = 0.0f64;
        let end = (t + dur).min(len);
        for (i, o) in out[t..end].iter_mut().enumerate() {
            let u = i as f64 / dur as f64;
            let f0 = f_start + (f_end - f_start) * u;
            let env = (std::f64::consts::PI * u).sin().powi(2);
            let mut v = 0.0;
            for h in 1..=25 {
                let f = h as f64 * f0;
                if f > 0.45 * fs {
                    break;
                }
                let gain: f64 = formants
                    .iter()
                    .map(|&fc| 1.0 / (1.0 + ((f - fc) / (0.12 * fc)).powi(2)))
                    .sum::<f64>()
                    / (h as f64).sqrt();
                v += gain * (std::f64::consts::TAU * h as f64 * phase).sin();
            }
            *o += env * v;
            phase += f0 / fs;
            phase -= phase.floor();
        }
        t = end + (rng.random_range(0.05..0.4) * fs) as usize;
    }
    let mut breath = band(fs, len, 500.0, 5000.0, rng);
    scale_to_spl(&mut breath, -30.0);
    add(&mut out, &breath, 1.0);
    out
}

/// Music-like notes of a scale.
fn music(fs: f64, len: usize, rng: &mut StdRng) -> Vec<f64> {
    let mut out = vec![0.0; len];
    let scale = [0, 2, 4, 5, 7, 9, 11];
    let mut t = 0usize;
    while t < len {
        let dur = (rng.random_range(0.15..0.6) * fs) as usize;
        let semis = 12 * rng.random_range(0..3) + scale[rng.random_range(0..scale.len())];
        let f0 = 110.0 * 2f64.powf(f64::from(semis) / 12.0);
        let end = (t + dur).min(len);
        let phases: Vec<f64> = (0..8).map(|_| rng.random()).collect();
        for (i, o) in out[t..end].iter_mut().enumerate() {
            let ts = i as f64 / fs;
            let env = (-(ts) / (dur as f64 / fs * 0.6)).exp() * (1.0 - (-ts / 0.01).exp());
            let vib = 1.0 + 0.004 * (std::f64::consts::TAU * 5.5 * ts).sin();
            let mut v = 0.0;
            for (h, p) in phases.iter().enumerate() {
                let f = (h + 1) as f64 * f0 * vib;
                if f > 0.45 * fs {
                    break;
                }
                let a = 10f64.powf(-4.0 * h as f64 / 20.0);
                v += a * (std::f64::consts::TAU * ((h + 1) as f64 * f0 * ts + p)).sin();
            }
            *o += env * v;
        }
        // Sometimes the next note starts before this one ends.
        t = if rng.random::<f64>() < 0.3 { t + dur / 2 } else { end };
    }
    out
}

/// Freeverb-style hall: eight damped feedback combs in parallel, four all-passes in series.
pub struct Hall {
    combs: Vec<(Vec<f64>, usize, f64, f64)>,
    allpasses: Vec<(Vec<f64>, usize)>,
    damp: f64,
}

impl Hall {
    /// A hall of reverberation time `rt60_s` at `fs`.
    pub fn new(rt60_s: f64, fs: f64) -> Self {
        // Freeverb's delays at 44.1 kHz, scaled to fs.
        let k = fs / 44_100.0;
        let combs = [1116, 1188, 1277, 1356, 1422, 1491, 1557, 1617]
            .iter()
            .map(|&d| {
                let n = ((d as f64 * k) as usize).max(1);
                let g = 10f64.powf(-3.0 * n as f64 / fs / rt60_s);
                (vec![0.0; n], 0usize, g, 0.0)
            })
            .collect();
        let allpasses = [556, 441, 341, 225]
            .iter()
            .map(|&d| (vec![0.0; ((d as f64 * k) as usize).max(1)], 0usize))
            .collect();
        Self { combs, allpasses, damp: 0.2 }
    }

    /// The reverberant tail of `x` (no direct sound), unit-power-normalised by the caller.
    pub fn process(&mut self, x: &[f64]) -> Vec<f64> {
        let damp = self.damp;
        x.iter()
            .map(|&v| {
                let mut y = 0.0;
                for (buf, i, g, lp) in self.combs.iter_mut() {
                    let out = buf[*i];
                    *lp = out * (1.0 - damp) + *lp * damp;
                    buf[*i] = v + *g * *lp;
                    *i = (*i + 1) % buf.len();
                    y += out;
                }
                for (buf, i) in self.allpasses.iter_mut() {
                    let b = buf[*i];
                    buf[*i] = y + 0.5 * b;
                    y = b - y;
                    *i = (*i + 1) % buf.len();
                }
                y
            })
            .collect()
    }
}

/// A hall's diffuse tail by the simulator's own late-reverberation model ([`crate::reverb`],
/// checked against pyroomacoustics, BENCHMARKS.md "Rooms that ring"): Gaussian noise whose
/// energy follows the image model's decay in octave bands, of a shoebox with the hall's
/// volume (proportions 4 : 3 : 1.6) and uniform absorption for `rt60_s`.
///
/// Its frequency response is a real large room's above the Schroeder frequency: a random
/// (Rayleigh) magnitude whose maxima lie about `4 / RT60` Hz apart, the same statistics at
/// every frequency. [`Hall`]'s eight feedback combs instead make clusters of resonances
/// every 30 Hz or so that stand 10–13 dB over the response's median (at RT60 1.6 s and
/// 16 kHz: 621.6 and 651.6 Hz), which a rotor line wandering past is pinned to.
pub struct DiffuseHall {
    /// Tail impulse response, pressure re the emitted signal per sample, from emission.
    response: Vec<f64>,
}

impl DiffuseHall {
    /// The tail of a hall of `volume_m3` with reverberation time `rt60_s`, at `fs` (Hz); `seed`
    /// draws the tail's noise.
    pub fn new(rt60_s: f64, volume_m3: f64, fs: f64, seed: u64) -> Self {
        use crate::reverb::{absorption_for_t30, tail_responses};
        use nalgebra::Vector3;
        let c = 343.0;
        // 4 : 3 : 1.6 (a sports hall's shape): x = (V / 1.92)^(1/3).
        let x = (volume_m3 / 1.92).cbrt();
        let size_m = [1.0 * x, 0.75 * x, 0.4 * x];
        let alpha = absorption_for_t30(size_m, rt60_s, c);
        let room = crate::room::Room {
            size_m,
            absorption: [alpha; 6],
            reflection_order: 0,
            late_tail: true,
        };
        let at = Vector3::new(0.5 * size_m[0], 0.5 * size_m[1], 1.2);
        let (first, mut tails) = tail_responses(&room, c, 0.0, fs, &[at], seed);
        let tail = tails.pop().unwrap_or_default();
        let mut response = vec![0.0; first + tail.len()];
        for (r, &t) in response[first..].iter_mut().zip(&tail) {
            *r = f64::from(t);
        }
        Self { response }
    }

    /// The reverberant tail of `x` (no direct sound), as long as `x`; its level is the model's,
    /// which the caller may scale.
    pub fn process(&self, x: &[f64]) -> Vec<f64> {
        use rustfft::num_complex::Complex;
        let (n, h) = (x.len(), &self.response);
        if n == 0 || h.is_empty() {
            return vec![0.0; n];
        }
        let size = (n + h.len()).next_power_of_two();
        let mut planner = rustfft::FftPlanner::<f64>::new();
        let (fwd, inv) = (planner.plan_fft_forward(size), planner.plan_fft_inverse(size));
        let pad = |v: &[f64]| {
            let mut b = vec![Complex::new(0.0, 0.0); size];
            for (d, &s) in b.iter_mut().zip(v) {
                d.re = s;
            }
            b
        };
        let (mut a, mut b) = (pad(x), pad(h));
        fwd.process(&mut a);
        fwd.process(&mut b);
        for (p, q) in a.iter_mut().zip(&b) {
            *p *= q;
        }
        inv.process(&mut a);
        a[..n].iter().map(|v| v.re / size as f64).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sound::rms_pa_to_spl;

    #[test]
    fn negatives_have_their_level() {
        for n in Negative::ALL {
            let x = n.signal(16_000.0, 16_000, 63.0, 3);
            let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
            assert!((rms_pa_to_spl(rms) - 63.0).abs() < 1e-6, "{}", n.name());
        }
    }

    #[test]
    fn hall_tail_decays_at_its_rt60() {
        // Energy of the impulse response in two windows 0.3 s apart: 60 dB per RT60.
        let fs = 16_000.0;
        let mut x = vec![0.0; (1.5 * fs) as usize];
        x[0] = 1.0;
        let y = Hall::new(1.0, fs).process(&x);
        let e = |a: f64, b: f64| {
            y[(a * fs) as usize..(b * fs) as usize].iter().map(|v| v * v).sum::<f64>()
        };
        let drop_db = 10.0 * (e(0.2, 0.4) / e(0.5, 0.7)).log10();
        assert!((drop_db - 18.0).abs() < 4.0, "decay {drop_db} dB over 0.3 s (RT60 1 s: 18 dB)");
    }

    /// Mean spacing (Hz) of the maxima of |H(f)|² over 500–1000 Hz, and the energy decay in
    /// dB over 0.2–0.4 s against 0.5–0.7 s, of an impulse response at 16 kHz.
    fn response_statistics(h: &[f64]) -> (f64, f64) {
        use rustfft::num_complex::Complex;
        let fs = 16_000.0;
        let n = 1 << 18;
        let mut b: Vec<Complex<f64>> =
            (0..n).map(|i| Complex::new(h.get(i).copied().unwrap_or(0.0), 0.0)).collect();
        rustfft::FftPlanner::new().plan_fft_forward(n).process(&mut b);
        let bin = fs / n as f64;
        let p: Vec<f64> = (0..n / 2).map(|k| b[k].norm_sqr()).collect();
        let (lo, hi) = ((500.0 / bin) as usize, (1000.0 / bin) as usize);
        let maxima = (lo..hi).filter(|&k| p[k] > p[k - 1] && p[k] > p[k + 1]).count();
        let e = |a: f64, b: f64| {
            h[(a * fs) as usize..(b * fs) as usize].iter().map(|v| v * v).sum::<f64>()
        };
        (500.0 / maxima as f64, 10.0 * (e(0.2, 0.4) / e(0.5, 0.7)).log10())
    }

    #[test]
    fn a_diffuse_hall_decays_at_its_rt60_and_its_response_has_schroeders_maxima() {
        // Schroeder and Kuttruff (1962): above the Schroeder frequency a room's |H(f)|² has
        // maxima about 4 / T60 Hz apart on average (here 4 Hz at 1 s, 2.5 Hz at 1.6 s); the
        // energy falls 60 dB per RT60 (18 dB over 0.3 s at 1 s). The Freeverb-style [`Hall`]
        // fails the first: its maxima lie 5.1–6.3 Hz apart, 1.6–2× too sparse (BENCHMARKS.md,
        // issue 19, session 16).
        let fs = 16_000.0;
        for (rt60, volume, seed) in [(1.0, 3000.0, 1), (1.6, 6000.0, 2)] {
            let mut x = vec![0.0; (2.5 * fs) as usize];
            x[0] = 1.0;
            let h = DiffuseHall::new(rt60, volume, fs, seed).process(&x);
            let (spacing, drop_db) = response_statistics(&h);
            let want = 4.0 / rt60;
            println!("RT60 {rt60} s: maxima {spacing:.2} Hz apart (Schroeder {want:.2}), decay {drop_db:.1} dB");
            assert!((spacing / want - 1.0).abs() < 0.3, "maxima {spacing} Hz apart at RT60 {rt60}");
            let want_db = 60.0 * 0.3 / rt60;
            assert!((drop_db - want_db).abs() < 0.2 * want_db, "decay {drop_db} dB at RT60 {rt60}");
            // The Freeverb-style hall of the same RT60, for contrast: resonance clusters.
            let mut x = vec![0.0; (2.5 * fs) as usize];
            x[0] = 1.0;
            let (spacing, _) = response_statistics(&Hall::new(rt60, fs).process(&x));
            println!("  Freeverb-style Hall: maxima {spacing:.2} Hz apart");
            assert!(spacing > 1.5 * want, "Hall maxima {spacing} Hz apart at RT60 {rt60}");
        }
    }
}
