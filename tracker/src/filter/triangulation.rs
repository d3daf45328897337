//! The DoA-ray triangulation baseline of the paper's distributed evaluation (§VII-D, Fig. 23):
//! at each step, the point closest to the rays along every array's latest bearing
//! ([`crate::multi::triangulate`]). No dynamics: what several arrays give
//! by geometry alone, to set beside the `aim` filter on the same frames.

use std::collections::BTreeMap;

use nalgebra::Matrix3;

use super::{Estimate, Filter, Step};
use crate::multi::triangulate::{ray_from_doa, triangulate, Ray};

/// A bearing older than this is not used, s.
pub const STALE_S: f64 = 1.0;
/// Rays closer than this to parallel give no point (the last one is held), rad.
pub const MIN_ANGLE_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// The triangulation baseline: the tracked array's smoothed DoA (in line of sight) and each
/// other array's latest raw bearing (at most [`STALE_S`] old), intersected; the last point held
/// while they give none.
#[derive(Clone, Debug, Default)]
pub struct TriangulationFilter {
    /// Latest bearing per array id as (its time, s; its ray).
    latest: BTreeMap<u16, (f64, Ray)>,
    /// The last estimate and the time of its point, s.
    last: Option<(f64, Estimate)>,
}

impl Filter for TriangulationFilter {
    fn step(&mut self, step: &Step) -> Option<Estimate> {
        if let (true, Some(d)) = (step.los, step.doa) {
            let ray = ray_from_doa(step.array, d.azimuth_rad, d.zenith_rad, 1.0);
            self.latest.insert(step.array.id, (step.t, ray));
        }
        for (pose, b) in &step.others {
            let ray = ray_from_doa(pose, b.azimuth_rad, b.zenith_rad, 1.0);
            self.latest.insert(pose.id, (b.t, ray));
        }
        self.latest.retain(|_, v| step.t - v.0 <= STALE_S);
        let rays: Vec<Ray> = self.latest.values().map(|(_, ray)| *ray).collect();
        let Ok(point) = triangulate(&rays, MIN_ANGLE_RAD) else {
            // Held where it was, not moving.
            return self.last.as_ref().map(|(_, e)| Estimate {
                velocity: [0.0; 3],
                crossed: false,
                ..e.clone()
            });
        };
        let mut position = point.position;
        if let Some(room) = step.room {
            for (i, p) in position.iter_mut().enumerate() {
                *p = p.clamp(room.min[i], room.max[i]);
            }
        }
        // Over the time since the last point (longer than a step after held steps).
        let velocity = match &self.last {
            Some((t, last)) if step.t > *t => {
                std::array::from_fn(|i| (position[i] - last.position[i]) / (step.t - t))
            }
            _ => [0.0; 3],
        };
        // The rays' scatter about the point as its spread (at least 0.1 m).
        let var = point.rms_distance_m.max(0.1).powi(2);
        // Rays of at least two arrays (the tracked one's may be stale or out of LoS).
        let estimate = Estimate {
            position,
            velocity,
            position_covariance: Matrix3::identity() * var,
            crossed: rays.len() >= 2,
        };
        self.last = Some((step.t, estimate.clone()));
        Some(estimate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::AcousticSpeed;
    use crate::motion::MotionClass;
    use crate::observation::Bearing;
    use crate::site::ArrayPose;
    use crate::testutil::exact_bearing;

    #[test]
    fn exact_bearings_meet_at_the_drone_and_a_lone_one_holds_the_last_point() {
        // Three arrays, one facing down from a ceiling, one turned; the drone moves. Oracle: the
        // drone's position (exact bearings cross there).
        let tracked = ArrayPose::new(1, [0.0, 0.0, 0.05], 0.3, 0.0, 0.0);
        let others = [
            ArrayPose::new(2, [10.0, 0.0, 0.05], -1.0, 0.0, 0.0),
            ArrayPose::new(3, [5.0, 10.0, 5.5], 0.5, std::f64::consts::PI, 0.0),
        ];
        let mut filter = TriangulationFilter::default();
        let speed = AcousticSpeed {
            horizontal: 0.0,
            horizontal_sigma: 1.0,
            vertical: 0.0,
            vertical_sigma: 1.0,
            horizontal_accel: 0.0,
            accelerating: false,
        };
        let mut rng = crate::testutil::Rng::new(3);
        let mut step_at = |t: f64, drone: [f64; 3], with_others: bool| {
            let mut doa = crate::testutil::doa(t, drone, &mut rng);
            let exact = exact_bearing(&tracked, drone, t);
            (doa.azimuth_rad, doa.zenith_rad) = (exact.azimuth_rad, exact.zenith_rad);
            let others: Vec<(&ArrayPose, Bearing)> = if with_others {
                others.iter().map(|a| (a, exact_bearing(a, drone, t))).collect()
            } else {
                Vec::new()
            };
            let step = Step {
                t,
                dt: 0.1,
                array: &tracked,
                others,
                doa: Some(doa),
                los: true,
                motion: MotionClass::Horizontal,
                speed,
                room: None,
                cruise_speeds: None,
                wake_splits: None,
                range_differences: Vec::new(),
                doppler: Vec::new(),
                speed_of_sound_mps: 343.0,
            };
            filter.step(&step)
        };
        let mut last = [0.0; 3];
        for k in 0..10 {
            let t = 0.1 * f64::from(k);
            let drone = [3.0 + 1.5 * t, 4.0, 2.0];
            let e = step_at(t, drone, true).expect("three rays");
            let error = crate::observation::norm(std::array::from_fn(|i| e.position[i] - drone[i]));
            assert!(error < 1e-6, "{t}: {:?} against {drone:?}", e.position);
            last = e.position;
        }
        // Two seconds later only the tracked array is heard: the others have gone stale, one
        // ray gives no point, and the last one is held.
        let e = step_at(3.0, [9.0, 4.0, 2.0], false).expect("held");
        assert_eq!((e.position, e.velocity), (last, [0.0; 3]));
        // Heard again: the velocity spans the time since the last point (2.2 s), not one step.
        let e = step_at(3.1, [9.0, 4.0, 2.0], true).expect("three rays");
        let expected = (9.0 - last[0]) / 2.2;
        assert!((e.velocity[0] - expected).abs() < 1e-6, "{:?} against {expected}", e.velocity);
    }
}
