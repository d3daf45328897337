//! The flight plan: waypoint legs flown at a set speed, as a reference trajectory (position,
//! velocity, acceleration as functions of time) for the position controller.
//!
//! Each leg starts and ends at rest. Speed ramps up and down with a raised-cosine profile whose
//! peak acceleration is `max_accel_mps2`, so the reference is smooth (continuous acceleration)
//! and the drone, like a pilot flying along floor markers, stops at every corner.
use nalgebra::Vector3;

/// Reference state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reference {
    /// Position, ENU m.
    pub position: Vector3<f64>,
    /// Velocity, m/s.
    pub velocity: Vector3<f64>,
    /// Acceleration, m/s².
    pub acceleration: Vector3<f64>,
}

#[derive(Clone, Debug)]
struct Leg {
    start_s: f64,
    from: Vector3<f64>,
    direction: Vector3<f64>,
    length_m: f64,
    speed_mps: f64,
    ramp_s: f64,
    duration_s: f64,
}

/// A flight plan: hover at the first waypoint, fly the legs, hover at the last one.
#[derive(Clone, Debug)]
pub struct FlightPlan {
    legs: Vec<Leg>,
    start: Vector3<f64>,
    end: Vector3<f64>,
    end_s: f64,
}

impl FlightPlan {
    /// Builds the plan. `waypoints` in ENU m; the drone hovers `hover_start_s` at the first,
    /// pauses `pause_s` at each intermediate one, and the plan ends `hover_end_s` after reaching
    /// the last. `speed_mps` is the cruise speed, `max_accel_mps2` the peak acceleration.
    pub fn new(
        waypoints: &[Vector3<f64>],
        speed_mps: f64,
        max_accel_mps2: f64,
        hover_start_s: f64,
        pause_s: f64,
        hover_end_s: f64,
    ) -> Result<Self, String> {
        if waypoints.is_empty() {
            return Err("the path has no waypoints".into());
        }
        if !(speed_mps > 0.0 && max_accel_mps2 > 0.0) {
            return Err("path speed and acceleration must be positive".into());
        }
        if !(hover_start_s >= 0.0 && pause_s >= 0.0 && hover_end_s >= 0.0) {
            return Err("hover and pause times must not be negative".into());
        }
        let mut legs = Vec::new();
        let mut t = hover_start_s;
        for (i, pair) in waypoints.windows(2).enumerate() {
            let d = pair[1] - pair[0];
            let length_m = d.norm();
            if length_m < 1e-9 {
                continue;
            }
            // Raised-cosine ramp: v(t) = V (1 − cos(π t / T)) / 2, peak acceleration π V / (2 T).
            // A leg too short to reach V cruises slower: V T(V) = L.
            let ramp = |v: f64| std::f64::consts::PI * v / (2.0 * max_accel_mps2);
            let mut v = speed_mps;
            if v * ramp(v) > length_m {
                v = (2.0 * max_accel_mps2 * length_m / std::f64::consts::PI).sqrt();
            }
            let ramp_s = ramp(v);
            let duration_s = length_m / v + ramp_s;
            if i > 0 {
                t += pause_s;
            }
            legs.push(Leg {
                start_s: t,
                from: pair[0],
                direction: d / length_m,
                length_m,
                speed_mps: v,
                ramp_s,
                duration_s,
            });
            t += duration_s;
        }
        Ok(Self {
            legs,
            start: waypoints[0],
            end: *waypoints.last().expect("not empty"),
            end_s: t + hover_end_s,
        })
    }

    /// Total duration of the plan, s.
    pub fn duration_s(&self) -> f64 {
        self.end_s
    }

    /// Reference at time `t_s` (before the start: hovering at the first waypoint).
    pub fn at(&self, t_s: f64) -> Reference {
        let hold = |p: Vector3<f64>| Reference {
            position: p,
            velocity: Vector3::zeros(),
            acceleration: Vector3::zeros(),
        };
        let mut current = hold(self.start);
        for leg in &self.legs {
            if t_s < leg.start_s {
                return current;
            }
            let tau = t_s - leg.start_s;
            if tau < leg.duration_s {
                let (s, v, a) = leg.profile(tau);
                return Reference {
                    position: leg.from + leg.direction * s,
                    velocity: leg.direction * v,
                    acceleration: leg.direction * a,
                };
            }
            current = hold(leg.from + leg.direction * leg.length_m);
        }
        if self.legs.is_empty() {
            hold(self.end)
        } else {
            current
        }
    }
}

impl Leg {
    /// Distance, speed and acceleration along the leg `tau` seconds after its start.
    fn profile(&self, tau: f64) -> (f64, f64, f64) {
        use std::f64::consts::PI;
        let (v, ramp) = (self.speed_mps, self.ramp_s);
        let ramp_len = v * ramp / 2.0;
        let up = |t: f64| {
            (
                v / 2.0 * (t - ramp / PI * (PI * t / ramp).sin()),
                v / 2.0 * (1.0 - (PI * t / ramp).cos()),
                v * PI / (2.0 * ramp) * (PI * t / ramp).sin(),
            )
        };
        let cruise_end = self.duration_s - ramp;
        if tau < ramp {
            up(tau)
        } else if tau < cruise_end {
            (ramp_len + v * (tau - ramp), v, 0.0)
        } else {
            // Deceleration mirrors the ramp-up in time.
            let (s, sv, sa) = up(self.duration_s - tau);
            (self.length_m - s, sv, -sa)
        }
    }
}

/// Corners of a horizontal square flown counter-clockwise (or clockwise) from `start` (x, y),
/// with side `side_m` along +x first, at `height_m`; the last waypoint closes the loop.
/// `loops` repeats it.
pub fn square(
    start: [f64; 2],
    side_m: f64,
    height_m: f64,
    clockwise: bool,
    loops: u32,
) -> Vec<Vector3<f64>> {
    let (x0, y0) = (start[0], start[1]);
    let dy = if clockwise { -side_m } else { side_m };
    let corners = [
        Vector3::new(x0 + side_m, y0, height_m),
        Vector3::new(x0 + side_m, y0 + dy, height_m),
        Vector3::new(x0, y0 + dy, height_m),
        Vector3::new(x0, y0, height_m),
    ];
    let mut points = vec![Vector3::new(x0, y0, height_m)];
    for _ in 0..loops.max(1) {
        points.extend_from_slice(&corners);
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leg_profile_integrates_consistently() {
        let w = square([0.0, 0.0], 10.0, 2.0, false, 1);
        let plan = FlightPlan::new(&w, 1.5, 1.0, 2.0, 0.5, 2.0).unwrap();
        // Numerically integrate velocity and acceleration and compare with position/velocity.
        let dt = 1e-3;
        let mut p = plan.at(0.0).position;
        let mut v = Vector3::zeros();
        let mut t = 0.0;
        let mut max_speed: f64 = 0.0;
        let mut max_accel: f64 = 0.0;
        while t < plan.duration_s() {
            let r0 = plan.at(t);
            let r1 = plan.at(t + dt);
            p += (r0.velocity + r1.velocity) * dt / 2.0;
            v += (r0.acceleration + r1.acceleration) * dt / 2.0;
            max_speed = max_speed.max(r1.velocity.norm());
            max_accel = max_accel.max(r1.acceleration.norm());
            t += dt;
            assert!((p - r1.position).norm() < 1e-3, "position drift at {t}");
            assert!((v - r1.velocity).norm() < 1e-3, "velocity drift at {t}");
        }
        assert!((max_speed - 1.5).abs() < 1e-6);
        assert!((max_accel - 1.0).abs() < 1e-3);
        assert!((plan.at(plan.duration_s()).position - w[0]).norm() < 1e-9);
        // 40 m at 1.5 m/s, plus four ramps (π·1.5/2 s each), three pauses, two hovers.
        let expected = 40.0 / 1.5 + 4.0 * std::f64::consts::PI * 1.5 / 2.0 + 1.5 + 4.0;
        assert!((plan.duration_s() - expected).abs() < 1e-9);
    }
}
