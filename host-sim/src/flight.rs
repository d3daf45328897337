//! Multirotor flight by rigid-body physics.
//!
//! The airframe is a rigid body (mass, diagonal inertia) pushed by its rotors: rotor i gives
//! thrust `Tᵢ = k_v εᵢ wᵢ fᵢ²` along body z at its hub and a reaction torque `−sᵢ k_h fᵢ²` about
//! body z (εᵢ: coaxial efficiency, wᵢ: wake factor, sᵢ: spin). Quadratic body drag, gravity.
//! A cascaded controller (position P → velocity PI → thrust vector and attitude on SO(3) →
//! body-rate PI → mixer) follows the flight plan; the mixer turns thrust and torques into rotor
//! speeds, the motors follow with a first-order lag, and an Ornstein–Uhlenbeck jitter stands for
//! the ESC's imperfect speed loop. Rotor speeds are whatever this loop makes them: nothing here
//! uses the tracker's simplified equations.
//!
//! Wake model (stated, not measured): in horizontal flight at airspeed v_h (body frame), a rotor
//! whose arm points downstream by `d = max(0, −d̂ᵢ · v_h)` loses thrust,
//! `wᵢ = 1 − κ g d (1 + q d)`, κ = `wake_loss_per_mps`, g and q the airframe's wake gain and
//! curvature ([`Airframe`]; nominal g = 1, q = 0). The controller does not know this; its rate
//! integrator finds the rear rotors' extra speed, which grows with flight speed as the paper
//! observes (§VII-C).
//!
//! The airframe as built ([`Airframe`], drawn from a population) differs from the profile the
//! controller's mixer assumes: its centre of gravity is offset, each motor's thrust coefficient
//! is its own (a chipped propeller's lower), each rotor jitters by its own amount. The rate and
//! velocity integrators trim these out, which leaves static rotor-speed imbalances in hover.
use nalgebra::{DMatrix, Matrix3, UnitQuaternion, Vector3};
use rand::{rngs::StdRng, Rng, SeedableRng};

use crate::path::FlightPlan;
use crate::profile::{Airframe, DroneProfile, RotorMount, GRAVITY_MPS2};

/// Controller and integrator settings. Gains are in units of the closed-loop bandwidth (1/s) so
/// they suit any airframe size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlGains {
    /// Position error to velocity command, 1/s.
    pub position: f64,
    /// Velocity error to acceleration command, 1/s.
    pub velocity: f64,
    /// Velocity error integral gain, 1/s².
    pub velocity_integral: f64,
    /// Attitude error to rate command, roll/pitch, 1/s.
    pub attitude: f64,
    /// Attitude error to rate command, yaw, 1/s.
    pub yaw: f64,
    /// Rate error to angular acceleration, 1/s.
    pub rate: f64,
    /// Rate error integral to angular acceleration, 1/s².
    pub rate_integral: f64,
    /// Largest tilt the controller commands, rad.
    pub max_tilt_rad: f64,
}

impl Default for ControlGains {
    fn default() -> Self {
        Self {
            position: 1.0,
            velocity: 2.5,
            velocity_integral: 0.5,
            attitude: 8.0,
            yaw: 3.0,
            rate: 25.0,
            rate_integral: 40.0,
            max_tilt_rad: 30f64.to_radians(),
        }
    }
}

/// State of the flight at one control step.
#[derive(Clone, Debug, PartialEq)]
pub struct FlightSample {
    /// Time, s (scenario time; negative before the scenario starts).
    pub t_s: f64,
    /// Centre-of-mass position, ENU m.
    pub position: Vector3<f64>,
    /// Velocity, m/s.
    pub velocity: Vector3<f64>,
    /// Acceleration (specific force plus gravity, i.e. d²p/dt²), m/s².
    pub acceleration: Vector3<f64>,
    /// Attitude, body (x forward, y left, z up) to ENU.
    pub attitude: UnitQuaternion<f64>,
    /// Rotor speeds, Hz (revolutions per second), jitter included.
    pub rotor_hz: Vec<f64>,
}

impl FlightSample {
    /// Heading: angle of the body x axis from ENU +x towards +y, rad.
    pub fn yaw_rad(&self) -> f64 {
        self.attitude.euler_angles().2
    }
}

/// A flown trajectory at a fixed step.
#[derive(Clone, Debug)]
pub struct FlightLog {
    /// Time of the first sample, s.
    pub t0_s: f64,
    /// Step between samples, s.
    pub dt_s: f64,
    /// The samples.
    pub samples: Vec<FlightSample>,
    /// Rotor mounts (body frame), in rotor order.
    pub rotors: Vec<RotorMount>,
}

impl FlightLog {
    /// Index and fraction of time `t_s` between samples (clamped to the log).
    pub fn locate(&self, t_s: f64) -> (usize, f64) {
        let x = (t_s - self.t0_s) / self.dt_s;
        let last = self.samples.len() - 1;
        if x <= 0.0 {
            return (0, 0.0);
        }
        let i = x.floor() as usize;
        if i >= last {
            return (last.saturating_sub(1), if last == 0 { 0.0 } else { 1.0 });
        }
        (i, x - i as f64)
    }

    /// World position of rotor `rotor`'s hub at time `t_s`, linearly interpolated, ENU m.
    pub fn rotor_position(&self, rotor: usize, t_s: f64) -> Vector3<f64> {
        let (i, f) = self.locate(t_s);
        let at = |s: &FlightSample| s.position + s.attitude * self.rotors[rotor].position_m;
        let a = at(&self.samples[i]);
        if f == 0.0 || i + 1 >= self.samples.len() {
            return a;
        }
        a + (at(&self.samples[i + 1]) - a) * f
    }

    /// Centre-of-mass position at time `t_s`, linearly interpolated, ENU m.
    pub fn position(&self, t_s: f64) -> Vector3<f64> {
        let (i, f) = self.locate(t_s);
        let a = self.samples[i].position;
        if i + 1 >= self.samples.len() {
            return a;
        }
        a + (self.samples[i + 1].position - a) * f
    }

    /// Speed of rotor `rotor` at time `t_s`, linearly interpolated, Hz.
    pub fn rotor_hz(&self, rotor: usize, t_s: f64) -> f64 {
        let (i, f) = self.locate(t_s);
        let a = self.samples[i].rotor_hz[rotor];
        if i + 1 >= self.samples.len() {
            return a;
        }
        a + (self.samples[i + 1].rotor_hz[rotor] - a) * f
    }
}

/// Time span and step of a flight simulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// First time, s.
    pub t0_s: f64,
    /// Last time (at least), s.
    pub t1_s: f64,
    /// Controller step and log interval, s (physics integrates at a quarter of it).
    pub dt_s: f64,
}

/// Flies `plan` with `profile` over `span`. The drone starts hovering at the plan's position at
/// `span.t0_s` with heading `yaw_rad`, which it holds, unless the plan flies nose-first
/// ([`FlightPlan::heading_at`]): then it follows the plan's heading, with the reference yaw
/// rate and acceleration fed forward to the rate loop, so a turn's torque comes from the
/// mixer's odd/even rotor-speed split (reaction torque `k_h f²`). `seed` seeds the rotor-speed
/// jitter. `airframe` is the drone as built; a non-nominal one first hovers
/// [`SETTLE_S`] (unlogged) so its integrators have trimmed its imbalances before `span.t0_s`.
/// The log's rotor mounts are relative to the true centre of mass.
#[allow(clippy::too_many_arguments)] // the flight's inputs, each its own thing
pub fn fly(
    profile: &DroneProfile,
    airframe: &Airframe,
    plan: &FlightPlan,
    yaw_rad: f64,
    gains: &ControlGains,
    span: Span,
    seed: u64,
) -> FlightLog {
    let Span { t0_s, t1_s, dt_s } = span;
    const SUBSTEPS: usize = 4;
    let rotors = profile.rotors();
    let n = rotors.len();
    assert_eq!(airframe.thrust_factor.len(), n, "airframe drawn for another rotor count");
    // The mounts as built: hubs relative to the true centre of mass.
    let cg = Vector3::new(airframe.cg_offset_m[0], airframe.cg_offset_m[1], 0.0);
    let built: Vec<RotorMount> =
        rotors.iter().map(|r| RotorMount { position_m: r.position_m - cg, ..*r }).collect();
    let settle_steps =
        if *airframe == Airframe::nominal(n) { 0 } else { (SETTLE_S / dt_s).round() as usize };
    let m = profile.mass_kg;
    let kv = profile.thrust_coefficient();
    let kh = kv * profile.torque_to_thrust_m;
    let inertia = Matrix3::from_diagonal(&Vector3::from(profile.inertia_kgm2));
    let inertia_inv = inertia.try_inverse().expect("positive inertia");
    let g = Vector3::new(0.0, 0.0, GRAVITY_MPS2);

    // Allocation: [ΣT, τx, τy, τz]ᵀ = B·T. The controller's model knows coaxial efficiency (it
    // is a property of the airframe) but not the wake.
    let mut b = DMatrix::<f64>::zeros(4, n);
    for (i, r) in rotors.iter().enumerate() {
        b[(0, i)] = 1.0;
        b[(1, i)] = r.position_m.y;
        b[(2, i)] = -r.position_m.x;
        b[(3, i)] = -r.spin * profile.torque_to_thrust_m;
    }
    let mixer = b.clone().pseudo_inverse(1e-12).expect("allocation matrix has full rank");

    let mut rng = StdRng::seed_from_u64(seed);
    let gauss = |rng: &mut StdRng| -> f64 {
        // Box–Muller; one value per call keeps the sequence simple and reproducible.
        let u1: f64 = rng.random::<f64>().max(1e-300);
        let u2: f64 = rng.random();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };

    let start = plan.at(t0_s).position;
    let mut p = start;
    let mut v = Vector3::zeros();
    let yaw0 = plan.heading_at(t0_s).map_or(yaw_rad, |h| h.yaw_rad);
    let mut q = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw0);
    let mut w = Vector3::zeros();
    let hover: Vec<f64> =
        rotors.iter().map(|r| (m * GRAVITY_MPS2 / (n as f64 * kv * r.efficiency)).sqrt()).collect();
    let mut motor = hover.clone();
    let mut jitter = vec![0.0; n];
    let mut vel_integral = Vector3::zeros();
    let mut rate_integral = Vector3::zeros();
    let mut accel = Vector3::zeros();

    let steps = ((t1_s - t0_s) / dt_s).ceil() as usize + 1;
    let mut samples = Vec::with_capacity(steps);
    let steps = steps + settle_steps;
    let h = dt_s / SUBSTEPS as f64;
    let jitter_sigma = profile.rotor_jitter * profile.hover_rotor_hz;
    let jitter_decay = (-h / profile.rotor_jitter_time_s).exp();
    let jitter_kick = jitter_sigma * (1.0 - jitter_decay * jitter_decay).sqrt();
    let kicks: Vec<f64> = airframe.jitter_factor.iter().map(|j| jitter_kick * j).collect();
    let max_hz = profile.max_rotor_hz;
    let drag = |v: Vector3<f64>| {
        let vh = Vector3::new(v.x, v.y, 0.0);
        -(vh * vh.norm() * profile.drag_h)
            - Vector3::new(0.0, 0.0, v.z * v.z.abs() * profile.drag_v)
    };

    for k in 0..steps {
        let t = t0_s + (k as f64 - settle_steps as f64) * dt_s;
        if k >= settle_steps {
            let rotor_hz: Vec<f64> =
                motor.iter().zip(&jitter).map(|(f, j)| (f + j).max(0.0)).collect();
            samples.push(FlightSample {
                t_s: t,
                position: p,
                velocity: v,
                acceleration: accel,
                attitude: q,
                rotor_hz,
            });
        }

        // ---- Controller (once per control step) ----
        let r = plan.at(t);
        let v_cmd = r.velocity + (r.position - p) * gains.position;
        let v_err = v_cmd - v;
        vel_integral += v_err * dt_s;
        let vi_max = 2.0 / gains.velocity_integral.max(1e-9);
        vel_integral = vel_integral.map(|x| x.clamp(-vi_max, vi_max));
        let a_cmd =
            r.acceleration + v_err * gains.velocity + vel_integral * gains.velocity_integral;
        // Desired force, drag feed-forward from the airframe model, tilt limited.
        let mut f_des = (a_cmd + g) * m - drag(v);
        f_des.z = f_des.z.max(0.2 * m * GRAVITY_MPS2);
        let horiz = Vector3::new(f_des.x, f_des.y, 0.0);
        let max_h = f_des.z * gains.max_tilt_rad.tan();
        if horiz.norm() > max_h {
            let s = max_h / horiz.norm();
            f_des.x *= s;
            f_des.y *= s;
        }
        let z_des = f_des.normalize();
        let heading = plan.heading_at(t);
        let yaw_c = heading.map_or(yaw_rad, |h| h.yaw_rad);
        let x_c = Vector3::new(yaw_c.cos(), yaw_c.sin(), 0.0);
        let y_des = z_des.cross(&x_c).normalize();
        let x_des = y_des.cross(&z_des);
        let r_des = Matrix3::from_columns(&[x_des, y_des, z_des]);
        let rot = q.to_rotation_matrix().into_inner();
        let thrust_cmd = f_des.dot(&(rot * Vector3::z()));
        // Attitude error on SO(3) (Lee, Leok, McClamroch 2010).
        let e_m = r_des.transpose() * rot - rot.transpose() * r_des;
        let e_r = Vector3::new(e_m[(2, 1)], e_m[(0, 2)], e_m[(1, 0)]) * 0.5;
        let mut w_des =
            -Vector3::new(e_r.x * gains.attitude, e_r.y * gains.attitude, e_r.z * gains.yaw);
        // Feed-forward of a turn: the reference yaw rate and acceleration (about world z) in
        // the body frame. A fixed heading has none (and its arithmetic stays as it was).
        let turn = heading.map(|h| {
            let rt = rot.transpose();
            (rt * Vector3::new(0.0, 0.0, h.rate_rad_s), rt * Vector3::new(0.0, 0.0, h.accel_rad_s2))
        });
        if let Some((rate_ff, _)) = turn {
            w_des += rate_ff;
        }
        let w_err = w_des - w;
        rate_integral += w_err * dt_s;
        rate_integral = rate_integral.map(|x| x.clamp(-2.0, 2.0));
        let mut alpha_cmd = w_err * gains.rate + rate_integral * gains.rate_integral;
        if let Some((_, accel_ff)) = turn {
            alpha_cmd += accel_ff;
        }
        let tau_cmd = inertia * alpha_cmd + w.cross(&(inertia * w));
        let u = nalgebra::DVector::from_vec(vec![thrust_cmd, tau_cmd.x, tau_cmd.y, tau_cmd.z]);
        let thrusts = &mixer * u;
        let command: Vec<f64> = (0..n)
            .map(|i| (thrusts[i].max(0.0) / (kv * rotors[i].efficiency)).sqrt().min(max_hz))
            .collect();

        // ---- Physics ----
        for _ in 0..SUBSTEPS {
            let v_body = q.inverse() * v;
            let mut force_body = 0.0;
            let mut torque = Vector3::zeros();
            for (i, rm) in built.iter().enumerate() {
                motor[i] += (command[i] - motor[i]) * (h / profile.motor_time_constant_s);
                jitter[i] = jitter[i] * jitter_decay + kicks[i] * gauss(&mut rng);
                let f = (motor[i] + jitter[i]).clamp(0.0, max_hz);
                let arm = Vector3::new(rm.position_m.x, rm.position_m.y, 0.0);
                let downstream = if arm.norm() > 0.0 {
                    (-(arm / arm.norm()).dot(&Vector3::new(v_body.x, v_body.y, 0.0))).max(0.0)
                } else {
                    0.0
                };
                let wake = airframe.wake_factor(profile.wake_loss_per_mps, downstream);
                let thrust = kv * rm.efficiency * airframe.thrust_factor[i] * wake * f * f;
                force_body += thrust;
                torque += rm.position_m.cross(&Vector3::new(0.0, 0.0, thrust));
                torque.z -= rm.spin * kh * f * f;
            }
            let force = q * Vector3::new(0.0, 0.0, force_body) + drag(v) - g * m;
            accel = force / m;
            v += accel * h;
            p += v * h;
            let w_dot = inertia_inv * (torque - w.cross(&(inertia * w)));
            w += w_dot * h;
            q *= UnitQuaternion::from_scaled_axis(w * h);
        }
    }
    FlightLog { t0_s, dt_s, samples, rotors: built }
}

/// Unlogged hover before a non-nominal airframe's flight, s: the rate integrator trims its
/// imbalances within about 0.5 s; the velocity loop's slow pole (about 0.19 /s with the
/// default gains) takes its thrust deficit's sag down to about 2 % in 20 s.
pub const SETTLE_S: f64 = 20.0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::{square, FlightPlan, Heading};
    use std::f64::consts::{FRAC_PI_2, PI, TAU};

    fn plan_square() -> FlightPlan {
        FlightPlan::new(
            &square([0.0, 0.0], 5.0, 2.0, false, 1),
            1.5,
            1.0,
            2.0,
            0.5,
            2.0,
            Heading::Fixed,
        )
        .unwrap()
    }

    /// Five seconds of hover at 2 m.
    fn plan_hover() -> FlightPlan {
        FlightPlan::new(&[Vector3::new(0.0, 0.0, 2.0)], 1.0, 1.0, 5.0, 0.0, 0.0, Heading::Fixed)
            .unwrap()
    }

    #[test]
    fn hover_balances_weight_at_164_hz() {
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let plan = plan_hover();
        let log = fly(
            &profile,
            &Airframe::nominal(4),
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: 3.0, dt_s: 1e-3 },
            1,
        );
        let last = log.samples.last().unwrap();
        for f in &last.rotor_hz {
            assert!((f - 164.0).abs() < 0.01, "{f}");
        }
        assert!((last.position - Vector3::new(0.0, 0.0, 2.0)).norm() < 1e-6);
    }

    #[test]
    fn follows_the_square_and_rear_rotors_speed_up_in_forward_flight() {
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let plan = plan_square();
        let log = fly(
            &profile,
            &Airframe::nominal(4),
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: 1e-3 },
            1,
        );
        let mut worst: f64 = 0.0;
        for s in &log.samples {
            worst = worst.max((s.position - plan.at(s.t_s).position).norm());
        }
        assert!(worst < 0.15, "tracking error {worst} m");
        // First leg along +x with heading 0: rotors 1, 2 (index 0, 1) in front, 3, 4 behind.
        // Mid-leg at cruise (leg starts at 2 s, ramp 2.36 s, cruise 4.36–5.34 s).
        let s = &log.samples[(5.0 / 1e-3) as usize];
        assert!((s.velocity.x - 1.5).abs() < 0.05, "{}", s.velocity.x);
        let front = (s.rotor_hz[0] + s.rotor_hz[1]) / 2.0;
        let rear = (s.rotor_hz[2] + s.rotor_hz[3]) / 2.0;
        // Thrust balance: the rear pair loses κ·v·cos45° of thrust, so (rear/front)² ≈ 1/(1 − that).
        let loss = 0.02 * 1.5 * std::f64::consts::FRAC_1_SQRT_2;
        let expected = (1.0 / (1.0 - loss)).sqrt();
        assert!(
            ((rear / front) - expected).abs() < 0.002,
            "rear/front {} vs {expected}",
            rear / front
        );
    }

    /// Every drone type of `crate::drones` flies the square as the Mini 2 does (its flight
    /// constants are scaled by size): within 0.15 m of the plan all along, and in mid-leg
    /// cruise its rotors carry its weight (oracle: Σ k_v fᵢ² = m g within the drag's share).
    #[test]
    fn every_preset_flies_the_square() {
        let plan = plan_square();
        for name in DroneProfile::PRESETS {
            let profile =
                DroneProfile { rotor_jitter: 0.0, ..DroneProfile::preset(name).expect("preset") };
            let n = profile.rotor_count();
            let log = fly(
                &profile,
                &Airframe::nominal(n),
                &plan,
                0.0,
                &ControlGains::default(),
                Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: 1e-3 },
                1,
            );
            let worst = log
                .samples
                .iter()
                .map(|s| (s.position - plan.at(s.t_s).position).norm())
                .fold(0.0, f64::max);
            assert!(worst < 0.15, "{name}: tracking error {worst} m");
            let s = &log.samples[(5.0 / 1e-3) as usize];
            let thrust: f64 = s.rotor_hz.iter().map(|f| profile.thrust_coefficient() * f * f).sum();
            let weight = profile.mass_kg * GRAVITY_MPS2;
            assert!(
                (thrust / weight - 1.0).abs() < 0.05,
                "{name}: thrust/weight {}",
                thrust / weight
            );
        }
    }

    /// Nose-first flight: the drone's heading follows the plan's, and during a turn the rotor
    /// speeds obey the yaw torque law I_z ψ̈ = k_h (Σ_even f² − Σ_odd f²) (odd rotors spin
    /// counter-clockwise, so their reaction torque turns the body clockwise).
    #[test]
    fn nose_first_turns_follow_the_plan_through_the_odd_even_split() {
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let heading = Heading::AlongTrack {
            max_rate_rad_s: 90f64.to_radians(),
            max_accel_rad_s2: 180f64.to_radians(),
        };
        // Counter-clockwise square then a clockwise dog-leg: turns of +90° and −90°.
        let mut w = square([0.0, 0.0], 3.0, 2.0, false, 1);
        w.truncate(3);
        w.push(Vector3::new(6.0, 3.0, 2.0));
        let plan = FlightPlan::new(&w, 1.0, 1.0, 1.0, 0.5, 1.0, heading).unwrap();
        let turns = plan.turns();
        assert_eq!(turns.len(), 2);
        assert!((turns[0].2 - FRAC_PI_2).abs() < 1e-12 && (turns[1].2 + FRAC_PI_2).abs() < 1e-12);
        let dt = 1e-3;
        let log = fly(
            &profile,
            &Airframe::nominal(4),
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: dt },
            1,
        );
        let yaw = |k: usize| log.samples[k].yaw_rad();
        let wrap = |a: f64| (a + PI).rem_euclid(TAU) - PI;
        // Heading against the commanded one (the oracle), all along and settled after turns.
        let mut worst: f64 = 0.0;
        for (k, s) in log.samples.iter().enumerate() {
            let cmd = plan.heading_at(s.t_s).unwrap().yaw_rad;
            worst = worst.max(wrap(yaw(k) - cmd).abs());
        }
        assert!(worst < 3f64.to_radians(), "worst heading error {}°", worst.to_degrees());
        let kv = profile.thrust_coefficient();
        let kh = kv * profile.torque_to_thrust_m;
        let iz = profile.inertia_kgm2[2];
        for &(t0, t1, delta) in &turns {
            let k1 = ((t1 + 0.3) / dt) as usize;
            let settled = plan.heading_at(t1 + 0.3).unwrap().yaw_rad;
            assert!(wrap(yaw(k1) - settled).abs() < 1f64.to_radians(), "after turn at {t0}");
            // In the yaw-acceleration quarter the even rotors must outrun the odd ones for a
            // left turn (positive ψ̈) and the reverse for a right turn; in the braking quarter
            // the reverse. The size follows the torque law against the truth's own ψ̈.
            let quarter = (t1 - t0) / 4.0;
            for (centre, sign) in [(t0 + quarter / 2.0, 1.0), (t1 - quarter / 2.0, -1.0)] {
                let k = (centre / dt) as usize;
                let h = 20;
                let psi_dd = wrap(yaw(k + h) - 2.0 * yaw(k) + yaw(k - h)) / (h as f64 * dt).powi(2);
                let f = &log.samples[k].rotor_hz;
                let even_minus_odd: f64 = f
                    .iter()
                    .enumerate()
                    .map(|(i, x)| if i % 2 == 1 { x * x } else { -x * x })
                    .sum();
                let torque_law = kh * even_minus_odd / iz;
                assert!(
                    torque_law.signum() == sign * delta.signum(),
                    "turn {delta:.2} at {centre:.2}: even−odd f² = {even_minus_odd:.1} Hz²"
                );
                assert!(
                    (torque_law - psi_dd).abs() < 0.1 * psi_dd.abs(),
                    "turn at {centre:.2}: torque law {torque_law:.3} vs ψ̈ {psi_dd:.3} rad/s²"
                );
            }
        }
    }

    #[test]
    fn fixed_heading_plan_has_no_heading_reference() {
        // The fixed plan leaves the heading to the controller: no reference, no turns.
        let plan = plan_square();
        assert!(plan.heading_at(3.0).is_none());
        assert!(plan.turns().is_empty());
    }
    /// A drone as built, off its profile: its settled hover speeds obey the static balance
    /// with the true centre of gravity and thrust coefficients (oracle: the 4×4 linear system
    /// Σ kᵥ cᵢ fᵢ² = m g, Σ kᵥ cᵢ fᵢ² (yᵢ − c_y) = 0, Σ kᵥ cᵢ fᵢ² (xᵢ − c_x) = 0, Σ sᵢ k_h fᵢ² = 0).
    #[test]
    fn off_nominal_airframe_hovers_at_its_static_balance() {
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let mut airframe = Airframe::nominal(4);
        airframe.cg_offset_m = [0.002, -0.001];
        airframe.thrust_factor = vec![1.02, 0.98, 1.0, 0.97];
        let plan = plan_hover();
        let log = fly(
            &profile,
            &airframe,
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: 1.0, dt_s: 1e-3 },
            1,
        );
        assert_eq!(log.samples[0].t_s, 0.0);
        let kv = profile.thrust_coefficient();
        let kh = kv * profile.torque_to_thrust_m;
        let rotors = profile.rotors();
        let mut a = nalgebra::Matrix4::zeros();
        for (i, r) in rotors.iter().enumerate() {
            let c = kv * airframe.thrust_factor[i];
            a[(0, i)] = c;
            a[(1, i)] = c * (r.position_m.y - airframe.cg_offset_m[1]);
            a[(2, i)] = c * (r.position_m.x - airframe.cg_offset_m[0]);
            a[(3, i)] = r.spin * kh;
        }
        let b = nalgebra::Vector4::new(profile.mass_kg * GRAVITY_MPS2, 0.0, 0.0, 0.0);
        let f2 = a.lu().solve(&b).unwrap();
        let last = log.samples.last().unwrap();
        for i in 0..4 {
            let f = f2[i].sqrt();
            assert!((last.rotor_hz[i] - f).abs() < 0.02, "rotor {i}: {} vs {f}", last.rotor_hz[i]);
        }
        // The CG 2 mm forward makes the front pair spin faster than the rear (≈ 2.7 %).
        let front = last.rotor_hz[0] + last.rotor_hz[1];
        let rear = last.rotor_hz[2] + last.rotor_hz[3];
        assert!(front / rear > 1.01, "{}", front / rear);
        // Hub positions in the log are relative to the true centre of mass.
        assert!((log.rotors[0].position_m.x - (rotors[0].position_m.x - 0.002)).abs() < 1e-15);
        assert!(last.velocity.norm() < 1e-3 && (last.position.z - 2.0).abs() < 0.01);
    }

    /// The wake of an airframe with gain g and curvature q: in steady cruise the rear/front
    /// speed ratio is (1 − κ g d (1 + q d))^(−½), d = v cos 45°, at two speeds (so the loss is
    /// seen to be non-linear in airspeed).
    #[test]
    fn drawn_wake_gain_and_curvature_set_the_cruise_split() {
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let mut airframe = Airframe::nominal(4);
        airframe.wake_gain = 1.3;
        airframe.wake_curvature_per_mps = 0.1;
        for speed in [1.0, 2.5] {
            let w = [Vector3::new(0.0, 0.0, 2.0), Vector3::new(30.0, 0.0, 2.0)];
            let plan = FlightPlan::new(&w, speed, 1.0, 1.0, 0.0, 1.0, Heading::Fixed).unwrap();
            let log = fly(
                &profile,
                &airframe,
                &plan,
                0.0,
                &ControlGains::default(),
                Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: 1e-3 },
                1,
            );
            let k = (plan.duration_s() / 2.0 / 1e-3) as usize;
            let s = &log.samples[k];
            assert!((s.velocity.x - speed).abs() < 0.02, "{}", s.velocity.x);
            let ratio = (s.rotor_hz[2] + s.rotor_hz[3]) / (s.rotor_hz[0] + s.rotor_hz[1]);
            let d = speed * std::f64::consts::FRAC_1_SQRT_2;
            let expected = (1.0 / airframe.wake_factor(0.02, d)).sqrt();
            assert!((ratio - expected).abs() < 0.002, "{speed} m/s: {ratio} vs {expected}");
        }
    }

    /// A circle flown nose first: the flown drone stays on the circle and its measured
    /// acceleration is the centripetal v²/r (Newton: the tilted thrust supplies it).
    #[test]
    fn flown_circle_keeps_the_centripetal_law() {
        use crate::path::Shape;
        let profile = DroneProfile { rotor_jitter: 0.0, ..DroneProfile::dji_mini_2() };
        let (v, r) = (1.5, 4.0);
        let shape = Shape::Circle {
            centre: [0.0, 0.0],
            height_m: 2.0,
            radius_m: r,
            start_rad: 0.0,
            sense: 1.0,
            loops: 1,
        };
        let heading = Heading::AlongTrack { max_rate_rad_s: 1.0, max_accel_rad_s2: 2.0 };
        let plan = FlightPlan::continuous(shape, v, 1.0, 1.0, 1.0, heading).unwrap();
        let log = fly(
            &profile,
            &Airframe::nominal(4),
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: 1e-3 },
            1,
        );
        let mid = &log.samples[(plan.duration_s() / 2.0 / 1e-3) as usize];
        let radial = Vector3::new(mid.position.x, mid.position.y, 0.0);
        assert!((radial.norm() - r).abs() < 0.05, "{}", radial.norm());
        assert!((mid.velocity.norm() - v).abs() < 0.03, "{}", mid.velocity.norm());
        let a_in = -mid.acceleration.dot(&radial.normalize());
        assert!((a_in - v * v / r).abs() < 0.03, "{a_in} vs {}", v * v / r);
        // Nose first: the heading is the velocity's direction.
        let along = mid.velocity.y.atan2(mid.velocity.x);
        let off = (mid.yaw_rad() - along + PI).rem_euclid(TAU) - PI;
        assert!(off.abs() < 2f64.to_radians(), "{}°", off.to_degrees());
    }
    /// A vertical climb and a diagonal descent (3-D legs): all along, the rotors' total thrust
    /// obeys Newton along the vertical, Σ k_v fᵢ² cos(tilt) = m (g + a_z) + k_d,v v_z |v_z|.
    #[test]
    fn climbs_and_descents_obey_newton_along_the_vertical() {
        // No wake (it would take thrust off the rear rotors on the diagonal leg).
        let profile = DroneProfile {
            rotor_jitter: 0.0,
            wake_loss_per_mps: 0.0,
            ..DroneProfile::dji_mini_2()
        };
        let w =
            [Vector3::new(0.0, 0.0, 1.5), Vector3::new(0.0, 0.0, 3.0), Vector3::new(4.0, 0.0, 2.0)];
        let plan = FlightPlan::new(&w, 1.5, 1.0, 1.0, 0.5, 1.0, Heading::Fixed).unwrap();
        let log = fly(
            &profile,
            &Airframe::nominal(4),
            &plan,
            0.0,
            &ControlGains::default(),
            Span { t0_s: 0.0, t1_s: plan.duration_s(), dt_s: 1e-3 },
            1,
        );
        let kv = profile.thrust_coefficient();
        let (mut worst, mut vz_max, mut vz_min): (f64, f64, f64) = (0.0, 0.0, 0.0);
        // A sample's acceleration is the last physics substep's, driven by the previous
        // sample's rotor speeds (the motors then move on): pair them so.
        for pair in log.samples.windows(2).skip(100).step_by(10) {
            let (s, next) = (&pair[0], &pair[1]);
            let thrust: f64 = s.rotor_hz.iter().map(|f| kv * f * f).sum();
            let up = (s.attitude * Vector3::z()).z;
            let drag = profile.drag_v * s.velocity.z * s.velocity.z.abs();
            let newton = profile.mass_kg * (GRAVITY_MPS2 + next.acceleration.z) + drag;
            worst = worst.max((thrust * up - newton).abs() / newton);
            vz_max = vz_max.max(s.velocity.z);
            vz_min = vz_min.min(s.velocity.z);
        }
        // The motors move within a step (lag 30 ms over 1 ms steps): a few per mille.
        assert!(worst < 0.01, "{worst}");
        // The 1.5 m climb is too short to reach 1.5 m/s at 1 m/s²: it peaks at √(2·1·1.5/π) m/s.
        assert!(vz_max > 0.95 && vz_min < -0.3, "{vz_max} {vz_min}");
        let end = log.samples.last().unwrap().position;
        assert!((end - w[2]).norm() < 0.05, "{end:?}");
    }
}
