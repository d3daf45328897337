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
//!
//! Continuous courses ([`FlightPlan::continuous`], [`Shape`]): a circle, a figure-eight or a
//! smooth spline through waypoints (any heights: climbs, descents and diagonal climbs included),
//! flown without stopping at one cruise speed between a ramp from rest and a ramp to rest; the
//! across-track acceleration `v² κ` is checked against the acceleration limit. Nose-first, the
//! heading follows the horizontal tangent continuously (rate `v κ_h`), no turns on the spot.
//! A random walk ([`FlightPlan::walk`], [`WalkSpec`]) stands for a hand-flown flight: smooth
//! random accelerations, jerk-limited, within speed, climb-rate and acceleration limits, inside
//! a box, braking to rest at the end.
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
    course: Option<Continuous>,
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
            course: None,
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
        match &self.course {
            Some(Continuous::Curve(c)) => return c.at(t_s).0,
            Some(Continuous::Walk(w)) => return w.at(t_s),
            None => {}
        }
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
        if let Some(Continuous::Curve(c)) = &self.course {
            let (_, yaw_rad, rate_rad_s) = c.at(t_s);
            let d = 1e-3;
            let accel_rad_s2 = (c.at(t_s + d).2 - c.at(t_s - d).2) / (2.0 * d);
            return Some(HeadingReference { yaw_rad, rate_rad_s, accel_rad_s2 });
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

// ---------------------------------------------------------------------------------------------
// Continuous flight: curves flown without stopping, and a hand-flown-like random walk.
// ---------------------------------------------------------------------------------------------

/// The geometry of a continuous course, parameterised by `u` (not arc length).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// A horizontal circle: centre (x, y) and height, m; radius, m; the angle of the start
    /// point seen from the centre, rad; counter-clockwise (+1) or clockwise (−1); `u` is the
    /// angle travelled, 0 ..= 2π · loops.
    Circle {
        /// Centre (x, y), ENU m.
        centre: [f64; 2],
        /// Height, m.
        height_m: f64,
        /// Radius, m.
        radius_m: f64,
        /// Angle of the start point from the centre, rad (from +x towards +y).
        start_rad: f64,
        /// +1 counter-clockwise, −1 clockwise.
        sense: f64,
        /// Number of loops.
        loops: u32,
    },
    /// A horizontal figure-eight, the lemniscate of Bernoulli: with `a = L/2` and `t = u + π/2`,
    /// `x = a cos t / (1 + sin² t)`, `y = a sin t cos t / (1 + sin² t)` in its own axes (turned
    /// `axis_rad` from ENU +x), `u` 0 ..= 2π · loops; it starts at the centre where its lobes
    /// cross. Its width is `L / (2√2)` and its tightest radius `L / 6` (curvature `3 r / a²` at
    /// distance r from the centre, zero at the crossing).
    Eight {
        /// Centre (x, y), ENU m.
        centre: [f64; 2],
        /// Height, m.
        height_m: f64,
        /// Length along its axis, m.
        length_m: f64,
        /// Direction of its axis, rad.
        axis_rad: f64,
        /// Number of loops.
        loops: u32,
    },
    /// A natural cubic spline through waypoints (ENU m), parameterised by chord length: the
    /// waypoints flown without stopping, continuous in position, velocity and acceleration.
    Spline(Spline),
}

/// A natural cubic spline through 3-D points, chord-length knots.
#[derive(Clone, Debug, PartialEq)]
pub struct Spline {
    knots: Vec<f64>,
    /// Per segment: p(u) = c0 + c1 τ + c2 τ² + c3 τ³, τ = u − knot.
    coeffs: Vec<[Vector3<f64>; 4]>,
}

impl Spline {
    /// The spline through `points` (repeated points dropped); `None` with fewer than two
    /// distinct points.
    pub fn through(points: &[Vector3<f64>]) -> Option<Self> {
        let mut pts: Vec<Vector3<f64>> = Vec::new();
        for p in points {
            if pts.last().is_none_or(|q: &Vector3<f64>| (p - q).norm() > 1e-9) {
                pts.push(*p);
            }
        }
        let n = pts.len();
        if n < 2 {
            return None;
        }
        let mut knots = vec![0.0];
        for w in pts.windows(2) {
            knots.push(knots.last().expect("one") + (w[1] - w[0]).norm());
        }
        let h: Vec<f64> = knots.windows(2).map(|w| w[1] - w[0]).collect();
        // Second derivatives M (natural: M₀ = Mₙ₋₁ = 0) by the Thomas algorithm.
        let mut m = vec![Vector3::zeros(); n];
        if n > 2 {
            let k = n - 2;
            let mut diag = vec![0.0; k];
            let mut rhs = vec![Vector3::zeros(); k];
            let mut upper = vec![0.0; k];
            for i in 0..k {
                diag[i] = 2.0 * (h[i] + h[i + 1]);
                upper[i] = h[i + 1];
                rhs[i] =
                    ((pts[i + 2] - pts[i + 1]) / h[i + 1] - (pts[i + 1] - pts[i]) / h[i]) * 6.0;
            }
            for i in 1..k {
                let w = h[i] / diag[i - 1];
                diag[i] -= w * upper[i - 1];
                let r = rhs[i - 1];
                rhs[i] -= r * w;
            }
            m[k] = rhs[k - 1] / diag[k - 1];
            for i in (0..k - 1).rev() {
                m[i + 1] = (rhs[i] - m[i + 2] * upper[i]) / diag[i];
            }
        }
        let coeffs = (0..n - 1)
            .map(|i| {
                let hi = h[i];
                let c1 = (pts[i + 1] - pts[i]) / hi - (m[i] * 2.0 + m[i + 1]) * (hi / 6.0);
                [pts[i], c1, m[i] / 2.0, (m[i + 1] - m[i]) / (6.0 * hi)]
            })
            .collect();
        Some(Self { knots, coeffs })
    }

    fn eval(&self, u: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let last = self.coeffs.len() - 1;
        let j = self.knots.partition_point(|&k| k <= u).saturating_sub(1).min(last);
        let t = u - self.knots[j];
        let [c0, c1, c2, c3] = self.coeffs[j];
        (
            c0 + (c1 + (c2 + c3 * t) * t) * t,
            c1 + (c2 * 2.0 + c3 * (3.0 * t)) * t,
            c2 * 2.0 + c3 * (6.0 * t),
        )
    }
}

impl Shape {
    /// End of the parameter range (the start is 0).
    fn u_end(&self) -> f64 {
        match self {
            Shape::Circle { loops, .. } | Shape::Eight { loops, .. } => {
                std::f64::consts::TAU * f64::from((*loops).max(1))
            }
            Shape::Spline(s) => *s.knots.last().expect("two knots"),
        }
    }

    /// Position and its first and second derivatives with respect to `u`.
    fn eval(&self, u: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        match self {
            Shape::Circle { centre, height_m, radius_m, start_rad, sense, .. } => {
                let (s, c) = (start_rad + sense * u).sin_cos();
                let r = *radius_m;
                (
                    Vector3::new(centre[0] + r * c, centre[1] + r * s, *height_m),
                    Vector3::new(-r * s * sense, r * c * sense, 0.0),
                    Vector3::new(-r * c, -r * s, 0.0),
                )
            }
            Shape::Eight { centre, height_m, length_m, axis_rad, .. } => {
                let a = length_m / 2.0;
                let t = u + std::f64::consts::FRAC_PI_2;
                let (s, c) = t.sin_cos();
                let (s2, s4) = ((2.0 * t).sin(), (4.0 * t).sin());
                let d = 1.0 + s * s;
                let local = [
                    (a * c / d, a * s * c / d),
                    (a * (s * s - 3.0) * s / (d * d), a * (1.0 - 3.0 * s * s) / (d * d)),
                    (
                        a * (-s.powi(4) + 12.0 * s * s - 3.0) * c / (d * d * d),
                        -a * (14.0 * s2 + 3.0 * s4) / (4.0 * d * d * d),
                    ),
                ];
                let (sa, ca) = axis_rad.sin_cos();
                let turn =
                    |(x, y): (f64, f64), z: f64| Vector3::new(ca * x - sa * y, sa * x + ca * y, z);
                (
                    turn(local[0], *height_m) + Vector3::new(centre[0], centre[1], 0.0),
                    turn(local[1], 0.0),
                    turn(local[2], 0.0),
                )
            }
            Shape::Spline(s) => s.eval(u),
        }
    }
}

/// A course flown at a steady speed along a [`Shape`]: a raised-cosine ramp from rest to the
/// cruise speed, cruise, and a ramp to rest at its end.
#[derive(Clone, Debug)]
struct Curve {
    shape: Shape,
    /// Arc length table: (u, s, unwrapped horizontal tangent heading), ascending.
    table: Vec<(f64, f64, f64)>,
    ramp: Ramp,
    start_s: f64,
}

impl Curve {
    fn new(shape: Shape, speed_mps: f64, max_accel_mps2: f64, start_s: f64) -> Self {
        let u_end = shape.u_end();
        // Arc length by Simpson's rule on a grid of about 1 cm.
        let approx: f64 = {
            let k = 1000;
            (0..k).map(|i| (shape.eval(u_end * (i as f64 + 0.5) / k as f64).1).norm()).sum::<f64>()
                * u_end
                / k as f64
        };
        let n = ((approx / 0.01).ceil() as usize).clamp(100, 400_000);
        let du = u_end / n as f64;
        let speed = |u: f64| shape.eval(u).1.norm();
        let heading = |u: f64| {
            let d = shape.eval(u).1;
            d.y.atan2(d.x)
        };
        let mut table = Vec::with_capacity(n + 1);
        let (mut s, mut psi) = (0.0, heading(0.0));
        table.push((0.0, 0.0, psi));
        for i in 0..n {
            let (u0, u1) = (du * i as f64, du * (i + 1) as f64);
            s += du / 6.0 * (speed(u0) + 4.0 * speed((u0 + u1) / 2.0) + speed(u1));
            psi += wrap_pi(heading(u1) - psi);
            table.push((u1, s, psi));
        }
        let length = s;
        Self { shape, table, ramp: Ramp::new(length, speed_mps, max_accel_mps2), start_s }
    }

    fn length_m(&self) -> f64 {
        self.table.last().expect("table").1
    }

    /// Parameter u at arc length `s` (table, then one Newton step on Simpson's rule).
    fn u_at(&self, s: f64) -> (f64, f64) {
        let i = self.table.partition_point(|e| e.1 <= s).clamp(1, self.table.len() - 1);
        let (a, b) = (self.table[i - 1], self.table[i]);
        let w = if b.1 > a.1 { (s - a.1) / (b.1 - a.1) } else { 0.0 };
        let mut u = a.0 + w * (b.0 - a.0);
        let sp = |u: f64| self.shape.eval(u).1.norm();
        let s_u = a.1 + (u - a.0) / 6.0 * (sp(a.0) + 4.0 * sp((a.0 + u) / 2.0) + sp(u));
        u -= (s_u - s) / sp(u).max(1e-12);
        let psi = a.2 + w * (b.2 - a.2);
        (u, psi)
    }

    /// Reference and (unwrapped heading, heading rate) at time `t_s`.
    fn at(&self, t_s: f64) -> (Reference, f64, f64) {
        let tau = (t_s - self.start_s).clamp(0.0, self.ramp.duration_s);
        let (s, v, a) = if t_s <= self.start_s {
            (0.0, 0.0, 0.0)
        } else if tau >= self.ramp.duration_s {
            (self.length_m(), 0.0, 0.0)
        } else {
            self.ramp.at(tau)
        };
        let (u, psi_table) = self.u_at(s.min(self.length_m()));
        let (p, d1, d2) = self.shape.eval(u);
        let norm = d1.norm().max(1e-12);
        let tangent = d1 / norm;
        // dT/ds: the curvature vector.
        let kappa = (d2 - tangent * d2.dot(&tangent)) / (norm * norm);
        let reference = Reference {
            position: p,
            velocity: tangent * v,
            acceleration: tangent * a + kappa * (v * v),
        };
        let h2 = tangent.x * tangent.x + tangent.y * tangent.y;
        let (psi, rate) = if h2 > 1e-12 {
            let raw = tangent.y.atan2(tangent.x);
            let psi =
                raw + std::f64::consts::TAU * ((psi_table - raw) / std::f64::consts::TAU).round();
            let dt_ds = kappa;
            (psi, (tangent.x * dt_ds.y - tangent.y * dt_ds.x) / h2 * v)
        } else {
            (psi_table, 0.0)
        };
        (reference, psi, rate)
    }
}

/// A hand-flown-like random walk: smooth random accelerations (an Ornstein–Uhlenbeck target,
/// jerk-limited) within the airframe's limits, kept inside a box, on a grid of `h` seconds with
/// acceleration linear between grid points (so velocity and position integrate it exactly).
#[derive(Clone, Debug)]
struct Walk {
    start_s: f64,
    h: f64,
    p: Vec<Vector3<f64>>,
    v: Vec<Vector3<f64>>,
    a: Vec<Vector3<f64>>,
}

/// Parameters of a random walk (`path.kind = "walk"`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkSpec {
    /// Where it starts (at rest), ENU m.
    pub start: Vector3<f64>,
    /// Lowest corner of the box it stays in, ENU m.
    pub area_min: Vector3<f64>,
    /// Highest corner, ENU m.
    pub area_max: Vector3<f64>,
    /// Time spent wandering before it brakes to rest, s.
    pub wander_s: f64,
    /// Correlation time of the random acceleration, s.
    pub tau_s: f64,
    /// Largest speed, m/s.
    pub max_speed_mps: f64,
    /// Largest vertical speed, m/s.
    pub max_climb_mps: f64,
    /// Largest acceleration, m/s².
    pub max_accel_mps2: f64,
    /// Largest jerk, m/s³.
    pub max_jerk_mps3: f64,
    /// Seed of the random accelerations.
    pub seed: u64,
}

impl Walk {
    const STEP_S: f64 = 0.01;

    fn new(spec: &WalkSpec, start_s: f64) -> Result<Self, String> {
        use rand::{rngs::StdRng, SeedableRng};
        let WalkSpec { area_min: lo, area_max: hi, .. } = *spec;
        let margin = 0.5;
        if (0..3).any(|i| hi[i] - lo[i] < 2.0 * margin + 0.5) {
            return Err(
                "walk: area_max must exceed area_min by at least 1.5 m on every axis".into()
            );
        }
        if (0..3).any(|i| spec.start[i] < lo[i] + margin || spec.start[i] > hi[i] - margin) {
            return Err("walk: the start must lie inside the area, 0.5 m from its faces".into());
        }
        let positive = [
            spec.wander_s,
            spec.tau_s,
            spec.max_speed_mps,
            spec.max_climb_mps,
            spec.max_accel_mps2,
            spec.max_jerk_mps3,
        ];
        if positive.iter().any(|x| !(x.is_finite() && *x > 0.0)) || spec.wander_s > 3600.0 {
            return Err("walk: durations, speeds, acceleration and jerk must be positive".into());
        }
        let h = Self::STEP_S;
        let mut rng = StdRng::seed_from_u64(spec.seed);
        let mut g =
            crate::filter::Gaussian::new(StdRng::seed_from_u64(rand::Rng::random(&mut rng)));
        let a_max = spec.max_accel_mps2;
        let sigma = 0.6 * a_max;
        let mut target = Vector3::zeros();
        let (mut p, mut v, mut a) = (spec.start, Vector3::<f64>::zeros(), Vector3::<f64>::zeros());
        let (mut ps, mut vs, mut as_) = (vec![p], vec![v], vec![a]);
        let wander = (spec.wander_s / h).round() as usize;
        let brake_a = 0.5 * a_max;
        for k in 0.. {
            let braking_out = k >= wander;
            if braking_out && v.norm() < 1e-4 && a.norm() < 1e-4 || k > wander + (60.0 / h) as usize
            {
                break;
            }
            let mut desired = if braking_out {
                -v
            } else {
                let kick = (2.0 * h / spec.tau_s).sqrt() * sigma;
                target += -target * (h / spec.tau_s)
                    + Vector3::new(g.sample(), g.sample(), 0.4 * g.sample()) * kick;
                target
            };
            // Speed still gained while the jerk limit unwinds an acceleration `along` the
            // velocity, m/s.
            let gain = |along: f64| along.max(0.0).powi(2) / (2.0 * spec.max_jerk_mps3);
            if !braking_out {
                // Climb limit first, so that the box's braking below has the last word (set
                // after it, a gentle climb correction replaced the braking and the walk left
                // its box through the floor or the ceiling).
                let climb = v.z.abs() + gain(a.z * v.z.signum());
                if climb > 0.8 * spec.max_climb_mps {
                    let over = (climb - 0.8 * spec.max_climb_mps) / (0.2 * spec.max_climb_mps);
                    desired.z = -v.z.signum() * a_max * over.min(1.0);
                }
                // Keep inside the box: brake before a face at half the acceleration limit,
                // counting the jerk-limited time to build that braking.
                for i in 0..3 {
                    let lead = v[i] * (a_max / spec.max_jerk_mps3);
                    let stop = v[i] * v[i] / (2.0 * brake_a) + lead.abs();
                    if v[i] > 0.0 && p[i] + stop + margin > hi[i] {
                        desired[i] = -a_max;
                    } else if v[i] < 0.0 && p[i] - stop - margin < lo[i] {
                        desired[i] = a_max;
                    } else if p[i] > hi[i] - margin {
                        desired[i] = desired[i].min(-0.3 * a_max);
                    } else if p[i] < lo[i] + margin {
                        desired[i] = desired[i].max(0.3 * a_max);
                    }
                }
                // Speed limits: no acceleration that adds speed beyond 90 % of the limit.
                // Counting the speed still gained while the jerk limit unwinds the acceleration.
                let speed =
                    v.norm() + gain(if v.norm() > 0.0 { a.dot(&v) / v.norm() } else { 0.0 });
                if speed > 0.9 * spec.max_speed_mps {
                    let u = v / v.norm();
                    let along = desired.dot(&u);
                    let over = (speed - 0.9 * spec.max_speed_mps) / (0.1 * spec.max_speed_mps);
                    desired -= u * (along.max(0.0) + over * a_max);
                }
            }
            if desired.norm() > a_max {
                desired *= a_max / desired.norm();
            }
            let mut step = desired - a;
            let jmax = spec.max_jerk_mps3 * h;
            if step.norm() > jmax {
                step *= jmax / step.norm();
            }
            let a1 = a + step;
            p += v * h + a * (h * h / 2.0) + (a1 - a) * (h * h / 6.0);
            v += (a + a1) * (h / 2.0);
            a = a1;
            ps.push(p);
            vs.push(v);
            as_.push(a);
        }
        Ok(Self { start_s, h, p: ps, v: vs, a: as_ })
    }

    fn duration_s(&self) -> f64 {
        (self.p.len() - 1) as f64 * self.h
    }

    fn at(&self, t_s: f64) -> Reference {
        let x = (t_s - self.start_s) / self.h;
        let last = self.p.len() - 1;
        if x <= 0.0 || x >= last as f64 {
            let k = if x <= 0.0 { 0 } else { last };
            return Reference {
                position: self.p[k],
                velocity: Vector3::zeros(),
                acceleration: Vector3::zeros(),
            };
        }
        let k = (x.floor() as usize).min(last - 1);
        let tau = t_s - self.start_s - k as f64 * self.h;
        let jerk = (self.a[k + 1] - self.a[k]) / self.h;
        Reference {
            position: self.p[k]
                + self.v[k] * tau
                + self.a[k] * (tau * tau / 2.0)
                + jerk * (tau * tau * tau / 6.0),
            velocity: self.v[k] + self.a[k] * tau + jerk * (tau * tau / 2.0),
            acceleration: self.a[k] + jerk * tau,
        }
    }
}

/// A continuous course of a [`FlightPlan`].
#[derive(Clone, Debug)]
enum Continuous {
    Curve(Curve),
    Walk(Walk),
}

impl FlightPlan {
    /// A plan that hovers `hover_start_s` at the shape's start, flies the whole shape without
    /// stopping at `speed_mps` (raised-cosine ramps of `max_accel_mps2` from and to rest), and
    /// hovers `hover_end_s`. The along-track acceleration stays within `max_accel_mps2` (the
    /// ramps), and so must the across-track `v² κ` (else an error naming the tightest radius;
    /// checked on a 1 cm grid, 0.1 % tolerance). With
    /// `Heading::AlongTrack` the nose follows the horizontal tangent (its rate `v κ_h`); the
    /// yaw limits then bound that rate.
    pub fn continuous(
        shape: Shape,
        speed_mps: f64,
        max_accel_mps2: f64,
        hover_start_s: f64,
        hover_end_s: f64,
        heading: Heading,
    ) -> Result<Self, String> {
        if !(speed_mps > 0.0 && max_accel_mps2 > 0.0 && speed_mps.is_finite()) {
            return Err("path speed and acceleration must be positive".into());
        }
        if !(hover_start_s >= 0.0 && hover_end_s >= 0.0) {
            return Err("hover times must not be negative".into());
        }
        let curve = Curve::new(shape, speed_mps, max_accel_mps2, hover_start_s);
        if curve.length_m() < 0.1 {
            return Err("the course is shorter than 0.1 m".into());
        }
        // Check the across-track acceleration and the yaw rate on a 1 cm grid of the course.
        let v = curve.ramp.speed;
        let (mut worst_k, mut worst_u) = (0.0f64, 0.0);
        let du = curve.shape.u_end() / (curve.table.len() - 1) as f64;
        for i in 0..curve.table.len() {
            let u = du * i as f64;
            let (_, d1, d2) = curve.shape.eval(u);
            let t = d1 / d1.norm();
            let k = ((d2 - t * d2.dot(&t)) / d1.norm_squared()).norm();
            if k > worst_k {
                (worst_k, worst_u) = (k, u);
            }
        }
        let across = v * v * worst_k;
        if across > max_accel_mps2 * (1.0 + 1e-3) {
            let at = curve.shape.eval(worst_u).0;
            return Err(format!(
                "the course turns on a {:.2} m radius near ({:.1}, {:.1}, {:.1}): {v:.2} m/s there \
                 needs {across:.2} m/s² across the track, more than max_accel_mps2 {max_accel_mps2}",
                1.0 / worst_k,
                at.x,
                at.y,
                at.z
            ));
        }
        if let Heading::AlongTrack { max_rate_rad_s, .. } = heading {
            if v * worst_k > max_rate_rad_s * (1.0 + 1e-9) {
                return Err(format!(
                    "nose-first at {v:.2} m/s on a {:.2} m radius turns at {:.0} °/s, more than the \
                     yaw rate limit {:.0} °/s",
                    1.0 / worst_k,
                    (v * worst_k).to_degrees(),
                    max_rate_rad_s.to_degrees()
                ));
            }
        }
        let start = curve.at(0.0).0.position;
        let end = curve.at(f64::INFINITY).0.position;
        let end_s = hover_start_s + curve.ramp.duration_s + hover_end_s;
        Ok(Self {
            legs: Vec::new(),
            turns: Vec::new(),
            heading,
            start,
            end,
            end_s,
            course: Some(Continuous::Curve(curve)),
        })
    }

    /// A random walk ([`WalkSpec`]) after `hover_start_s` of hover, then `hover_end_s` of hover
    /// where it came to rest. The heading is fixed.
    pub fn walk(spec: &WalkSpec, hover_start_s: f64, hover_end_s: f64) -> Result<Self, String> {
        if !(hover_start_s >= 0.0 && hover_end_s >= 0.0) {
            return Err("hover times must not be negative".into());
        }
        let walk = Walk::new(spec, hover_start_s)?;
        let end = *walk.p.last().expect("one sample");
        let end_s = hover_start_s + walk.duration_s() + hover_end_s;
        Ok(Self {
            legs: Vec::new(),
            turns: Vec::new(),
            heading: Heading::Fixed,
            start: spec.start,
            end,
            end_s,
            course: Some(Continuous::Walk(walk)),
        })
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
    use std::f64::consts::{PI, TAU};

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
    /// Integrates a plan's velocity and acceleration on a 1 ms grid against its position and
    /// velocity (the reference is self-consistent), and returns the largest speed, the largest
    /// of the along-track and across-track accelerations, and the largest acceleration step
    /// between successive ms (a jump would show as a large step).
    fn integrate(plan: &FlightPlan) -> (f64, f64, f64) {
        let dt = 1e-3;
        let mut p = plan.at(0.0).position;
        let mut v = plan.at(0.0).velocity;
        let (mut vmax, mut amax, mut step): (f64, f64, f64) = (0.0, 0.0, 0.0);
        let mut t = 0.0;
        while t < plan.duration_s() + 0.5 {
            let (r0, r1) = (plan.at(t), plan.at(t + dt));
            p += (r0.velocity + r1.velocity) * dt / 2.0;
            v += (r0.acceleration + r1.acceleration) * dt / 2.0;
            t += dt;
            assert!(
                (p - r1.position).norm() < 2e-3,
                "position drift at {t}: {}",
                (p - r1.position).norm()
            );
            assert!((v - r1.velocity).norm() < 2e-3, "velocity drift at {t}");
            vmax = vmax.max(r1.velocity.norm());
            let speed = r1.velocity.norm();
            let (along, across) = if speed > 1e-9 {
                let t = r1.velocity / speed;
                let a = r1.acceleration.dot(&t);
                (a.abs(), (r1.acceleration - t * a).norm())
            } else {
                (r1.acceleration.norm(), 0.0)
            };
            amax = amax.max(along).max(across);
            step = step.max((r1.acceleration - r0.acceleration).norm());
        }
        (vmax, amax, step)
    }

    #[test]
    fn circle_at_constant_speed_obeys_the_centripetal_law_and_faces_its_tangent() {
        let (v, r) = (1.5, 4.0);
        let shape = Shape::Circle {
            centre: [10.0, 8.0],
            height_m: 2.0,
            radius_m: r,
            start_rad: -std::f64::consts::FRAC_PI_2,
            sense: 1.0,
            loops: 2,
        };
        let heading = Heading::AlongTrack { max_rate_rad_s: 1.0, max_accel_rad_s2: 2.0 };
        let plan = FlightPlan::continuous(shape, v, 1.0, 2.0, 2.0, heading).unwrap();
        let (vmax, amax, step) = integrate(&plan);
        assert!((vmax - v).abs() < 1e-6, "{vmax}");
        assert!(amax <= 1.0 + 1e-3 && step < 2e-3, "{amax} {step}");
        // Two loops, 2·2π·4 m, plus the ramps' extra time (π v / (2 a)) and the hovers.
        let expected = 2.0 * TAU * r / v + PI * v / 2.0 + 4.0;
        assert!((plan.duration_s() - expected).abs() < 1e-3, "{} {expected}", plan.duration_s());
        let ramp_s = PI * v / 2.0;
        let mut t = 2.0;
        while t < plan.duration_s() {
            let q = plan.at(t);
            let c = Vector3::new(10.0, 8.0, 2.0);
            assert!(((q.position - c).norm() - r).abs() < 1e-6, "off the circle at {t}");
            let h = plan.heading_at(t).unwrap();
            if q.velocity.norm() > 1e-6 {
                let along = q.velocity.y.atan2(q.velocity.x);
                assert!(wrap_pi(h.yaw_rad - along).abs() < 1e-6, "nose off the track at {t}");
            }
            // In cruise: speed v, acceleration v²/r towards the centre, yaw rate v / r.
            if t > 2.0 + ramp_s + 0.1 && t < plan.duration_s() - 2.0 - ramp_s - 0.1 {
                assert!((q.velocity.norm() - v).abs() < 1e-9);
                let inward = (c - q.position) / r;
                assert!((q.acceleration - inward * (v * v / r)).norm() < 1e-6, "at {t}");
                assert!((h.rate_rad_s - v / r).abs() < 1e-6 && h.accel_rad_s2.abs() < 1e-3);
            }
            t += 0.05;
        }
        // The heading integrates to two full turns (unwrapped).
        let (h0, h1) = (plan.heading_at(0.0).unwrap(), plan.heading_at(plan.duration_s()).unwrap());
        assert!((h1.yaw_rad - h0.yaw_rad - 2.0 * TAU).abs() < 1e-6, "{}", h1.yaw_rad - h0.yaw_rad);
        assert!(h0.yaw_rad.abs() < 1e-12); // starts south of the centre heading east
    }

    #[test]
    fn too_tight_a_course_is_refused_with_its_radius() {
        let shape = Shape::Circle {
            centre: [0.0, 0.0],
            height_m: 2.0,
            radius_m: 1.0,
            start_rad: 0.0,
            sense: -1.0,
            loops: 5,
        };
        let e =
            FlightPlan::continuous(shape.clone(), 3.0, 1.0, 0.0, 0.0, Heading::Fixed).unwrap_err();
        assert!(e.contains("1.00 m radius") && e.contains("9.00 m/s²"), "{e}");
        let nose = Heading::AlongTrack { max_rate_rad_s: 1.0, max_accel_rad_s2: 1.0 };
        let e = FlightPlan::continuous(shape, 1.5, 3.0, 0.0, 0.0, nose).unwrap_err();
        assert!(e.contains("yaw rate limit"), "{e}");
    }

    #[test]
    fn figure_eight_crosses_its_centre_and_keeps_its_limits() {
        let shape = Shape::Eight {
            centre: [10.0, 8.0],
            height_m: 2.0,
            length_m: 14.0,
            axis_rad: 0.3,
            loops: 1,
        };
        let plan = FlightPlan::continuous(shape, 1.5, 1.0, 1.0, 1.0, Heading::Fixed).unwrap();
        let (vmax, amax, step) = integrate(&plan);
        assert!((vmax - 1.5).abs() < 1e-6 && amax <= 1.0 + 1e-3 && step < 2e-3, "{amax} {step}");
        // Starts and ends at the crossing, passes it once more mid-way (at speed).
        let c = Vector3::new(10.0, 8.0, 2.0);
        assert!((plan.at(0.0).position - c).norm() < 1e-9);
        assert!((plan.at(plan.duration_s()).position - c).norm() < 1e-6);
        let mid = plan.duration_s() / 2.0;
        let nearest = (0..2000)
            .map(|k| (plan.at(mid - 2.0 + k as f64 * 2e-3).position - c).norm())
            .fold(f64::MAX, f64::min);
        assert!(nearest < 5e-3, "{nearest}");
        // Extent: ±7 m along its axis, ±7/(2√2) m across it.
        let (sa, ca) = 0.3f64.sin_cos();
        let (mut along, mut across): (f64, f64) = (0.0, 0.0);
        for k in 0..4000 {
            let d = plan.at(k as f64 * plan.duration_s() / 4000.0).position - c;
            along = along.max((ca * d.x + sa * d.y).abs());
            across = across.max((-sa * d.x + ca * d.y).abs());
        }
        let half_width = 7.0 / (2.0 * 2f64.sqrt());
        assert!(
            (along - 7.0).abs() < 1e-3 && (across - half_width).abs() < 1e-3,
            "{along} {across}"
        );
    }

    #[test]
    fn smooth_waypoints_pass_every_point_without_stopping_and_climb() {
        let pts = [
            Vector3::new(6.0, 4.0, 1.5),
            Vector3::new(11.0, 3.5, 2.0),
            Vector3::new(15.0, 6.0, 3.0),
            Vector3::new(14.0, 11.0, 2.5),
            Vector3::new(9.0, 13.0, 3.0),
            Vector3::new(5.0, 9.0, 2.0),
            Vector3::new(6.0, 4.0, 1.5),
        ];
        let spline = Spline::through(&pts).unwrap();
        // The spline interpolates its knots.
        for (k, p) in spline.knots.iter().zip(&pts) {
            assert!((spline.eval(*k).0 - p).norm() < 1e-9);
        }
        let plan =
            FlightPlan::continuous(Shape::Spline(spline), 1.5, 1.0, 3.0, 3.0, Heading::Fixed)
                .unwrap();
        let (vmax, amax, step) = integrate(&plan);
        assert!(
            (vmax - 1.5).abs() < 1e-6 && amax <= 1.0 + 1e-3 && step < 2e-3,
            "{vmax} {amax} {step}"
        );
        // Every waypoint is passed (within 1 cm) and, between the first and the last, at speed.
        let ramp_s = PI * 1.5 / 2.0;
        for p in &pts[1..pts.len() - 1] {
            let (mut best, mut at) = (f64::MAX, 0.0);
            let mut t = 0.0;
            while t < plan.duration_s() {
                let d = (plan.at(t).position - p).norm();
                if d < best {
                    (best, at) = (d, t);
                }
                t += 1e-3;
            }
            assert!(best < 0.01, "{p:?} missed by {best}");
            assert!(at > 3.0 + ramp_s && (plan.at(at).velocity.norm() - 1.5).abs() < 1e-9);
        }
        // It climbs and descends: vertical speed both ways.
        let vz: Vec<f64> =
            (0..1000).map(|k| plan.at(k as f64 * plan.duration_s() / 1000.0).velocity.z).collect();
        assert!(vz.iter().cloned().fold(f64::MIN, f64::max) > 0.1);
        assert!(vz.iter().cloned().fold(f64::MAX, f64::min) < -0.1);
        assert!(Spline::through(&[pts[0], pts[0]]).is_none());
    }

    fn walk_spec(seed: u64) -> WalkSpec {
        WalkSpec {
            start: Vector3::new(10.0, 6.0, 2.0),
            area_min: Vector3::new(5.0, 3.0, 1.2),
            area_max: Vector3::new(15.0, 13.0, 3.2),
            wander_s: 60.0,
            tau_s: 2.0,
            max_speed_mps: 2.0,
            max_climb_mps: 0.8,
            max_accel_mps2: 1.0,
            max_jerk_mps3: 3.0,
            seed,
        }
    }

    #[test]
    fn random_walk_stays_within_its_box_speed_acceleration_and_jerk() {
        let mut ends = Vec::new();
        // A taller box from its middle too (a climb correction once overrode the box's braking
        // and seeds 1, 2, 6 and 8 of it left through the floor or the ceiling).
        let tall = |seed| WalkSpec {
            start: Vector3::new(10.0, 10.0, 2.0),
            area_min: Vector3::new(3.0, 3.0, 0.8),
            area_max: Vector3::new(17.0, 17.0, 3.5),
            ..walk_spec(seed)
        };
        for spec in (1..=6).map(walk_spec).chain((1..=10).map(tall)) {
            let seed = spec.seed;
            let plan = FlightPlan::walk(&spec, 2.0, 2.0).unwrap();
            let (vmax, amax, step) = integrate(&plan);
            assert!(vmax <= spec.max_speed_mps + 1e-9, "seed {seed}: {vmax}");
            assert!(amax <= spec.max_accel_mps2 + 1e-9, "seed {seed}: {amax}");
            // Jerk: acceleration moves at most max_jerk · 1 ms per ms.
            assert!(step <= spec.max_jerk_mps3 * 1e-3 + 1e-9, "seed {seed}: {step}");
            let (mut moving, mut vz_max): (f64, f64) = (0.0, 0.0);
            let mut t = 0.0;
            while t < plan.duration_s() {
                let q = plan.at(t);
                for i in 0..3 {
                    assert!(
                        q.position[i] >= spec.area_min[i] && q.position[i] <= spec.area_max[i],
                        "seed {seed}: out of the box at {t}: {:?}",
                        q.position
                    );
                }
                vz_max = vz_max.max(q.velocity.z.abs());
                if q.velocity.norm() > 0.5 {
                    moving += 0.01;
                }
                t += 0.01;
            }
            assert!(vz_max <= spec.max_climb_mps + 1e-9, "seed {seed}: {vz_max}");
            // It does wander (most of the time above 0.5 m/s) and ends at rest.
            assert!(moving > 0.5 * spec.wander_s, "seed {seed}: moving {moving} s");
            let end = plan.at(plan.duration_s());
            assert!(end.velocity.norm() < 1e-3);
            ends.push(end.position);
        }
        // Different seeds, different courses.
        assert!((ends[0] - ends[1]).norm() > 0.1);
        let bad = WalkSpec { area_max: Vector3::new(15.0, 13.0, 2.0), ..walk_spec(1) };
        assert!(FlightPlan::walk(&bad, 0.0, 0.0).unwrap_err().contains("area_max"));
    }
}
