//! The flight plan: waypoint legs flown at a set speed, as a reference trajectory (position,
//! velocity, acceleration as functions of time) for the position controller, and a heading
//! reference for the attitude controller.
//!
//! Each leg starts and ends at rest. Speed ramps up and down with a raised-cosine profile whose
//! peak acceleration is `max_accel_mps2`, so the reference is smooth (continuous acceleration)
//! and the drone, like a pilot flying along floor markers, stops at every corner.
//!
//! Heading ([`Heading`]): `Fixed` holds one heading (given to the flight controller);
//! `AlongTrack` flies nose-first. The drone starts facing its first leg, and at every corner
//! whose next leg points elsewhere it pauses `pause_s`, turns the short way to face the next
//! leg, and pauses `pause_s` again before setting off. The turn is a rest-to-rest profile of the
//! same raised-cosine form as a leg (peak yaw rate and peak yaw acceleration as given), so the
//! rotor speeds show a yaw-acceleration phase (odd against even rotors), a steady turn and a
//! yaw-braking phase.
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

/// Heading reference at one instant (heading: angle of the body x axis from ENU +x towards +y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingReference {
    /// Heading, rad, continuous (not wrapped: successive turns add up).
    pub yaw_rad: f64,
    /// Yaw rate, rad/s (positive counter-clockwise seen from above).
    pub rate_rad_s: f64,
    /// Yaw acceleration, rad/s².
    pub accel_rad_s2: f64,
}

/// How the drone points its nose (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Heading {
    /// One heading throughout; the flight controller is given it.
    Fixed,
    /// Nose first along each leg, turning at the corners.
    AlongTrack {
        /// Peak yaw rate of a turn, rad/s.
        max_rate_rad_s: f64,
        /// Peak yaw acceleration of a turn, rad/s².
        max_accel_rad_s2: f64,
    },
}

/// A rest-to-rest move along one coordinate: raised-cosine speed ramps of peak acceleration
/// `max_accel` up to `speed` (or less, if the move is too short to reach it), cruise, and the
/// mirrored ramp down. Units: those of `length` (m or rad) and seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ramp {
    length: f64,
    speed: f64,
    ramp_s: f64,
    duration_s: f64,
}

impl Ramp {
    fn new(length: f64, max_speed: f64, max_accel: f64) -> Self {
        // Raised-cosine ramp: v(t) = V (1 − cos(π t / T)) / 2, peak acceleration π V / (2 T).
        // A move too short to reach V cruises slower: V T(V) = L.
        let ramp = |v: f64| std::f64::consts::PI * v / (2.0 * max_accel);
        let mut v = max_speed;
        if v * ramp(v) > length {
            v = (2.0 * max_accel * length / std::f64::consts::PI).sqrt();
        }
        let ramp_s = ramp(v);
        let duration_s = length / v + ramp_s;
        Self { length, speed: v, ramp_s, duration_s }
    }

    /// Distance, speed and acceleration `tau` seconds after the start.
    fn at(&self, tau: f64) -> (f64, f64, f64) {
        use std::f64::consts::PI;
        let (v, ramp) = (self.speed, self.ramp_s);
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
            (self.length - s, sv, -sa)
        }
    }
}

#[derive(Clone, Debug)]
struct Leg {
    start_s: f64,
    from: Vector3<f64>,
    direction: Vector3<f64>,
    ramp: Ramp,
}

/// One turn on the spot: from heading `from_rad` by `delta_rad` (signed), starting `start_s`.
#[derive(Clone, Debug)]
struct Turn {
    start_s: f64,
    from_rad: f64,
    delta_rad: f64,
    ramp: Ramp,
}

/// A flight plan: hover at the first waypoint, fly the legs, hover at the last one.
#[derive(Clone, Debug)]
pub struct FlightPlan {
    legs: Vec<Leg>,
    turns: Vec<Turn>,
    heading: Heading,
    start: Vector3<f64>,
    end: Vector3<f64>,
    end_s: f64,
}

/// Wraps an angle to (−π, π], rad.
fn wrap_pi(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

impl FlightPlan {
    /// Builds the plan. `waypoints` in ENU m; the drone hovers `hover_start_s` at the first,
    /// pauses `pause_s` at each intermediate one, and the plan ends `hover_end_s` after reaching
    /// the last. `speed_mps` is the cruise speed, `max_accel_mps2` the peak acceleration.
    /// `heading` (module docs): with `AlongTrack`, a corner whose next leg points elsewhere
    /// takes `pause_s`, the turn and `pause_s` again.
    #[allow(clippy::too_many_arguments)] // the plan's parameters, each a physical quantity
    pub fn new(
        waypoints: &[Vector3<f64>],
        speed_mps: f64,
        max_accel_mps2: f64,
        hover_start_s: f64,
        pause_s: f64,
        hover_end_s: f64,
        heading: Heading,
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
        if let Heading::AlongTrack { max_rate_rad_s, max_accel_rad_s2 } = heading {
            if !(max_rate_rad_s > 0.0
                && max_rate_rad_s.is_finite()
                && max_accel_rad_s2 > 0.0
                && max_accel_rad_s2.is_finite())
            {
                return Err("yaw rate and yaw acceleration must be positive".into());
            }
        }
        let mut legs: Vec<Leg> = Vec::new();
        let mut turns = Vec::new();
        let mut t = hover_start_s;
        // Heading of the previous leg (continuous), for along-track flight.
        let mut yaw: Option<f64> = None;
        for (i, pair) in waypoints.windows(2).enumerate() {
            let d = pair[1] - pair[0];
            let length_m = d.norm();
            if length_m < 1e-9 {
                continue;
            }
            let ramp = Ramp::new(length_m, speed_mps, max_accel_mps2);
            if i > 0 {
                t += pause_s;
            }
            if let Heading::AlongTrack { max_rate_rad_s, max_accel_rad_s2 } = heading {
                // A vertical leg keeps the heading it has.
                if d.x.hypot(d.y) > 1e-9 {
                    let leg_yaw = d.y.atan2(d.x);
                    match yaw {
                        None => yaw = Some(leg_yaw),
                        Some(from_rad) => {
                            let delta_rad = wrap_pi(leg_yaw - from_rad);
                            if delta_rad.abs() > 1e-9 {
                                let ramp =
                                    Ramp::new(delta_rad.abs(), max_rate_rad_s, max_accel_rad_s2);
                                turns.push(Turn { start_s: t, from_rad, delta_rad, ramp });
                                t += ramp.duration_s + pause_s;
                                yaw = Some(from_rad + delta_rad);
                            }
                        }
                    }
                }
            }
            legs.push(Leg { start_s: t, from: pair[0], direction: d / length_m, ramp });
            t += ramp.duration_s;
        }
        Ok(Self {
            legs,
            turns,
            heading,
            start: waypoints[0],
            end: *waypoints.last().expect("not empty"),
            end_s: t + hover_end_s,
        })
    }

    /// Total duration of the plan, s.
    pub fn duration_s(&self) -> f64 {
        self.end_s
    }

    /// The heading behaviour.
    pub fn heading(&self) -> Heading {
        self.heading
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
            if tau < leg.ramp.duration_s {
                let (s, v, a) = leg.ramp.at(tau);
                return Reference {
                    position: leg.from + leg.direction * s,
                    velocity: leg.direction * v,
                    acceleration: leg.direction * a,
                };
            }
            current = hold(leg.from + leg.direction * leg.ramp.length);
        }
        if self.legs.is_empty() {
            hold(self.end)
        } else {
            current
        }
    }

    /// Heading reference at time `t_s`: `None` with a fixed heading (the controller holds its
    /// own), else the along-track heading, rad, with its rate and acceleration (a plan without
    /// a horizontal leg faces ENU +x).
    pub fn heading_at(&self, t_s: f64) -> Option<HeadingReference> {
        if self.heading == Heading::Fixed {
            return None;
        }
        let first = self.legs.iter().find(|l| l.direction.x.hypot(l.direction.y) > 1e-9);
        let hold = |yaw_rad: f64| HeadingReference { yaw_rad, rate_rad_s: 0.0, accel_rad_s2: 0.0 };
        let mut current = hold(first.map_or(0.0, |l| l.direction.y.atan2(l.direction.x)));
        for turn in &self.turns {
            if t_s < turn.start_s {
                return Some(current);
            }
            let tau = t_s - turn.start_s;
            let sign = turn.delta_rad.signum();
            if tau < turn.ramp.duration_s {
                let (s, v, a) = turn.ramp.at(tau);
                return Some(HeadingReference {
                    yaw_rad: turn.from_rad + sign * s,
                    rate_rad_s: sign * v,
                    accel_rad_s2: sign * a,
                });
            }
            current = hold(turn.from_rad + turn.delta_rad);
        }
        Some(current)
    }

    /// Every turn of the plan as (start, end, signed heading change), s, s, rad; empty with a
    /// fixed heading. The oracle of the yaw the drone should fly.
    pub fn turns(&self) -> Vec<(f64, f64, f64)> {
        self.turns.iter().map(|t| (t.start_s, t.start_s + t.ramp.duration_s, t.delta_rad)).collect()
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
        let plan = FlightPlan::new(&w, 1.5, 1.0, 2.0, 0.5, 2.0, Heading::Fixed).unwrap();
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

    #[test]
    fn along_track_heading_faces_each_leg_and_integrates_consistently() {
        use std::f64::consts::{FRAC_PI_2, PI};
        let w = square([0.0, 0.0], 10.0, 2.0, false, 1);
        let (rate, accel) = (90f64.to_radians(), 180f64.to_radians());
        let heading = Heading::AlongTrack { max_rate_rad_s: rate, max_accel_rad_s2: accel };
        let fixed = FlightPlan::new(&w, 1.5, 1.0, 2.0, 0.5, 2.0, Heading::Fixed).unwrap();
        let plan = FlightPlan::new(&w, 1.5, 1.0, 2.0, 0.5, 2.0, heading).unwrap();
        // Three left turns of 90°: each adds a pause and a turn (ramps π·rate/(2·accel) s each,
        // cruise (90° − ramp distance)/rate).
        let turns = plan.turns();
        assert_eq!(turns.len(), 3);
        let ramp_s = PI * rate / (2.0 * accel);
        let turn_s = FRAC_PI_2 / rate + ramp_s;
        for &(t0, t1, delta) in &turns {
            assert!((delta - FRAC_PI_2).abs() < 1e-12);
            assert!((t1 - t0 - turn_s).abs() < 1e-12);
        }
        let expected = fixed.duration_s() + 3.0 * (0.5 + turn_s);
        assert!((plan.duration_s() - expected).abs() < 1e-9);
        // Integrate rate and acceleration; compare with heading and rate; never above the peaks.
        let dt = 1e-3;
        let h0 = plan.heading_at(0.0).unwrap();
        assert_eq!(h0.yaw_rad, 0.0);
        let (mut yaw, mut r, mut t) = (h0.yaw_rad, 0.0, 0.0);
        while t < plan.duration_s() {
            let (a, b) = (plan.heading_at(t).unwrap(), plan.heading_at(t + dt).unwrap());
            yaw += (a.rate_rad_s + b.rate_rad_s) * dt / 2.0;
            r += (a.accel_rad_s2 + b.accel_rad_s2) * dt / 2.0;
            t += dt;
            assert!((yaw - b.yaw_rad).abs() < 1e-4, "heading drift at {t}");
            assert!((r - b.rate_rad_s).abs() < 1e-4, "rate drift at {t}");
            assert!(b.rate_rad_s.abs() <= rate + 1e-9 && b.accel_rad_s2.abs() <= accel + 1e-9);
            // Never turning while moving: the legs are flown nose first.
            let v = plan.at(t).velocity;
            if v.norm() > 1e-9 {
                assert!(b.rate_rad_s == 0.0);
                let along = v.y.atan2(v.x);
                let off = (b.yaw_rad - along).rem_euclid(2.0 * PI);
                assert!(off < 1e-9 || 2.0 * PI - off < 1e-9, "nose off the track at {t}");
            }
        }
        assert!((yaw - 3.0 * FRAC_PI_2).abs() < 1e-4);
        // The position reference is the fixed plan's, shifted by the corner stops.
        assert!((plan.at(plan.duration_s()).position - w[0]).norm() < 1e-9);
        // Bad yaw limits are refused with a message.
        let bad = Heading::AlongTrack { max_rate_rad_s: 0.0, max_accel_rad_s2: 1.0 };
        let e = FlightPlan::new(&w, 1.5, 1.0, 2.0, 0.5, 2.0, bad).unwrap_err();
        assert!(e.contains("yaw rate"), "{e}");
    }

    #[test]
    fn a_turn_takes_the_short_way() {
        // Heading east, then a leg to the south-east then north: −45° then +135°; a leg back
        // the way it came turns by π (either way; wrap gives +π).
        let w = [
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(1.0, 0.0, 1.0),
            Vector3::new(2.0, -1.0, 1.0),
            Vector3::new(2.0, 1.0, 1.0),
            Vector3::new(2.0, -1.0, 1.0),
        ];
        let heading = Heading::AlongTrack { max_rate_rad_s: 1.0, max_accel_rad_s2: 2.0 };
        let plan = FlightPlan::new(&w, 1.0, 1.0, 0.0, 0.0, 0.0, heading).unwrap();
        let d: Vec<f64> = plan.turns().iter().map(|t| t.2.to_degrees()).collect();
        assert_eq!(d.len(), 3);
        assert!((d[0] + 45.0).abs() < 1e-9 && (d[1] - 135.0).abs() < 1e-9, "{d:?}");
        assert!((d[2].abs() - 180.0).abs() < 1e-9, "{d:?}");
    }
}
