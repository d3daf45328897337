//! The paper's baseline (§V-A, §V-C; ALGORITHMS.md §6–§8): per-step coordinates S = h·w from
//! the corrected eq. (5) solved over a window, eq. (6) for vertical motion, fused by a Kalman
//! filter whose state is the position only.
//!
//! Height h (along the array normal) comes from the horizontal displacement the dynamics give
//! and the change of w = (tan φ cos α, tan φ sin α, 1) it causes at constant height:
//! h·|w_j − w_i|_xy = Σ_{steps i..j} (v_h τ + ½ a_h τ²) (eq. 5 summed over the steps of a
//! chord of about `chord_s`). Single 0.1 s steps move w by less than its noise, so each LoS
//! step of a horizontal run gives one chord back to a step `chord_s` earlier of the same run,
//! the chords of the last `window_chords` are referred to the present height by the vertical
//! displacement since (eq. 6: h changes by v_v τ + ½ a_v τ² during vertical motion), the
//! interquartile-range rule (§7) drops the outlying per-chord solutions, and the rest give h by
//! least squares. The DoA the chords use is the IQR-smoothed window state of the array.
//!
//! The Kalman filter predicts with the acoustic displacement (the dynamics' speed along the
//! last heading the bearings showed, or the vertical speed) and, in line of sight, fuses the
//! per-step coordinate S = h·w; without line of sight the DoA is dropped and the track is dead
//! reckoned (paper step 3). The yaw ambiguity of step 4 is not modelled.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Vector3};

use super::{max_range_in_room, Estimate, Filter, Step};
use crate::iqr::iqr_inliers;
use crate::linalg::symmetrized;
use crate::motion::MotionClass;

/// Tunables of the baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct PaperConfig {
    /// Height along the array normal assumed until the first chords measure it, m.
    pub initial_height_m: f64,
    /// Span of one chord of eq. (5), s.
    pub chord_s: f64,
    /// Chords shorter than this in |Δw|_xy (dimensionless) are not used: noise dominates.
    pub min_chord: f64,
    /// Chords kept for the least-squares height (the newest), count.
    pub window_chords: usize,
    /// Random-walk density of the position, m²/s.
    pub q: f64,
    /// Standard deviation of a per-step coordinate in line of sight, m.
    pub sigma_los_m: f64,
    /// Standard deviation of the first coordinate (height not yet measured), m.
    pub sigma_initial_m: f64,
}

impl Default for PaperConfig {
    fn default() -> Self {
        Self {
            initial_height_m: 1.5,
            chord_s: 1.5,
            min_chord: 0.05,
            window_chords: 40,
            q: 0.5,
            sigma_los_m: 0.5,
            sigma_initial_m: 2.0,
        }
    }
}

/// One output step as the height solver keeps it.
#[derive(Clone, Copy, Debug)]
struct Record {
    t: f64,
    /// w in the array frame, in line of sight only.
    w: Option<[f64; 3]>,
    /// Horizontal path length flown so far, m (eq. 5's right-hand side, summed).
    path_m: f64,
    /// Index of the horizontal run the step belongs to (`None` outside horizontal motion).
    run: Option<u64>,
}

/// One chord of eq. (5): |Δw|_xy, the path flown along it, and the rise at its end.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Chord {
    dw: f64,
    path_m: f64,
    rise_m: f64,
}

/// Height along the array normal from chords of eq. (5), least squares over a window with the
/// IQR rule on the per-chord solutions, referred to the present by eq. (6).
#[derive(Clone, Debug, Default)]
pub struct HeightSolver {
    records: VecDeque<Record>,
    chords: VecDeque<Chord>,
    path_m: f64,
    rise_m: f64,
    run: u64,
    in_run: bool,
}

impl HeightSolver {
    /// Adds one step: its class, its duration `dt` (s), the dynamics' horizontal speed (m/s)
    /// and acceleration (m/s²), the vertical velocity along the array normal (m/s) and, in line
    /// of sight, w in the array frame. Returns whether a new chord was formed.
    #[allow(clippy::too_many_arguments)]
    pub fn push(
        &mut self,
        config: &PaperConfig,
        t: f64,
        dt: f64,
        motion: MotionClass,
        speed_h: f64,
        accel_h: f64,
        speed_normal: f64,
        w: Option<[f64; 3]>,
    ) -> bool {
        let horizontal = motion == MotionClass::Horizontal;
        if horizontal {
            self.path_m += (speed_h * dt + 0.5 * accel_h * dt * dt).max(0.0);
            if !self.in_run {
                self.run += 1;
            }
        }
        if motion == MotionClass::Vertical {
            self.rise_m += speed_normal * dt;
        }
        self.in_run = horizontal;
        let run = horizontal.then_some(self.run);
        let record = Record { t, w, path_m: self.path_m, run };
        while self.records.front().is_some_and(|r| r.t < t - 2.0 * config.chord_s) {
            self.records.pop_front();
        }
        let mut formed = false;
        if let (Some(run), Some(w1)) = (run, w) {
            // The newest step of the same run at least `chord_s` back.
            let start =
                self.records.iter().rev().find(|r| {
                    r.t <= t - config.chord_s + 1e-9 && r.w.is_some() && r.run == Some(run)
                });
            if let Some(r0) = start {
                let w0 = r0.w.unwrap_or(w1);
                let dw = (w1[0] - w0[0]).hypot(w1[1] - w0[1]);
                let path_m = self.path_m - r0.path_m;
                if dw >= config.min_chord && path_m > 0.0 && dw.is_finite() {
                    self.chords.push_back(Chord { dw, path_m, rise_m: self.rise_m });
                    while self.chords.len() > config.window_chords.max(1) {
                        self.chords.pop_front();
                    }
                    formed = true;
                }
            }
        }
        self.records.push_back(record);
        formed
    }

    /// The present height, m, or `None` before any chord.
    pub fn height(&self) -> Option<f64> {
        if self.chords.is_empty() {
            return None;
        }
        // Each chord's own solution, referred to now by the rise since.
        let now: Vec<f64> =
            self.chords.iter().map(|c| c.path_m / c.dw + (self.rise_m - c.rise_m)).collect();
        let keep = if now.len() >= 4 { iqr_inliers(&now) } else { vec![true; now.len()] };
        let (num, den) = self
            .chords
            .iter()
            .zip(&now)
            .zip(&keep)
            .filter(|(_, k)| **k)
            .fold((0.0, 0.0), |(n, d), ((c, h), _)| (n + c.dw * c.dw * h, d + c.dw * c.dw));
        (den > 0.0).then(|| num / den)
    }

    /// Vertical displacement along the array normal since the start, m.
    pub fn rise_m(&self) -> f64 {
        self.rise_m
    }

    /// Number of chords in the window.
    pub fn chords(&self) -> usize {
        self.chords.len()
    }
}

/// Position-only Kalman filter on per-step coordinates.
#[derive(Clone, Debug, Default)]
pub struct PaperFilter {
    config: PaperConfig,
    state: Option<([f64; 3], Matrix3<f64>)>,
    solver: HeightSolver,
    /// Recent LoS coordinates (t, position) for the heading.
    recent: VecDeque<(f64, [f64; 3])>,
    /// Unit horizontal heading, world.
    heading: [f64; 2],
}

impl PaperFilter {
    /// A filter with explicit tunables.
    pub fn new(config: PaperConfig) -> Self {
        Self { config, ..Self::default() }
    }

    /// The present height estimate along the array normal, m (the prior before any chord).
    pub fn height(&self) -> f64 {
        self.solver
            .height()
            .unwrap_or(self.config.initial_height_m + self.solver.rise_m())
            .clamp(0.2, 50.0)
    }
}

/// w = (tan φ cos α, tan φ sin α, 1) of a smoothed DoA (array frame); `None` at or below the
/// array's plane.
fn w_of(azimuth_rad: f64, zenith_rad: f64) -> Option<[f64; 3]> {
    (zenith_rad < 88f64.to_radians()).then(|| {
        let tz = zenith_rad.max(0.0).tan();
        [tz * azimuth_rad.cos(), tz * azimuth_rad.sin(), 1.0]
    })
}

impl Filter for PaperFilter {
    fn step(&mut self, step: &Step) -> Option<Estimate> {
        let c = self.config.clone();
        let normal_up = step.array.to_world([0.0, 0.0, 1.0])[2];
        let w = step.doa.and_then(|d| w_of(d.azimuth_rad, d.zenith_rad));
        let s = step.speed;
        let los_w = if step.los { w } else { None };
        self.solver.push(
            &c,
            step.t,
            step.dt,
            step.motion,
            s.horizontal,
            s.horizontal_accel,
            s.vertical * normal_up,
            los_w,
        );
        let mut h = self.height();
        // The coordinate of eq. (5)/(6), kept inside the room when the site gives it.
        let coordinate = |w: [f64; 3], h: &mut f64| {
            let dir = step.array.to_world(w);
            let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
            let unit = [dir[0] / norm, dir[1] / norm, dir[2] / norm];
            let r_max = max_range_in_room(step.array.position, unit, step.room, f64::INFINITY);
            *h = h.min(r_max / norm);
            let p = step.array.position;
            [p[0] + *h * dir[0], p[1] + *h * dir[1], p[2] + *h * dir[2]]
        };
        let Some((x, p)) = self.state.take() else {
            // The first fix from the first DoA, LoS or not (the paper initialises A_0 from the
            // first points of the flight).
            let z = coordinate(w?, &mut h);
            let p = Matrix3::identity() * c.sigma_initial_m.powi(2);
            self.state = Some((z, p));
            return Some(Estimate {
                position: z,
                velocity: [0.0; 3],
                position_covariance: p,
                crossed: false,
            });
        };
        // Predict with the acoustic displacement.
        let u = match step.motion {
            MotionClass::Horizontal => {
                let d =
                    (s.horizontal * step.dt + 0.5 * s.horizontal_accel * step.dt.powi(2)).max(0.0);
                [self.heading[0] * d, self.heading[1] * d, 0.0]
            }
            MotionClass::Vertical => [0.0, 0.0, s.vertical * step.dt],
            MotionClass::Hover | MotionClass::Yaw => [0.0; 3],
        };
        let x_pred = [x[0] + u[0], x[1] + u[1], x[2] + u[2]];
        let p_pred = p + Matrix3::identity() * (c.q * step.dt);
        let (x_new, p_new) = match los_w {
            Some(w) => {
                let z = coordinate(w, &mut h);
                let r = Matrix3::identity() * c.sigma_los_m.powi(2);
                let k = p_pred * (p_pred + r).try_inverse()?;
                let y = Vector3::new(z[0] - x_pred[0], z[1] - x_pred[1], z[2] - x_pred[2]);
                let dx = k * y;
                let i_k = Matrix3::identity() - k;
                let p = symmetrized(&(i_k * p_pred * i_k.transpose() + k * r * k.transpose()));
                ([x_pred[0] + dx[0], x_pred[1] + dx[1], x_pred[2] + dx[2]], p)
            }
            None => (x_pred, p_pred),
        };
        // The heading of horizontal motion from the LoS track over about a chord.
        if step.motion == MotionClass::Horizontal && los_w.is_some() {
            self.recent.push_back((step.t, x_new));
            while self.recent.front().is_some_and(|r| r.0 < step.t - c.chord_s) {
                self.recent.pop_front();
            }
            if let Some(&(_, first)) = self.recent.front() {
                let (dx, dy) = (x_new[0] - first[0], x_new[1] - first[1]);
                let d = dx.hypot(dy);
                if d > 0.05 {
                    self.heading = [dx / d, dy / d];
                }
            }
        } else if step.motion != MotionClass::Horizontal {
            self.recent.clear();
        }
        let velocity = if step.dt > 0.0 {
            [(x_new[0] - x[0]) / step.dt, (x_new[1] - x[1]) / step.dt, (x_new[2] - x[2]) / step.dt]
        } else {
            [0.0; 3]
        };
        self.state = Some((x_new, p_new));
        Some(Estimate { position: x_new, velocity, position_covariance: p_new, crossed: false })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::AcousticSpeed;
    use crate::observation::angles_of;
    use crate::site::ArrayPose;
    use crate::testutil::{doa, Rng};

    /// Bearing noise of the smoothed DoA, rad (0.5°, the LoS level of the DoA window).
    const NOISE: f64 = 0.5 * std::f64::consts::PI / 180.0;

    /// w of a drone at `pos` relative to an upward array at the origin, with bearing noise.
    fn w_seen(pos: [f64; 3], rng: &mut Rng) -> [f64; 3] {
        let (az, zen) = angles_of(pos);
        w_of(az + NOISE * rng.normal(), zen + NOISE * rng.normal()).expect("above the array")
    }

    /// A straight leg at `height` m above the array, 1.5 m/s along +x from (−4, 3), in 0.1 s
    /// steps for `seconds`; `outlier` replaces the w of that step by a wild one.
    fn leg(solver: &mut HeightSolver, height: f64, seconds: f64, outlier: Option<usize>) {
        let config = PaperConfig::default();
        let mut rng = Rng::new(5);
        let (v, dt) = (1.5, 0.1);
        for k in 0..(seconds / dt) as usize {
            let t = k as f64 * dt;
            let pos = [-4.0 + v * t, 3.0, height];
            let w = if outlier == Some(k) { [4.0, -6.0, 1.0] } else { w_seen(pos, &mut rng) };
            solver.push(&config, t, dt, MotionClass::Horizontal, v, 0.0, 0.0, Some(w));
        }
    }

    #[test]
    fn windowed_eq5_recovers_the_height_of_a_constant_height_leg() {
        // Eq. (5) at constant height: h·|Δw|_xy is the path flown. Over 1.5 s chords the 0.5°
        // bearing noise moves |Δw| by about 2 % (Δw ≈ 1.1 at 2 m), and 40 chords average it down.
        for height in [1.0, 2.0, 3.5] {
            let mut solver = HeightSolver::default();
            leg(&mut solver, height, 6.0, None);
            assert!(solver.chords() >= 30, "{} chords", solver.chords());
            let h = solver.height().expect("chords formed");
            assert!((h / height - 1.0).abs() < 0.03, "height {height} m: solved {h} m");
        }
        // Single 0.1 s steps (the old solution) move w by less than its noise: each step's own
        // solution scatters far more than the window's.
        let mut rng = Rng::new(5);
        let solutions: Vec<f64> = (0..40)
            .map(|k| {
                let t = k as f64 * 0.1;
                let w0 = w_seen([-4.0 + 1.5 * t, 3.0, 2.0], &mut rng);
                let w1 = w_seen([-4.0 + 1.5 * (t + 0.1), 3.0, 2.0], &mut rng);
                0.15 / (w1[0] - w0[0]).hypot(w1[1] - w0[1])
            })
            .collect();
        let spread = solutions.iter().map(|h| (h - 2.0).abs()).sum::<f64>() / 40.0;
        assert!(spread > 0.1, "single steps scatter only {spread} m");
    }

    #[test]
    fn the_iqr_rule_drops_a_wild_bearing() {
        // One wild DoA in the leg spoils the two chords it ends and starts; the IQR rule on the
        // per-chord solutions drops them.
        let mut solver = HeightSolver::default();
        leg(&mut solver, 2.0, 6.0, Some(40));
        let now: Vec<f64> = solver.chords.iter().map(|c| c.path_m / c.dw).collect();
        let wild = now.iter().filter(|h| (*h / 2.0 - 1.0).abs() > 0.5).count();
        assert!(wild >= 1, "the outlier spoilt no chord: {now:?}");
        let h = solver.height().expect("chords formed");
        assert!((h / 2.0 - 1.0).abs() < 0.03, "solved {h} m");
        // Without the rule (plain least squares over the same chords) the outlier shows.
        let (num, den) = solver
            .chords
            .iter()
            .fold((0.0, 0.0), |(n, d), c| (n + c.dw * c.path_m, d + c.dw * c.dw));
        assert!((num / den / 2.0 - 1.0).abs() > 0.05, "plain LS {} m", num / den);
    }

    #[test]
    fn eq6_carries_the_height_through_a_climb() {
        // A leg at 2 m, then a 1.2 m climb at 0.6 m/s (eq. 6), then hover: the height now is
        // 3.2 m though every chord was measured at 2 m.
        let config = PaperConfig::default();
        let mut solver = HeightSolver::default();
        leg(&mut solver, 2.0, 6.0, None);
        for k in 0..20 {
            let t = 6.0 + 0.1 * k as f64;
            solver.push(&config, t, 0.1, MotionClass::Vertical, 0.0, 0.0, 0.6, None);
        }
        solver.push(&config, 8.0, 0.1, MotionClass::Hover, 0.0, 0.0, 0.0, None);
        let h = solver.height().expect("chords formed");
        assert!((h - 3.2).abs() < 0.07, "solved {h} m");
        // A new leg at the new height joins the same window without bias.
        let mut rng = Rng::new(9);
        for k in 0..60 {
            let t = 8.1 + 0.1 * k as f64;
            let pos = [3.0 - 1.5 * 0.1 * k as f64, -2.0, 3.2];
            let w = w_seen(pos, &mut rng);
            solver.push(&config, t, 0.1, MotionClass::Horizontal, 1.5, 0.0, 0.0, Some(w));
        }
        let h = solver.height().expect("chords formed");
        assert!((h - 3.2).abs() < 0.1, "solved {h} m");
    }

    #[test]
    fn the_filter_tracks_a_leg_and_dead_reckons_without_line_of_sight() {
        // Hover 2 s at an unknown height (the prior is 1.5 m, the drone at 2.5 m), a leg of
        // 8 s at 1.5 m/s, the last 2 s of it without line of sight (DoA dropped, dead
        // reckoned along the heading the bearings showed).
        let array = ArrayPose::new(0, [0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
        let mut filter = PaperFilter::default();
        let mut rng = Rng::new(3);
        let dt = 0.1;
        let mut errors = Vec::new();
        for k in 0..100 {
            let t = k as f64 * dt;
            let moving = t >= 2.0;
            let pos = [-5.0 + if moving { 1.5 * (t - 2.0) } else { 0.0 }, 4.0, 2.5];
            let los = t < 8.0;
            let step = Step {
                others: Vec::new(),
                range_differences: Vec::new(),
                t,
                dt,
                array: &array,
                doa: Some(doa(t, pos, &mut rng)),
                los,
                motion: if moving { MotionClass::Horizontal } else { MotionClass::Hover },
                speed: AcousticSpeed {
                    horizontal: if moving { 1.5 } else { 0.0 },
                    horizontal_sigma: 0.1,
                    vertical: 0.0,
                    vertical_sigma: 0.05,
                    horizontal_accel: 0.0,
                    accelerating: false,
                },
                room: None,
                cruise_speeds: None,
                wake_splits: None,
                doppler: Vec::new(),
                speed_of_sound_mps: 343.2,
            };
            let est = filter.step(&step).expect("a fix from the first DoA");
            errors.push((
                t,
                crate::observation::norm([
                    est.position[0] - pos[0],
                    est.position[1] - pos[1],
                    est.position[2] - pos[2],
                ]),
            ));
        }
        // Before any chord the prior height puts the hover 40 % short along its ray.
        assert!(errors[10].1 > 1.0, "{errors:?}");
        // Once chords have measured the height, in line of sight and after 2 s of dead
        // reckoning.
        for &(t, e) in errors.iter().filter(|(t, _)| *t >= 6.0) {
            assert!(e < 0.35, "{e} m at {t} s");
        }
        assert!((filter.height() - 2.5).abs() < 0.1, "{}", filter.height());
    }
}
