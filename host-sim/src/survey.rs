//! The calibration flight of a site: what an installer flies, with a reference beside it, to
//! calibrate the arrays' zenith (`aim calibrate`, [`aim_tracker::zenith`]).
//!
//! The same room, arrays, obstacles, noise and drone as the scenario; only the flight is
//! replaced: from each array, straight spokes out to the room's walls (ending 1 m short of the
//! wall along the spoke, at most [`SPOKE_MAX_M`] long) and back, every 45° of azimuth, at two heights
//! ([`SURVEY_HEIGHTS_M`], lowered under a low ceiling), at [`SURVEY_SPEED_MPS`]. It covers the
//! zeniths a drone is seen at in that room without following any flight the tracker is later
//! scored on. [`calibrate`] simulates it with a seed of its own and fits the arrays'
//! corrections from its frames and its truth track exactly as `aim calibrate` does (the truth
//! standing for the installer's reference).

use nalgebra::Vector3;

use crate::path::{FlightPlan, Heading};
use crate::scenario::Scenario;

/// Heights of the spokes above the floor, m.
pub const SURVEY_HEIGHTS_M: [f64; 2] = [1.0, 2.5];
/// Cruise speed of the survey, m/s.
pub const SURVEY_SPEED_MPS: f64 = 2.0;
/// Longest spoke, horizontal m.
pub const SPOKE_MAX_M: f64 = 14.0;
/// Where each spoke starts, horizontal m from the array.
pub const SPOKE_START_M: f64 = 1.5;
/// Shortest spoke worth flying, horizontal m from the array.
pub const SPOKE_MIN_M: f64 = 3.0;
/// How far the spokes stay from the walls and the ceiling, m.
pub const WALL_MARGIN_M: f64 = 1.0;

/// Horizontal distance from `(x, y)` along azimuth `az` (rad, from +x towards +y) to the
/// boundary of the box `[0, lx] × [0, ly]`.
fn to_wall(x: f64, y: f64, az: f64, lx: f64, ly: f64) -> f64 {
    let (s, c) = az.sin_cos();
    let mut d = f64::INFINITY;
    if c > 1e-9 {
        d = d.min((lx - x) / c);
    } else if c < -1e-9 {
        d = d.min(-x / c);
    }
    if s > 1e-9 {
        d = d.min((ly - y) / s);
    } else if s < -1e-9 {
        d = d.min(-y / s);
    }
    d
}

/// The survey's waypoints for `scenario` (ENU m): spokes from every array, at every height.
pub fn waypoints(scenario: &Scenario) -> Vec<Vector3<f64>> {
    let (lx, ly, lz) = match &scenario.room {
        Some(r) => (r.size_m[0], r.size_m[1], r.size_m[2]),
        None => (f64::INFINITY, f64::INFINITY, f64::INFINITY),
    };
    let ceiling = (lz - WALL_MARGIN_M).max(0.5);
    let mut out = Vec::new();
    for &h in &SURVEY_HEIGHTS_M {
        let h = h.min(ceiling);
        for a in &scenario.arrays {
            let (x, y) = (a.position_m.x, a.position_m.y);
            for k in 0..8 {
                let az = (22.5 + 45.0 * f64::from(k)).to_radians();
                let far = (to_wall(x, y, az, lx, ly) - WALL_MARGIN_M).min(SPOKE_MAX_M);
                if far < SPOKE_MIN_M {
                    continue;
                }
                let (s, c) = az.sin_cos();
                let at = |d: f64| Vector3::new(x + d * c, y + d * s, h);
                out.extend([at(SPOKE_START_M), at(far), at(SPOKE_START_M)]);
            }
        }
    }
    out
}

/// The scenario with its flight replaced by the survey and its seed by `seed`.
pub fn survey_scenario(scenario: &Scenario, seed: u64) -> Result<Scenario, String> {
    let points = waypoints(scenario);
    if points.len() < 2 {
        return Err(format!(
            "{}: the room leaves no spoke of {SPOKE_MIN_M} m or more for the zenith survey",
            scenario.name
        ));
    }
    let plan = FlightPlan::new(&points, SURVEY_SPEED_MPS, 1.0, 2.0, 0.5, 2.0, Heading::Fixed)?;
    let mut s = scenario.clone();
    s.name = format!("{}-zenith-survey", scenario.name);
    s.description = format!("zenith calibration survey of {}", scenario.name);
    s.seed = seed;
    s.duration_s = plan.duration_s();
    s.yaw_rad = 0.0;
    s.plan = plan;
    Ok(s)
}

/// Simulates the survey of `scenario` with `seed` (`threads` worker threads, 0: all cores) and
/// fits every array's zenith correction
/// from its frames (link bytes in link order, through the intake) against its truth track, as
/// `aim calibrate frames-<id>.aimraw --reference truth.csv --site site.toml` does. Returns the
/// corrections by array id, the fits and the survey's files (site text, truth CSV, each
/// array's link bytes) for storing.
pub fn calibrate(scenario: &Scenario, seed: u64, threads: usize) -> anyhow::Result<Survey> {
    let survey = survey_scenario(scenario, seed).map_err(anyhow::Error::msg)?;
    let (sim, links) = crate::eval::link::simulate_links(
        &survey,
        &crate::Options { threads },
        &indicatif::ProgressBar::hidden(),
        crate::DEFAULT_FULL_SCALE_PA,
    )?;
    let site_text = sim.site.to_toml()?;
    let truth_csv = sim.truth.to_csv();
    let array_ids = sim.arrays.iter().map(|a| u16::from(a.id)).collect();
    Survey::fit(site_text, truth_csv, array_ids, links)
}

/// A simulated survey and what it gave.
pub struct Survey {
    /// The survey's site file (uncalibrated).
    pub site_text: String,
    /// Its truth track, `truth.csv` (the reference).
    pub truth_csv: String,
    /// The arrays' ids, in scenario order.
    pub array_ids: Vec<u16>,
    /// Each array's link bytes, in scenario order.
    pub links: Vec<Vec<u8>>,
    /// Each array's fit.
    pub fits: Vec<aim_tracker::zenith::Fit>,
}

impl Survey {
    /// Fits each array's correction from a survey's files, as `aim calibrate` does: each
    /// array's link bytes through the intake, against the truth track as the reference.
    pub fn fit(
        site_text: String,
        truth_csv: String,
        array_ids: Vec<u16>,
        links: Vec<Vec<u8>>,
    ) -> anyhow::Result<Self> {
        use aim_tracker::zenith;
        let site = aim_tracker::site::Site::parse(&site_text, std::path::Path::new("site.toml"))?;
        let reference = zenith::Reference::parse(&truth_csv, std::path::Path::new("truth.csv"))?;
        let obstacles =
            aim_tracker::site::obstacles(&site_text, std::path::Path::new("site.toml"))?;
        let mut fits = Vec::new();
        for bytes in &links {
            let mut source = aim_tracker::link::FrameSource::new(bytes.as_slice());
            let bearings = zenith::bearings_of(&site, &mut source)?;
            let config = zenith::FitConfig::default();
            fits.extend(zenith::calibrate(&site, &obstacles, &bearings, &reference, config));
        }
        Ok(Survey { site_text, truth_csv, array_ids, links, fits })
    }

    /// Reads a survey stored by `host-sim fly --zenith-survey` or `bench` (`site.toml`,
    /// `truth.csv`, `frames-<id>.aimraw` of every array of the site) and fits it again.
    pub fn load(dir: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context as _;
        let read = |name: &str| {
            std::fs::read(dir.join(name))
                .with_context(|| format!("reading {}", dir.join(name).display()))
        };
        let site_text = String::from_utf8(read("site.toml")?).context("site.toml is not UTF-8")?;
        let truth_csv = String::from_utf8(read("truth.csv")?).context("truth.csv is not UTF-8")?;
        let site = aim_tracker::site::Site::parse(&site_text, &dir.join("site.toml"))?;
        let array_ids: Vec<u16> = site.arrays.iter().map(|a| a.id).collect();
        let links = array_ids
            .iter()
            .map(|id| read(&format!("frames-{id}.aimraw")))
            .collect::<anyhow::Result<_>>()?;
        Self::fit(site_text, truth_csv, array_ids, links)
    }

    /// The corrections by array id (arrays whose fit gave no point left out).
    pub fn corrections(&self) -> Vec<(u16, aim_tracker::zenith::ZenithCorrection)> {
        self.fits
            .iter()
            .filter(|f| !f.correction.is_empty())
            .map(|f| (f.array_id, f.correction.clone()))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spokes_stay_inside_the_room_and_skip_the_near_walls() {
        let s = Scenario::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/square10-los.toml"),
        )
        .unwrap();
        let w = waypoints(&s);
        let room = s.room.as_ref().unwrap().size_m;
        // The margin is along each spoke, whose azimuths are 22.5° off an axis at least: a
        // wall is at least WALL_MARGIN_M · cos 67.5° away across.
        let m = WALL_MARGIN_M * 67.5f64.to_radians().cos() - 1e-9;
        assert!(w
            .iter()
            .all(|p| { (m..=room[0] - m).contains(&p.x) && (m..=room[1] - m).contains(&p.y) }));
        // The array sits 2 m from the south wall: the two spokes straight at it (247.5° and
        // 292.5°) are too short; the six others, 3 points each, at two heights.
        assert_eq!(w.len(), 6 * 3 * 2, "{w:?}");
        let a = s.arrays[0].position_m;
        let far = w.iter().map(|p| (p.x - a.x).hypot(p.y - a.y)).fold(0.0, f64::max);
        assert!((far - SPOKE_MAX_M).abs() < 1e-9, "{far}");
        let survey = survey_scenario(&s, 7).unwrap();
        assert_eq!(survey.seed, 7);
        assert!(survey.duration_s > 60.0, "{}", survey.duration_s);
    }
}
