//! Propeller sound at the source: for each rotor, the pressure it would make at 1 m in free
//! field (pascals), on the simulator's source time grid.
//!
//! Per rotor with shaft phase φ(t) = ∫ f dt (cycles):
//! - tonal: `Σₘ Aₘ cos(2π m φ + ψₘ)` over shaft harmonics m = 1 ..= blades·K. Multiples of the
//!   blade count are the BPF harmonics (level falling `harmonic_slope_db` per harmonic); the
//!   others are the shaft-rate lines of imbalance (`shaft_line_db` below, plus the airframe's
//!   boost on a chipped propeller, [`crate::profile::Airframe`]). Random phases ψₘ.
//! - broadband: Gaussian noise shaped to 250 Hz – 6 kHz, amplitude-modulated at the BPF
//!   (`1 + ½ cos 2π n φ`), `broadband_db` relative to the tonal power.
//! - both scale with `(f / f_hover)^level_exponent`.
//!
//! Calibration: in hover the rotors' powers add (incoherent phases) to `spl_1m_db` at 1 m.
use rand::{rngs::StdRng, Rng, SeedableRng};

use crate::filter::{Biquad, Cascade, Gaussian};
use crate::flight::FlightLog;
use crate::profile::DroneProfile;

/// Reference pressure for SPL, Pa.
pub const P_REF_PA: f64 = 20e-6;

/// Root-mean-square pressure of a sound pressure level, Pa.
pub fn spl_to_rms_pa(spl_db: f64) -> f64 {
    P_REF_PA * 10f64.powf(spl_db / 20.0)
}

/// Sound pressure level of an RMS pressure, dB re 20 µPa.
pub fn rms_pa_to_spl(rms_pa: f64) -> f64 {
    20.0 * (rms_pa / P_REF_PA).log10()
}

/// A source signal on a uniform time grid: sample k is at `t0_s + k / sample_rate_hz`.
#[derive(Clone, Debug)]
pub struct SourceSignal {
    /// Time of sample 0, s.
    pub t0_s: f64,
    /// Samples per second.
    pub sample_rate_hz: f64,
    /// Pressure at 1 m from the source in free field, Pa.
    pub samples: Vec<f32>,
}

/// Relative amplitudes of the shaft harmonics m = 1..=blades·K (index m−1), before scaling;
/// the shaft-rate lines `shaft_line_boost_db` above the profile's.
fn harmonic_shape(profile: &DroneProfile, shaft_line_boost_db: f64) -> Vec<f64> {
    let n = profile.blades as usize;
    (1..=n * profile.bpf_harmonics as usize)
        .map(|m| {
            let k = m as f64 / n as f64; // harmonic number in BPF units
            let db = profile.harmonic_slope_db * (k - 1.0).max(0.0)
                + if m % n == 0 { 0.0 } else { profile.shaft_line_db + shaft_line_boost_db };
            10f64.powf(db / 20.0)
        })
        .collect()
}

/// Synthesizes the sound of rotor `rotor` of a flight, `len` samples from `t0_s`; its shaft-rate
/// lines `shaft_line_boost_db` louder than the profile says (a chipped propeller; 0 nominal).
#[allow(clippy::too_many_arguments)] // one rotor's sound: profile, flight, grid, airframe, seed
pub fn propeller(
    profile: &DroneProfile,
    shaft_line_boost_db: f64,
    log: &FlightLog,
    rotor: usize,
    t0_s: f64,
    sample_rate_hz: f64,
    len: usize,
    seed: u64,
) -> SourceSignal {
    let mut g =
        Propeller::new(profile, shaft_line_boost_db, log, rotor, t0_s, sample_rate_hz, len, seed);
    let mut samples = vec![0.0; len];
    g.fill(&mut samples);
    SourceSignal { t0_s, sample_rate_hz, samples }
}

/// A generator of samples of a source signal, block by block: the same samples in the same
/// order whatever the block sizes asked for.
pub trait SignalBlocks: Send {
    /// Writes the next `out.len()` samples (Pa at 1 m); zeros past the signal's length.
    fn fill(&mut self, out: &mut [f32]);
}

/// The sound of one rotor ([`propeller`]) generated block by block: the synthesis runs in
/// steps of at most 256 samples (ending at flight-log samples), whose boundaries depend only
/// on the signal's total length, so any block split gives the same bits as the whole signal.
pub struct Propeller<'a> {
    log: &'a FlightLog,
    rotor: usize,
    t0_s: f64,
    sample_rate_hz: f64,
    len: usize,
    amps: Vec<f64>,
    phases: Vec<(f64, f64)>,
    shaping: Cascade,
    bb_scale: f64,
    noise: Gaussian,
    blades: usize,
    f_hover: f64,
    level_exponent: f64,
    /// Shaft phase at sample `k`, cycles.
    phase: f64,
    /// Next sample the synthesis computes.
    k: usize,
    /// Samples synthesized but not handed out yet.
    pending: Vec<f32>,
    /// How many of `pending` were handed out.
    taken: usize,
}

/// Depth of the broadband noise's modulation at the blade-passing frequency.
const MODULATION: f64 = 0.5;

impl<'a> Propeller<'a> {
    /// Prepares rotor `rotor`'s sound of `len` samples from `t0_s` (arguments as [`propeller`]).
    #[allow(clippy::too_many_arguments)] // as `propeller`
    pub fn new(
        profile: &DroneProfile,
        shaft_line_boost_db: f64,
        log: &'a FlightLog,
        rotor: usize,
        t0_s: f64,
        sample_rate_hz: f64,
        len: usize,
        seed: u64,
    ) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let shape = harmonic_shape(profile, shaft_line_boost_db);
        // Per-rotor RMS in hover; tonal and broadband shares of its power.
        let p_rotor = spl_to_rms_pa(profile.spl_1m_db) / (profile.rotor_count() as f64).sqrt();
        let bb_ratio = 10f64.powf(profile.broadband_db / 10.0);
        let tonal_power = p_rotor * p_rotor / (1.0 + bb_ratio);
        // Calibrated on the profile's own shape: a chipped propeller's boost adds power.
        let unit_power: f64 = harmonic_shape(profile, 0.0).iter().map(|a| a * a / 2.0).sum();
        let tonal_scale = (tonal_power / unit_power).sqrt();
        let amps: Vec<f64> = shape.iter().map(|a| a * tonal_scale).collect();
        let phases: Vec<(f64, f64)> =
            amps.iter().map(|_| (std::f64::consts::TAU * rng.random::<f64>()).sin_cos()).collect();

        let shaping = Cascade(vec![
            Biquad::highpass(250.0, std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
            Biquad::lowpass(6000.0, std::f64::consts::FRAC_1_SQRT_2, sample_rate_hz),
        ]);
        let bb_power = tonal_power * bb_ratio;
        let bb_scale = (bb_power
            / (shaping.white_noise_power_gain() * (1.0 + MODULATION * MODULATION / 2.0)))
            .sqrt();
        let noise = Gaussian::new(StdRng::seed_from_u64(rng.random()));
        let phase: f64 = rng.random(); // cycles
        Self {
            log,
            rotor,
            t0_s,
            sample_rate_hz,
            len,
            amps,
            phases,
            shaping,
            bb_scale,
            noise,
            blades: profile.blades as usize,
            f_hover: profile.hover_rotor_hz,
            level_exponent: profile.level_exponent,
            phase,
            k: 0,
            pending: Vec::with_capacity(256),
            taken: 0,
        }
    }

    /// Synthesizes the next step (at most 256 samples) into `pending`.
    fn step(&mut self) {
        let (t0_s, sample_rate_hz, len, log) = (self.t0_s, self.sample_rate_hz, self.len, self.log);
        let nyquist_guard = 0.45 * sample_rate_hz;
        let k = self.k;
        // Rotor speed and level are linear between flight-log samples; the unit phasor
        // e^{i2πφ} is advanced by small rotations and re-anchored to the exact phase every step.
        let speed_and_level = |t: f64| {
            let f = log.rotor_hz(self.rotor, t).max(0.0);
            (f, (f / self.f_hover).powf(self.level_exponent))
        };
        let t_a = t0_s + k as f64 / sample_rate_hz;
        let (i, _) = log.locate(t_a);
        let t_next = log.t0_s + (i + 1) as f64 * log.dt_s;
        let end = if t_next <= t_a || i + 1 >= log.samples.len() {
            len
        } else {
            (((t_next - t0_s) * sample_rate_hz).ceil() as usize).clamp(k + 1, len)
        };
        let end = end.min(k + 256);
        let (f_a, lv_a) = speed_and_level(t_a);
        let t_b = t0_s + end as f64 / sample_rate_hz;
        let (f_b, lv_b) = speed_and_level(t_b);
        let n = (end - k) as f64;
        let mut phase = self.phase;
        let (mut zr1, mut zi1) = {
            let (s, c) = (std::f64::consts::TAU * phase).sin_cos();
            (c, s)
        };
        let top = ((nyquist_guard / f_a.max(f_b).max(1e-3)) as usize).min(self.amps.len());
        self.pending.clear();
        self.taken = 0;
        for j in 0..end - k {
            let w = j as f64 / n;
            let f = f_a + (f_b - f_a) * w;
            let level = lv_a + (lv_b - lv_a) * w;
            let (mut zr, mut zi) = (1.0, 0.0);
            let mut tonal = 0.0;
            let mut blade_cos = 0.0;
            for (m, (a, (ps, pc))) in self.amps.iter().zip(&self.phases).enumerate().take(top) {
                // z = e^{i 2π (m+1) φ}, one complex multiplication per harmonic.
                let nr = zr * zr1 - zi * zi1;
                zi = zr * zi1 + zi * zr1;
                zr = nr;
                tonal += a * (zr * pc - zi * ps);
                if m + 1 == self.blades {
                    blade_cos = zr;
                }
            }
            let bb = self.shaping.process(self.noise.sample())
                * self.bb_scale
                * (1.0 + MODULATION * blade_cos);
            self.pending.push(((tonal + bb) * level) as f32);
            // Advance the phase by f / fs: exact in φ, a 5th-order rotation for the phasor.
            let d = f / sample_rate_hz;
            phase += d;
            let a = std::f64::consts::TAU * d;
            let a2 = a * a;
            let (c, s) = (1.0 - a2 / 2.0 + a2 * a2 / 24.0, a * (1.0 - a2 / 6.0 + a2 * a2 / 120.0));
            let nr = zr1 * c - zi1 * s;
            zi1 = zr1 * s + zi1 * c;
            zr1 = nr;
        }
        self.phase = phase - phase.floor();
        self.k = end;
    }
}

impl SignalBlocks for Propeller<'_> {
    fn fill(&mut self, out: &mut [f32]) {
        let mut done = 0;
        while done < out.len() {
            if self.taken == self.pending.len() {
                if self.k >= self.len {
                    out[done..].fill(0.0);
                    return;
                }
                self.step();
            }
            let n = (self.pending.len() - self.taken).min(out.len() - done);
            out[done..done + n].copy_from_slice(&self.pending[self.taken..self.taken + n]);
            self.taken += n;
            done += n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spl_round_trip() {
        assert!((rms_pa_to_spl(spl_to_rms_pa(77.0)) - 77.0).abs() < 1e-12);
        assert!((spl_to_rms_pa(94.0) - 1.0).abs() < 0.003);
    }
    /// A chipped propeller: its shaft-rate line (1 × the rotor speed) comes out
    /// `shaft_line_boost_db` louder, its BPF line unchanged (same seed, same phases).
    #[test]
    fn chipped_propeller_raises_its_shaft_line_only() {
        use crate::flight::{FlightLog, FlightSample};
        let profile = DroneProfile::dji_mini_2();
        let sample = |t: f64| FlightSample {
            t_s: t,
            position: nalgebra::Vector3::zeros(),
            velocity: nalgebra::Vector3::zeros(),
            acceleration: nalgebra::Vector3::zeros(),
            attitude: nalgebra::UnitQuaternion::identity(),
            rotor_hz: vec![164.0; 4],
        };
        let log = FlightLog {
            t0_s: 0.0,
            dt_s: 0.01,
            samples: (0..=200).map(|k| sample(k as f64 * 0.01)).collect(),
            rotors: profile.rotors(),
        };
        let fs = 48_000.0;
        // Amplitude of the line at `hz` over exactly 1 s (an integer number of its periods).
        let line = |x: &SourceSignal, hz: f64| {
            let (mut re, mut im) = (0.0, 0.0);
            for (k, v) in x.samples.iter().take(48_000).enumerate() {
                let (s, c) = (std::f64::consts::TAU * hz * k as f64 / fs).sin_cos();
                re += f64::from(*v) * c;
                im += f64::from(*v) * s;
            }
            2.0 * re.hypot(im) / 48_000.0
        };
        let plain = propeller(&profile, 0.0, &log, 0, 0.0, fs, 48_000, 5);
        let chipped = propeller(&profile, 10.0, &log, 0, 0.0, fs, 48_000, 5);
        let shaft = line(&chipped, 164.0) / line(&plain, 164.0);
        let bpf = line(&chipped, 328.0) / line(&plain, 328.0);
        assert!(
            (20.0 * shaft.log10() - 10.0).abs() < 0.3,
            "shaft line +{} dB",
            20.0 * shaft.log10()
        );
        assert!((20.0 * bpf.log10()).abs() < 0.1, "BPF line {} dB", 20.0 * bpf.log10());
    }
}
