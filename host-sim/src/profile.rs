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

    /// The built-in profile called `name` (`dji-mini-2`).
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "dji-mini-2" => Some(Self::dji_mini_2()),
            _ => None,
        }
    }

    /// Names of the built-in profiles.
    pub const PRESETS: &'static [&'static str] = &["dji-mini-2"];

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
}
