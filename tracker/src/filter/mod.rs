//! The two filters that turn per-step cues into positions (ALGORITHMS.md §8).
//!
//! Both see exactly the same [`Step`]s: the smoothed DoA and the LoS decision of the array,
//! the motion class and the acoustic speeds. `paper` is the paper's position-only Kalman
//! filter fed with per-step coordinates (the baseline); `aim` is a Gaussian mixture of EKFs on
//! position and velocity with bearing, speed and motion-class updates.

pub mod aim;
pub mod ekf;
pub mod paper;
pub mod triangulation;

use crate::doa::DoaState;
use crate::dynamics::AcousticSpeed;
use crate::motion::MotionClass;
use crate::site::{ArrayPose, Room};

/// Which filter to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterKind {
    /// The paper's position-only Kalman filter on per-step coordinates.
    Paper,
    /// Position–velocity EKF mixture with bearing, speed and motion-class updates.
    Aim,
    /// The DoA rays of every array intersected at each step (several arrays; the paper's
    /// distributed baseline).
    Triangulate,
}

impl std::str::FromStr for FilterKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "paper" => Ok(FilterKind::Paper),
            "aim" => Ok(FilterKind::Aim),
            "triangulate" => Ok(FilterKind::Triangulate),
            other => {
                Err(format!("unknown filter `{other}` (expected `paper`, `aim` or `triangulate`)"))
            }
        }
    }
}

/// One range difference from an inter-array delay (ALGORITHMS.md §9): at time `t` the drone
/// was `range_difference_m` farther from point `p` than from point `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RangeDifference {
    /// Time the delay describes (the centre of its correlation window, on the tracked
    /// array's time base), s.
    pub t: f64,
    /// Where array p hears (its microphones' centre), world m.
    pub p: [f64; 3],
    /// Where array q hears, world m.
    pub q: [f64; 3],
    /// |S − p| − |S − q| = c·T_pq, m.
    pub range_difference_m: f64,
    /// Standard deviation, m.
    pub sigma_m: f64,
    /// Half width of the window the delay was searched in, m (a wrong peak lies anywhere in
    /// it).
    pub span_m: f64,
}

/// Everything a filter may use at one output instant.
#[derive(Clone, Debug)]
pub struct Step<'a> {
    /// Output time, s.
    pub t: f64,
    /// Time since the previous step, s.
    pub dt: f64,
    /// The array whose bearings drive the track.
    pub array: &'a ArrayPose,
    /// Raw bearings of the site's other arrays heard since the previous step (each given
    /// once, at most `stale_s` old), with their arrays' poses
    /// ([`crate::tracker::TrackerConfig::fuse_arrays`]); empty with one array.
    pub others: Vec<(&'a ArrayPose, crate::observation::Bearing)>,
    /// Range differences from inter-array delays measured since the previous step (each
    /// given once); empty without a beacon clock and snippets.
    pub range_differences: Vec<RangeDifference>,
    /// The DoA window's state, if it has one (LoS or not).
    pub doa: Option<DoaState>,
    /// Line-of-sight decision (false without DoA).
    pub los: bool,
    /// Motion class.
    pub motion: MotionClass,
    /// Speeds from the dynamics.
    pub speed: AcousticSpeed,
    /// The flight volume, if the site gives it.
    pub room: Option<Room>,
    /// Once a wake cue of the leg has settled: the horizontal speeds read from the cruise BPF
    /// frames heard since the previous step, one per frame and cue (thrust excess, front/rear
    /// split; see [`crate::wake`]), with standard deviations (m/s), each given once (the leg
    /// mean in `speed` re-uses every frame at every step). `None` before either settles.
    pub cruise_speeds: Option<Vec<(f64, f64)>>,
    /// The BPF frames heard since the previous step, each as its centre frequency
    /// ([`crate::doppler::FrameCentre`]), for the Doppler cue.
    pub doppler: Vec<crate::doppler::DopplerFrame>,
    /// Each new spectrum frame's change of the relative front/rear BPF split against hover
    /// and its standard deviation (dimensionless), during a settled horizontal leg, when the
    /// profile has no wake coefficient and the tracker learns the gain online
    /// ([`crate::tracker::TrackerConfig::online_wake_gain`]); `None` otherwise.
    pub wake_splits: Option<Vec<(f64, f64)>>,
    /// Speed of sound at the site, m/s.
    pub speed_of_sound_mps: f64,
}

/// A filter's output at one step.
#[derive(Clone, Debug)]
pub struct Estimate {
    /// Position, world ENU m.
    pub position: [f64; 3],
    /// Velocity, m/s.
    pub velocity: [f64; 3],
    /// Covariance of the position (3×3, m²).
    pub position_covariance: nalgebra::Matrix3<f64>,
    /// Other arrays' measurements (bearings, range differences) went into this estimate at
    /// this step: its range is observed by crossing, not inferred by one array.
    pub crossed: bool,
}

/// A tracking filter.
pub trait Filter {
    /// Consumes one step; returns the estimate, or `None` before the first usable bearing.
    fn step(&mut self, step: &Step) -> Option<Estimate>;
}

/// A new filter of the given kind.
pub fn new_filter(kind: FilterKind) -> Box<dyn Filter + Send> {
    match kind {
        FilterKind::Paper => Box::new(paper::PaperFilter::default()),
        FilterKind::Aim => Box::new(aim::AimFilter::default()),
        FilterKind::Triangulate => Box::new(triangulation::TriangulationFilter::default()),
    }
}

/// Unit vector of the smoothed DoA in the world frame.
pub fn world_direction(array: &ArrayPose, doa: &DoaState) -> [f64; 3] {
    array.to_world(crate::observation::unit_vector(doa.azimuth_rad, doa.zenith_rad))
}

/// The farthest range along a world direction from `origin` that stays inside the room,
/// however far (`default` applies only without a room, or along a ray that leaves it
/// nowhere).
pub fn max_range_in_room(origin: [f64; 3], dir: [f64; 3], room: Option<Room>, default: f64) -> f64 {
    let Some(room) = room else { return default };
    // The room bounds the range however large it is (a cap of `default` inside a 50 m hall
    // kept every hypothesis short of a drone 35 m away).
    let mut best = f64::INFINITY;
    for i in 0..3 {
        if dir[i].abs() > 1e-9 {
            let bound = if dir[i] > 0.0 { room.max[i] } else { room.min[i] };
            let r = (bound - origin[i]) / dir[i];
            if r > 0.0 {
                best = best.min(r);
            }
        }
    }
    if best.is_finite() {
        best.max(0.5)
    } else {
        default
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The range to the wall along a ray (oracle: the geometry of the box), however far;
    /// the default only without a room.
    #[test]
    fn the_room_bounds_the_range_however_far() {
        let room = Some(Room { min: [0.0; 3], max: [50.0, 50.0, 8.0] });
        let d = std::f64::consts::FRAC_1_SQRT_2;
        let r = max_range_in_room([5.0, 5.0, 0.05], [d, d, 0.0], room, 25.0);
        assert!((r - 45.0 * std::f64::consts::SQRT_2).abs() < 1e-9, "{r}");
        // Up: the ceiling, 7.95 m away.
        let r = max_range_in_room([5.0, 5.0, 0.05], [0.0, 0.0, 1.0], room, 25.0);
        assert!((r - 7.95).abs() < 1e-9, "{r}");
        assert_eq!(max_range_in_room([5.0, 5.0, 0.05], [d, d, 0.0], None, 25.0), 25.0);
    }
}
