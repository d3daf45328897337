//! Drone types for identification (issue 16): six multirotors with published-spec-like
//! airframes, each a population from which every clip draws its own airframe, and the sound
//! of one drawn drone at 1 m while it manoeuvres.
//!
//! The types (hover rotor speeds are estimates from mass, propeller size and blade count, not
//! measurements; levels are typical of the class):
//!
//! | name | frame | mass | blades | hover rotor | BPF | SPL at 1 m |
//! |---|---|---|---|---|---|---|
//! | `dji-mini-2` | quad | 249 g | 2 | 164 Hz | 328 Hz | 77 dB (the paper's drone) |
//! | `fpv-5in` | quad, 5.1" props | 650 g | 3 | 185 Hz | 555 Hz | 84 dB |
//! | `camera-quad-1kg` | quad, 9" props | 1.0 kg | 3 | 95 Hz | 285 Hz | 80 dB |
//! | `hexacopter` | hexa, 10" props | 2.4 kg | 2 | 78 Hz | 156 Hz | 83 dB |
//! | `toy-70g` | quad, 3" props | 70 g | 2 | 380 Hz | 760 Hz | 68 dB |
//! | `consumer-400g` | quad, 6" props | 400 g | 2 | 132 Hz | 264 Hz | 76 dB |
//!
//! The sound is [`crate::sound::Propeller`]'s (BPF harmonics, shaft-rate lines, modulated
//! broadband) driven by a synthetic flight log of rotor speeds, so the identification data use
//! the same propeller model as the tracking scenarios. Per clip ([`Draw`]):
//! - airframe: mass ±10 % (hover rotor speed ∝ √mass at a fixed thrust coefficient), propeller
//!   spread of the hover speed ±5 %, harmonic slope ±0.6 dB per harmonic, shaft-rate lines
//!   ±4 dB, broadband ±2 dB, each rotor's speed ±3 % off the others (trim, thrust spread),
//!   and with probability 0.1 a chipped propeller (shaft lines +10 dB on one rotor);
//! - manoeuvre: the rotor speeds move smoothly (raised cosine) from one factor to another,
//!   both uniform in 1 ± 0.3, plus each rotor's Ornstein–Uhlenbeck jitter (the profile's);
//! - Doppler of cruise: a constant radial speed uniform in ±`cruise_mps` scales every
//!   frequency by `c / (c − v_r)` (the clip is short: the range change is not modelled).
use nalgebra::{UnitQuaternion, Vector3};
use rand::{rngs::StdRng, Rng, SeedableRng};

use crate::flight::{FlightLog, FlightSample};
use crate::profile::{DroneProfile, Frame};
use crate::sound::{Propeller, SignalBlocks};
use crate::tonal::Ou;

/// Speed of sound used for the Doppler factor, m/s.
pub const SOUND_SPEED_MPS: f64 = 343.0;
/// Largest relative change of the rotor speeds in a manoeuvre (0.3: ±30 %).
pub const MANOEUVRE: f64 = 0.3;

/// The six drone types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DroneType {
    /// DJI Mini 2: 249 g, two-blade.
    Mini2,
    /// 5-inch FPV racing quad: 650 g, three-blade, high BPF.
    Fpv5,
    /// ~1 kg camera quad with three-blade propellers.
    CameraQuad,
    /// ~2.4 kg hexacopter, two-blade.
    Hexa,
    /// ~70 g toy quad.
    Toy,
    /// ~400 g consumer quad, two-blade.
    Consumer,
}

impl DroneType {
    /// All types, in class order.
    pub const ALL: [DroneType; 6] = [
        DroneType::Mini2,
        DroneType::Fpv5,
        DroneType::CameraQuad,
        DroneType::Hexa,
        DroneType::Toy,
        DroneType::Consumer,
    ];

    /// Class name (the dataset folder).
    pub fn name(self) -> &'static str {
        match self {
            DroneType::Mini2 => "dji-mini-2",
            DroneType::Fpv5 => "fpv-5in",
            DroneType::CameraQuad => "camera-quad-1kg",
            DroneType::Hexa => "hexacopter",
            DroneType::Toy => "toy-70g",
            DroneType::Consumer => "consumer-400g",
        }
    }

    /// Highest cruise speed of the type, m/s (the Doppler's radial-speed bound).
    pub fn cruise_mps(self) -> f64 {
        match self {
            DroneType::Fpv5 => 15.0,
            DroneType::Toy => 3.0,
            DroneType::Hexa => 8.0,
            _ => 10.0,
        }
    }

    /// The type's nominal profile.
    pub fn profile(self) -> DroneProfile {
        let base = DroneProfile::dji_mini_2();
        let p =
            |name: &str,
             frame: Frame,
             mass_kg: f64,
             arm_m: f64,
             blades: u32,
             hover_rotor_hz: f64,
             spl_1m_db: f64,
             (harmonic_slope_db, shaft_line_db, broadband_db): (f64, f64, f64)| {
                // Flight constants scaled from the Mini 2's by size (estimates, like the
                // Mini 2's own): inertia ∝ m·arm², drag ∝ arm² (frontal area), drag torque
                // ∝ arm (propeller radius), motor lag ∝ √arm (heavier propellers).
                let size = arm_m / base.arm_m;
                let inertia = mass_kg / base.mass_kg * size * size;
                DroneProfile {
                    name: name.into(),
                    frame,
                    mass_kg,
                    arm_m,
                    blades,
                    hover_rotor_hz,
                    max_rotor_hz: 2.0 * hover_rotor_hz,
                    torque_to_thrust_m: base.torque_to_thrust_m * size,
                    inertia_kgm2: base.inertia_kgm2.map(|i| i * inertia),
                    drag_h: base.drag_h * size * size,
                    drag_v: base.drag_v * size * size,
                    motor_time_constant_s: base.motor_time_constant_s * size.sqrt(),
                    spl_1m_db,
                    harmonic_slope_db,
                    shaft_line_db,
                    broadband_db,
                    bpf_harmonics: 12,
                    ..base.clone()
                }
            };
        match self {
            DroneType::Mini2 => base,
            DroneType::Fpv5 => {
                p("fpv-5in", Frame::Quad, 0.65, 0.11, 3, 185.0, 84.0, (-2.0, -18.0, -5.0))
            }
            DroneType::CameraQuad => {
                p("camera-quad-1kg", Frame::Quad, 1.0, 0.18, 3, 95.0, 80.0, (-3.0, -17.0, -8.0))
            }
            DroneType::Hexa => {
                p("hexacopter", Frame::Hexa, 2.4, 0.28, 2, 78.0, 83.0, (-2.0, -22.0, -10.0))
            }
            DroneType::Toy => {
                p("toy-70g", Frame::Quad, 0.07, 0.05, 2, 380.0, 68.0, (-4.0, -15.0, -4.0))
            }
            DroneType::Consumer => {
                p("consumer-400g", Frame::Quad, 0.4, 0.12, 2, 132.0, 76.0, (-4.0, -14.0, -6.0))
            }
        }
    }
}

/// One drone drawn from its type's population, with its manoeuvre and Doppler (module docs).
#[derive(Clone, Debug)]
pub struct Draw {
    /// The drawn profile (hover speed, levels as built).
    pub profile: DroneProfile,
    /// Each rotor's speed relative to the drawn hover speed.
    pub rotor_factor: Vec<f64>,
    /// Each rotor's extra shaft-line level, dB.
    pub shaft_boost_db: Vec<f64>,
    /// Manoeuvre factor at the start and the end of the clip.
    pub manoeuvre: (f64, f64),
    /// Radial speed towards the listener, m/s (positive approaching).
    pub radial_mps: f64,
}

impl Draw {
    /// Draws a drone of `ty` from `seed`.
    pub fn new(ty: DroneType, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut sym = |spread: f64| spread * (2.0 * rng.random::<f64>() - 1.0);
        let mut profile = ty.profile();
        let mass = 1.0 + sym(0.10);
        profile.mass_kg *= mass;
        profile.hover_rotor_hz *= mass.sqrt() * (1.0 + sym(0.05));
        profile.max_rotor_hz = 2.0 * profile.hover_rotor_hz;
        profile.harmonic_slope_db += sym(0.6);
        profile.shaft_line_db += sym(4.0);
        profile.broadband_db += sym(2.0);
        let n = profile.rotor_count();
        let rotor_factor: Vec<f64> = (0..n).map(|_| 1.0 + sym(0.03)).collect();
        let manoeuvre = (1.0 + sym(MANOEUVRE), 1.0 + sym(MANOEUVRE));
        let radial_mps = sym(ty.cruise_mps());
        let (chip, which) = (sym(1.0), sym(1.0));
        let mut shaft_boost_db = vec![0.0; n];
        if chip > 0.8 {
            let i = (((which + 1.0) / 2.0 * n as f64) as usize).min(n - 1);
            shaft_boost_db[i] = 10.0;
        }
        Self { profile, rotor_factor, shaft_boost_db, manoeuvre, radial_mps }
    }

    /// The drone's sound at 1 m (Pa), `len` samples at `fs`, all rotors summed.
    pub fn sound(&self, fs: f64, len: usize, seed: u64) -> Vec<f64> {
        let secs = len as f64 / fs;
        let dt = 0.01;
        let steps = (secs / dt).ceil() as usize + 2;
        let doppler = SOUND_SPEED_MPS / (SOUND_SPEED_MPS - self.radial_mps);
        let n = self.profile.rotor_count();
        let mut jitter: Vec<Ou> = (0..n)
            .map(|i| {
                let s = seed.wrapping_mul(31).wrapping_add(i as u64 + 1);
                Ou::new(self.profile.rotor_jitter, self.profile.rotor_jitter_time_s, 1.0 / dt, s)
            })
            .collect();
        let (a, b) = self.manoeuvre;
        let samples = (0..steps)
            .map(|k| {
                let t = k as f64 * dt;
                let u = (t / secs).min(1.0);
                let m = a + (b - a) * 0.5 * (1.0 - (std::f64::consts::PI * u).cos());
                FlightSample {
                    t_s: t,
                    position: Vector3::zeros(),
                    velocity: Vector3::zeros(),
                    acceleration: Vector3::zeros(),
                    attitude: UnitQuaternion::identity(),
                    rotor_hz: (0..n)
                        .map(|i| {
                            self.profile.hover_rotor_hz
                                * self.rotor_factor[i]
                                * m
                                * doppler
                                * (1.0 + jitter[i].step())
                        })
                        .collect(),
                }
            })
            .collect();
        let log = FlightLog { t0_s: 0.0, dt_s: dt, samples, rotors: self.profile.rotors() };
        let mut out = vec![0.0f64; len];
        let mut buf = vec![0.0f32; len];
        for i in 0..n {
            let s = seed.wrapping_mul(1_000_003).wrapping_add(i as u64 + 7);
            let mut g =
                Propeller::new(&self.profile, self.shaft_boost_db[i], &log, i, 0.0, fs, len, s);
            g.fill(&mut buf);
            for (o, v) in out.iter_mut().zip(&buf) {
                *o += f64::from(*v);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sound::{rms_pa_to_spl, spl_to_rms_pa};

    #[test]
    fn profiles_are_valid_and_bpf_as_tabled() {
        let bpf = [328.0, 555.0, 285.0, 156.0, 760.0, 264.0];
        for (ty, want) in DroneType::ALL.iter().zip(bpf) {
            let p = ty.profile();
            p.validate().unwrap();
            assert_eq!(p.hover_rotor_hz * f64::from(p.blades), want, "{}", ty.name());
        }
    }

    /// A hovering drone (no manoeuvre, no Doppler) is at its SPL at 1 m, and its strongest
    /// line is its BPF.
    #[test]
    fn hover_sound_has_its_level_and_bpf() {
        for ty in [DroneType::Mini2, DroneType::CameraQuad, DroneType::Hexa] {
            let mut d = Draw::new(ty, 3);
            d.manoeuvre = (1.0, 1.0);
            d.radial_mps = 0.0;
            d.shaft_boost_db.iter_mut().for_each(|b| *b = 0.0);
            let fs = 16_000.0;
            let x = d.sound(fs, 16_000, 9);
            let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
            // Rotor speeds ±3 % off hover change the level by (1.03)^2.5: ±0.4 dB.
            let spl = rms_pa_to_spl(rms);
            assert!((spl - d.profile.spl_1m_db).abs() < 0.6, "{} {spl}", ty.name());
            assert!(rms > spl_to_rms_pa(60.0));
            let bpf = d.profile.hover_rotor_hz * f64::from(d.profile.blades);
            let line = |hz: f64| {
                let (mut re, mut im) = (0.0, 0.0);
                for (k, v) in x.iter().enumerate() {
                    let (s, c) = (std::f64::consts::TAU * hz * k as f64 / fs).sin_cos();
                    re += v * c;
                    im += v * s;
                }
                re.hypot(im)
            };
            // Per-rotor spread smears the line over ±3 %: take the best of a few bins.
            let at =
                |f: f64| (-6..=6).map(|j| line(f * (1.0 + 0.005 * j as f64))).fold(0.0, f64::max);
            assert!(at(bpf) > 3.0 * at(bpf * 0.75), "{}", ty.name());
            assert!(at(bpf) > 3.0 * at(bpf * 1.5), "{}", ty.name());
        }
    }

    /// The strongest line near the BPF moves with the manoeuvre factor and the Doppler factor
    /// (within the ±3 % spread of the rotors' speeds).
    #[test]
    fn doppler_and_manoeuvre_scale_the_bpf() {
        let fs = 16_000.0;
        let peak = |x: &[f64], lo: f64, hi: f64| {
            let mut best = (0.0, 0.0);
            let mut f = lo;
            while f < hi {
                let (mut re, mut im) = (0.0, 0.0);
                for (k, v) in x.iter().enumerate() {
                    let (s, c) = (std::f64::consts::TAU * f * k as f64 / fs).sin_cos();
                    re += v * c;
                    im += v * s;
                }
                if re.hypot(im) > best.1 {
                    best = (f, re.hypot(im));
                }
                f += 2.0;
            }
            best.0
        };
        for (m, v) in [(1.0, 0.0), (1.25, 0.0), (0.75, 10.0), (1.25, -10.0)] {
            let mut d = Draw::new(DroneType::Fpv5, 1);
            d.manoeuvre = (m, m);
            d.radial_mps = v;
            let bpf = d.profile.hover_rotor_hz * 3.0;
            let x = d.sound(fs, 8_000, 2);
            let want = bpf * m * SOUND_SPEED_MPS / (SOUND_SPEED_MPS - v);
            let got = peak(&x, 0.6 * bpf, 1.4 * bpf);
            assert!((got / want - 1.0).abs() < 0.04, "m {m} v {v}: {got} Hz, want {want}");
        }
    }
}
