//! Drone profiles: airframe, rotors, motors, sound. The preset `dji-mini-2` follows the paper's
//! drone (249 g, two-blade propellers, hover rotor 164 Hz, 77 dB SPL at 1 m).
//!
//! Rotor numbering follows the paper (§III-B): rotors are numbered counter-clockwise seen from
//! above, starting at the front-right one, odd rotors spin counter-clockwise and even rotors
//! clockwise, so the pitch pairs are quad (1 2)(3 4), hexa (1 2)(3 6)(4 5), octo
//! (1 2)(3 8)(4 7)(5 6) and Y6 (3 4 5 6)(1 2); yaw is odd against even. Y6: rotors 1, 2 on the
//! rear arm, 3, 4 front-left, 5, 6 front-right; odd rotors on top.
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Standard gravity, m/s².
pub const GRAVITY_MPS2: f64 = 9.80665;

/// Airframe layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Frame {
    /// Four rotors in an X.
    Quad,
    /// Six rotors, two at the front.
    Hexa,
    /// Eight rotors, two at the front.
    Octo,
    /// Three arms (one rear, two front), a coaxial pair of rotors on each.
    Y6,
}

impl Frame {
    /// Number of rotors.
    pub fn rotor_count(self) -> usize {
        match self {
            Frame::Quad => 4,
            Frame::Hexa | Frame::Y6 => 6,
            Frame::Octo => 8,
        }
    }
}

/// One rotor's place on the airframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorMount {
    /// Hub position in the body frame (x forward, y left, z up), metres.
    pub position_m: Vector3<f64>,
    /// +1 spins counter-clockwise seen from above (reaction torque on the body: clockwise,
    /// negative z), −1 clockwise.
    pub spin: f64,
    /// Thrust efficiency in still air (1; 0.8 for the lower rotor of a coaxial pair, which
    /// works in the upper rotor's wake).
    pub efficiency: f64,
}

/// A drone: everything the flight and the sound models need. Units in the field names.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DroneProfile {
    /// Profile name.
    pub name: String,
    /// Airframe layout.
    pub frame: Frame,
    /// Take-off mass, kg.
    pub mass_kg: f64,
    /// Distance from the centre to each rotor hub, m.
    pub arm_m: f64,
    /// Blades per propeller.
    pub blades: u32,
    /// Rotor speed in hover, Hz (revolutions per second). Sets the thrust coefficient:
    /// `k_v = m g / (N · f_hover²)` (for a Y6, with the coaxial efficiencies).
    pub hover_rotor_hz: f64,
    /// Drag-torque to thrust ratio `k_h / k_v`, m.
    pub torque_to_thrust_m: f64,
    /// Moments of inertia about body x, y, z, kg·m².
    #[serde(deserialize_with = "aim_tracker::config::exactly")]
    pub inertia_kgm2: [f64; 3],
    /// Quadratic drag coefficients, horizontal and vertical, N·s²/m².
    pub drag_h: f64,
    /// See `drag_h`.
    pub drag_v: f64,
    /// Motor time constant (first-order lag from commanded to actual speed), s.
    pub motor_time_constant_s: f64,
    /// Highest rotor speed the motors reach, Hz.
    pub max_rotor_hz: f64,
    /// Rotor-speed jitter: standard deviation relative to the hover speed (ESC speed-loop error,
    /// an Ornstein–Uhlenbeck process).
    pub rotor_jitter: f64,
    /// Correlation time of the rotor-speed jitter, s.
    pub rotor_jitter_time_s: f64,
    /// Wake loss: thrust lost by a rotor downstream of the others, per m/s of horizontal
    /// airspeed, times how far downstream it sits (`max(0, −d̂ᵢ·v_h)` with d̂ᵢ the unit
    /// direction of its arm). The controller then spins rear rotors faster in forward flight.
    pub wake_loss_per_mps: f64,
    /// Total sound pressure level at 1 m in hover, all rotors, dB re 20 µPa.
    pub spl_1m_db: f64,
    /// Number of BPF harmonics synthesized (the fundamental is harmonic 1).
    pub bpf_harmonics: u32,
    /// Level change per BPF harmonic, dB (harmonic k has `(k−1)·slope` dB relative to the BPF).
    pub harmonic_slope_db: f64,
    /// Level of the shaft-rate lines (harmonics of the rotor speed that are not multiples of the
    /// blade count) relative to the BPF line, dB.
    pub shaft_line_db: f64,
    /// Broadband noise power relative to the total tonal power, dB.
    pub broadband_db: f64,
    /// Sound amplitude grows with rotor speed as `(f / f_hover)^exponent`.
    pub level_exponent: f64,
}

impl DroneProfile {
    /// A DJI-Mini-2-like quadcopter: 249 g, 213 mm diagonal, two-blade propellers, hover rotor
    /// 164 Hz (BPF 328 Hz), 77 dB SPL at 1 m in hover. Inertia, drag and motor constants are
    /// estimates for a drone of this size, not measurements.
    pub fn dji_mini_2() -> Self {
        Self {
            name: "dji-mini-2".into(),
            frame: Frame::Quad,
            mass_kg: 0.249,
            arm_m: 0.1065,
            blades: 2,
            hover_rotor_hz: 164.0,
            torque_to_thrust_m: 0.012,
            inertia_kgm2: [4.0e-4, 4.5e-4, 7.5e-4],
            drag_h: 0.005,
            drag_v: 0.008,
            motor_time_constant_s: 0.03,
            max_rotor_hz: 330.0,
            rotor_jitter: 0.002,
            rotor_jitter_time_s: 0.05,
            wake_loss_per_mps: 0.02,
            spl_1m_db: 77.0,
            bpf_harmonics: 15,
            harmonic_slope_db: -2.5,
            shaft_line_db: -20.0,
            broadband_db: -8.0,
            level_exponent: 2.5,
        }
    }

    /// The built-in profile called `name` (one of [`Self::PRESETS`]).
    pub fn preset(name: &str) -> Option<Self> {
        crate::drones::DroneType::ALL.iter().find(|t| t.name() == name).map(|t| t.profile())
    }

    /// Names of the built-in profiles: the six drone types of [`crate::drones`].
    pub const PRESETS: &'static [&'static str] =
        &["dji-mini-2", "fpv-5in", "camera-quad-1kg", "hexacopter", "toy-70g", "consumer-400g"];

    /// Number of rotors.
    pub fn rotor_count(&self) -> usize {
        self.frame.rotor_count()
    }

    /// Rotor mounts in the paper's numbering (module docs).
    pub fn rotors(&self) -> Vec<RotorMount> {
        let n = self.rotor_count();
        let mount = |deg: f64, z: f64, spin: f64, efficiency: f64| RotorMount {
            position_m: Vector3::new(
                self.arm_m * deg.to_radians().cos(),
                self.arm_m * deg.to_radians().sin(),
                z,
            ),
            spin,
            efficiency,
        };
        let spin = |i: usize| if i.is_multiple_of(2) { 1.0 } else { -1.0 };
        match self.frame {
            Frame::Y6 => {
                // Arms at 180° (rear), 60° (front-left), −60° (front-right); upper rotor first.
                let mut v = Vec::with_capacity(6);
                for arm_deg in [180.0, 60.0, -60.0] {
                    v.push(mount(arm_deg, 0.02, 1.0, 1.0));
                    v.push(mount(arm_deg, -0.02, -1.0, 0.8));
                }
                v
            }
            _ => {
                let step = 360.0 / n as f64;
                (0..n).map(|i| mount(-step / 2.0 + step * i as f64, 0.0, spin(i), 1.0)).collect()
            }
        }
    }

    /// Thrust coefficient `k_v`, N/Hz²: hover thrust equals weight at `hover_rotor_hz`.
    pub fn thrust_coefficient(&self) -> f64 {
        let efficiency: f64 = self.rotors().iter().map(|r| r.efficiency).sum();
        self.mass_kg * GRAVITY_MPS2 / (efficiency * self.hover_rotor_hz * self.hover_rotor_hz)
    }

    /// Checks the numbers are physical; names the first bad field.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("mass_kg", self.mass_kg),
            ("arm_m", self.arm_m),
            ("hover_rotor_hz", self.hover_rotor_hz),
            ("torque_to_thrust_m", self.torque_to_thrust_m),
            ("inertia_kgm2[0]", self.inertia_kgm2[0]),
            ("inertia_kgm2[1]", self.inertia_kgm2[1]),
            ("inertia_kgm2[2]", self.inertia_kgm2[2]),
            ("motor_time_constant_s", self.motor_time_constant_s),
            ("rotor_jitter_time_s", self.rotor_jitter_time_s),
            ("level_exponent", self.level_exponent),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("drone.{name} must be a positive number, got {v}"));
            }
        }
        let non_negative = [
            ("drag_h", self.drag_h),
            ("drag_v", self.drag_v),
            ("rotor_jitter", self.rotor_jitter),
            ("wake_loss_per_mps", self.wake_loss_per_mps),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("drone.{name} must be zero or positive, got {v}"));
            }
        }
        if self.blades == 0 || self.bpf_harmonics == 0 {
            return Err("drone.blades and drone.bpf_harmonics must be at least 1".into());
        }
        if self.max_rotor_hz.is_nan() || self.max_rotor_hz <= 1.2 * self.hover_rotor_hz {
            return Err(format!(
                "drone.max_rotor_hz ({}) must exceed 1.2 × hover_rotor_hz ({}) to leave room to climb",
                self.max_rotor_hz, self.hover_rotor_hz
            ));
        }
        for (name, v) in [
            ("spl_1m_db", self.spl_1m_db),
            ("harmonic_slope_db", self.harmonic_slope_db),
            ("shaft_line_db", self.shaft_line_db),
            ("broadband_db", self.broadband_db),
        ] {
            if !v.is_finite() {
                return Err(format!("drone.{name} must be a finite number"));
            }
        }
        Ok(())
    }
}

/// The spread of a drone population: how far one run's airframe strays from its profile. Each
/// run draws its [`Airframe`] from this, seeded ([`Population::draw`]); all spreads 0 (the
/// [`Default`]) is the nominal airframe, exactly the profile. Scenario table `[airframe]`.
///
/// Distributions (all uniform, independent):
/// - wake gain `g ∈ [1 − wake_spread, 1 + wake_spread]` and curvature
///   `q ∈ [−wake_curvature_per_mps, +wake_curvature_per_mps]`: a rotor `d` m/s downstream loses
///   `κ g d (1 + q d)` of its thrust (κ the profile's `wake_loss_per_mps`), so the loss is
///   non-linear in airspeed and its slope differs from the profile's by up to ±`wake_spread`;
/// - centre-of-gravity offset: uniform in a disc of radius `cg_offset_m` in the body x–y
///   plane. The controller's mixer assumes the nominal centre, so in hover its rate integrator
///   settles on a static front/rear and left/right rotor-speed imbalance;
/// - thrust coefficient of each motor/propeller: `k_v (1 + δᵢ)`, `δᵢ ∈ ±thrust_spread`
///   (a further static imbalance the controller trims out);
/// - rotor-speed jitter of each rotor: the profile's `rotor_jitter` times
///   `∈ [1 − jitter_spread, 1 + jitter_spread]`;
/// - with probability `chipped_probability` one rotor (uniform) has a chipped propeller: its
///   thrust coefficient is `chipped_thrust_loss` lower and its shaft-rate lines (the
///   imbalance tones) `chipped_line_db` louder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Population {
    /// Relative spread of the wake loss slope (0.3: ±30 %).
    pub wake_spread: f64,
    /// Spread of the wake loss curvature, per m/s.
    pub wake_curvature_per_mps: f64,
    /// Largest centre-of-gravity offset from the rotor centre, m.
    pub cg_offset_m: f64,
    /// Relative spread of each motor's thrust coefficient (0.03: ±3 %).
    pub thrust_spread: f64,
    /// Relative spread of each rotor's speed jitter.
    pub jitter_spread: f64,
    /// Probability that one propeller is chipped, 0..=1.
    pub chipped_probability: f64,
    /// Thrust coefficient lost by a chipped propeller, fraction.
    pub chipped_thrust_loss: f64,
    /// Extra level of a chipped propeller's shaft-rate lines, dB.
    pub chipped_line_db: f64,
}

impl Default for Population {
    /// The nominal airframe: no spread.
    fn default() -> Self {
        Self {
            wake_spread: 0.0,
            wake_curvature_per_mps: 0.0,
            cg_offset_m: 0.0,
            thrust_spread: 0.0,
            jitter_spread: 0.0,
            chipped_probability: 0.0,
            chipped_thrust_loss: 0.03,
            chipped_line_db: 10.0,
        }
    }
}

impl Population {
    /// Checks the spreads; names the first bad key of the scenario's `[airframe]` table.
    pub fn validate(&self) -> Result<(), String> {
        let within = [
            ("wake_spread", self.wake_spread, 0.9),
            ("wake_curvature_per_mps", self.wake_curvature_per_mps, 0.5),
            ("cg_offset_m", self.cg_offset_m, 0.05),
            ("thrust_spread", self.thrust_spread, 0.3),
            ("jitter_spread", self.jitter_spread, 1.0),
            ("chipped_probability", self.chipped_probability, 1.0),
            ("chipped_thrust_loss", self.chipped_thrust_loss, 0.5),
            ("chipped_line_db", self.chipped_line_db, 40.0),
        ];
        for (name, v, max) in within {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(format!("airframe.{name} must be in 0..={max}, got {v}"));
            }
        }
        Ok(())
    }

    /// Draws one airframe for a drone of `rotors` rotors from `seed`. With every spread 0 the
    /// result is [`Airframe::nominal`] whatever the seed.
    pub fn draw(&self, rotors: usize, seed: u64) -> Airframe {
        use rand::{rngs::StdRng, Rng, SeedableRng};
        let mut rng = StdRng::seed_from_u64(seed);
        // Every draw is taken whatever the spreads, so one spread does not shift the others.
        let mut sym = |spread: f64| spread * (2.0 * rng.random::<f64>() - 1.0);
        let wake_gain = 1.0 + sym(self.wake_spread);
        let wake_curvature_per_mps = sym(self.wake_curvature_per_mps);
        let thrust_factor: Vec<f64> = (0..rotors).map(|_| 1.0 + sym(self.thrust_spread)).collect();
        let jitter_factor: Vec<f64> = (0..rotors).map(|_| 1.0 + sym(self.jitter_spread)).collect();
        // Uniform in the disc: radius √u, angle uniform.
        let (u, a): (f64, f64) = (rng.random(), rng.random());
        let r = self.cg_offset_m * u.sqrt();
        let (s, c) = (std::f64::consts::TAU * a).sin_cos();
        let cg_offset_m = if r > 0.0 { [r * c, r * s] } else { [0.0, 0.0] };
        let (chip, which): (f64, f64) = (rng.random(), rng.random());
        let chipped_rotor = (chip < self.chipped_probability)
            .then(|| ((which * rotors as f64) as usize).min(rotors.saturating_sub(1)));
        let mut airframe = Airframe {
            wake_gain,
            wake_curvature_per_mps,
            cg_offset_m,
            thrust_factor,
            jitter_factor,
            chipped_rotor,
            shaft_line_boost_db: vec![0.0; rotors],
        };
        if let Some(i) = chipped_rotor {
            airframe.thrust_factor[i] *= 1.0 - self.chipped_thrust_loss;
            airframe.shaft_line_boost_db[i] = self.chipped_line_db;
        }
        airframe
    }
}

/// One drone as built: how this airframe differs from its profile (drawn from a
/// [`Population`]). Simulation truth only: written to the truth file, never to the site file
/// or a tracker profile.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Airframe {
    /// Wake loss slope relative to the profile's `wake_loss_per_mps`.
    pub wake_gain: f64,
    /// Wake loss curvature q, per m/s: loss `κ g d (1 + q d)`.
    pub wake_curvature_per_mps: f64,
    /// Centre of gravity in the body frame (x forward, y left) relative to the rotors' centre, m.
    pub cg_offset_m: [f64; 2],
    /// Each rotor's thrust coefficient relative to the profile's (a chipped propeller's loss
    /// included).
    pub thrust_factor: Vec<f64>,
    /// Each rotor's speed jitter relative to the profile's `rotor_jitter`.
    pub jitter_factor: Vec<f64>,
    /// Index of the rotor with a chipped propeller, if any (0-based, paper order).
    pub chipped_rotor: Option<usize>,
    /// Extra level of each rotor's shaft-rate lines, dB (nonzero on a chipped propeller).
    pub shaft_line_boost_db: Vec<f64>,
}

impl Airframe {
    /// The profile's own airframe, `rotors` rotors.
    pub fn nominal(rotors: usize) -> Self {
        Population::default().draw(rotors, 0)
    }

    /// Thrust factor of a rotor `downstream_mps` m/s downstream of the others (≥ 0) for a
    /// profile wake loss `kappa_per_mps`: `1 − κ g d (1 + q d)`, kept within [0.5, 1].
    pub fn wake_factor(&self, kappa_per_mps: f64, downstream_mps: f64) -> f64 {
        let d = downstream_mps;
        let loss = kappa_per_mps * self.wake_gain * d * (1.0 + self.wake_curvature_per_mps * d);
        (1.0 - loss).clamp(0.5, 1.0)
    }

    /// The airframe as a TOML table (for the truth file).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mini_2_hovers_at_164_hz() {
        let p = DroneProfile::dji_mini_2();
        let kv = p.thrust_coefficient();
        let thrust = 4.0 * kv * 164.0 * 164.0;
        assert!((thrust - 0.249 * GRAVITY_MPS2).abs() < 1e-9);
        assert!(p.validate().is_ok());
    }

    #[test]
    fn rotor_pairs_follow_the_paper() {
        for frame in [Frame::Quad, Frame::Hexa, Frame::Octo] {
            let p = DroneProfile { frame, ..DroneProfile::dji_mini_2() };
            let r = p.rotors();
            // Rotor 1 front-right, rotor 2 front-left, mirror images across the x axis.
            assert!(r[0].position_m.x > 0.0 && r[0].position_m.y < 0.0);
            assert!((r[0].position_m.x - r[1].position_m.x).abs() < 1e-12);
            assert!((r[0].position_m.y + r[1].position_m.y).abs() < 1e-12);
            // Odd rotors (index 0, 2, ..) spin one way, even ones the other: no net yaw torque.
            assert_eq!(r.iter().map(|m| m.spin).sum::<f64>(), 0.0);
        }
    }
    #[test]
    fn nominal_population_draws_the_profile_whatever_the_seed() {
        for seed in [0, 1, 99] {
            let a = Population::default().draw(4, seed);
            assert_eq!(a, Airframe::nominal(4));
            assert_eq!(a.thrust_factor, vec![1.0; 4]);
            assert_eq!(a.cg_offset_m, [0.0, 0.0]);
            assert_eq!(a.chipped_rotor, None);
            // The nominal wake factor is the profile's law 1 − κ d, bit for bit.
            for d in [0.0, 0.7, 1.5, 3.0] {
                assert_eq!(a.wake_factor(0.02, d), (1.0 - 0.02 * d).max(0.5));
            }
        }
    }

    #[test]
    fn drawn_airframes_stay_in_their_stated_bounds_and_fill_them() {
        let pop = Population {
            wake_spread: 0.3,
            wake_curvature_per_mps: 0.1,
            cg_offset_m: 0.004,
            thrust_spread: 0.03,
            jitter_spread: 0.5,
            chipped_probability: 0.25,
            ..Population::default()
        };
        pop.validate().unwrap();
        let draws: Vec<Airframe> = (0..2000).map(|s| pop.draw(4, s)).collect();
        let gains: Vec<f64> = draws.iter().map(|a| a.wake_gain).collect();
        let (lo, hi) = gains.iter().fold((f64::MAX, f64::MIN), |(l, h), &g| (l.min(g), h.max(g)));
        assert!(lo >= 0.7 && hi <= 1.3 && lo < 0.72 && hi > 1.28, "{lo} {hi}");
        let mean = gains.iter().sum::<f64>() / gains.len() as f64;
        assert!((mean - 1.0).abs() < 0.02, "{mean}");
        let chipped = draws.iter().filter(|a| a.chipped_rotor.is_some()).count() as f64 / 2000.0;
        assert!((chipped - 0.25).abs() < 0.04, "{chipped}");
        for a in &draws {
            assert!(a.wake_curvature_per_mps.abs() <= 0.1);
            assert!(a.cg_offset_m[0].hypot(a.cg_offset_m[1]) <= 0.004 + 1e-15);
            for (i, f) in a.thrust_factor.iter().enumerate() {
                let chip = if a.chipped_rotor == Some(i) { 0.97 } else { 1.0 };
                assert!((f / chip - 1.0).abs() <= 0.03 + 1e-12, "{f}");
            }
            assert!(a.jitter_factor.iter().all(|j| (0.5..=1.5).contains(j)));
        }
        // The same seed draws the same airframe; another seed another one.
        assert_eq!(pop.draw(4, 7), pop.draw(4, 7));
        assert_ne!(pop.draw(4, 7), pop.draw(4, 8));
        // The CG offset fills the disc uniformly: half the draws within r/√2.
        let inner = draws
            .iter()
            .filter(|a| a.cg_offset_m[0].hypot(a.cg_offset_m[1]) < 0.004 / 2f64.sqrt())
            .count() as f64
            / 2000.0;
        assert!((inner - 0.5).abs() < 0.04, "{inner}");
        let bad = Population { thrust_spread: -0.1, ..pop };
        assert!(bad.validate().unwrap_err().contains("airframe.thrust_spread"));
    }
}
