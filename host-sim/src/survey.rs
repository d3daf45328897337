//! The calibration flight of a site: what an installer flies, with a reference beside it, to
//! calibrate the arrays' zenith (`aim calibrate`, [`aim_tracker::zenith`]).
//!
//! The same room, arrays, obstacles and noise as the scenario; the drone is the installer's
//! own calibration drone (a nominal DJI Mini 2 whatever type the scenario flies, so no scored
//! airframe reaches the correction), and the flight is replaced: from each array, straight spokes out to the room's walls (ending 1 m short of the
//! wall along the spoke, at most [`SPOKE_MAX_M`] long) and back, every 45° of azimuth, at two heights
//! ([`SURVEY_HEIGHTS_M`], lowered under a low ceiling), at [`SURVEY_SPEED_MPS`]. It covers the
//! zeniths a drone is seen at in that room without following any flight the tracker is later
//! scored on. [`calibrate`] simulates it with a seed of its own and fits the arrays'
//! corrections from its frames exactly as `aim calibrate` does, against the installer's
//! reference: the truth track with the errors of a real one ([`REFERENCE_SIGMA_M`] of
//! position noise per row, a time offset drawn within ±[`REFERENCE_MAX_OFFSET_S`] per survey).

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
/// Standard deviation of the reference's position error per axis and row, m (a total station
/// tracking a prism, or motion capture, does better; marked spots with noted times worse).
pub const REFERENCE_SIGMA_M: f64 = 0.02;
/// Largest offset of the reference's clock against the arrays' time base, s (the offset of a
/// survey is drawn uniformly within ±this from its seed).
pub const REFERENCE_MAX_OFFSET_S: f64 = 0.05;

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
    s.drone = crate::profile::DroneProfile::dji_mini_2();
    s.population = crate::profile::Population::default();
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
/// from its frames (link bytes in link order, through the intake) against the installer's
/// reference ([`reference_of`]), as `aim calibrate frames-<id>.aimraw --reference reference.csv
/// --site site.toml` does. Returns the corrections by array id, the fits and the survey's files
/// (site text, truth and reference CSV, each array's link bytes) for storing.
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
    let reference_csv = reference_of(&sim.truth, seed);
    let array_ids = sim.arrays.iter().map(|a| u16::from(a.id)).collect();
    Survey::fit(Some(seed), site_text, truth_csv, reference_csv, array_ids, links)
}

/// The installer's reference of a survey flown with `seed`: `t,x,y,z` of the truth track, each
/// position with [`REFERENCE_SIGMA_M`] of Gaussian error per axis, every time off by one offset
/// drawn uniformly within ±[`REFERENCE_MAX_OFFSET_S`].
pub fn reference_of(truth: &crate::truth::Truth, seed: u64) -> String {
    use rand::{Rng, SeedableRng};
    use std::fmt::Write as _;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x2EF0_5E7E_11CE_0FF5);
    let offset = rng.random_range(-REFERENCE_MAX_OFFSET_S..=REFERENCE_MAX_OFFSET_S);
    let mut out = String::from("t,x,y,z\n");
    for r in &truth.rows {
        let mut p = r.position;
        for v in &mut p {
            // Box–Muller: one normal deviate per axis.
            let (u1, u2): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
            *v += REFERENCE_SIGMA_M * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        }
        let _ = writeln!(out, "{:.4},{:.4},{:.4},{:.4}", r.t_s + offset, p[0], p[1], p[2]);
    }
    out
}

/// A simulated survey and what it gave.
pub struct Survey {
    /// The survey's site file (uncalibrated).
    pub site_text: String,
    /// The seed it was flown with (None: a stored survey that did not say).
    pub seed: Option<u64>,
    /// Its truth track, `truth.csv` (scoring only).
    pub truth_csv: String,
    /// The installer's reference, `reference.csv` ([`reference_of`]): what the fit uses.
    pub reference_csv: String,
    /// The arrays' ids, in scenario order.
    pub array_ids: Vec<u16>,
    /// Each array's link bytes, in scenario order.
    pub links: Vec<Vec<u8>>,
    /// Each array's fit.
    pub fits: Vec<aim_tracker::zenith::Fit>,
}

impl Survey {
    /// Fits each array's correction from a survey's files, as `aim calibrate` does: each
    /// array's link bytes through the intake, against the reference.
    pub fn fit(
        seed: Option<u64>,
        site_text: String,
        truth_csv: String,
        reference_csv: String,
        array_ids: Vec<u16>,
        links: Vec<Vec<u8>>,
    ) -> anyhow::Result<Self> {
        use aim_tracker::zenith;
        let site = aim_tracker::site::Site::parse(&site_text, std::path::Path::new("site.toml"))?;
        let reference =
            zenith::Reference::parse(&reference_csv, std::path::Path::new("reference.csv"))?;
        let obstacles =
            aim_tracker::site::obstacles(&site_text, std::path::Path::new("site.toml"))?;
        let mut fits = Vec::new();
        for bytes in &links {
            let mut source = aim_tracker::link::FrameSource::new(bytes.as_slice());
            let (bearings, _) = zenith::bearings_of(&site, &mut source)?;
            let config = zenith::FitConfig::default();
            // The checks `aim calibrate` makes of a reference.
            if let Some(check) =
                zenith::time_check(&site, &obstacles, &bearings, &reference, config.bin_deg)
            {
                check.verdict("the survey's reference.csv").map_err(anyhow::Error::msg)?;
            }
            fits.extend(zenith::calibrate(&site, &obstacles, &bearings, &reference, config));
        }
        Ok(Survey { seed, site_text, truth_csv, reference_csv, array_ids, links, fits })
    }

    /// Reads a survey stored by `host-sim fly --zenith-survey` or `bench` (`survey.toml` with
    /// its seed, `site.toml`, `reference.csv`, `truth.csv`, `frames-<id>.aimraw` of every array
    /// of the site) and fits it again. A survey stored without `reference.csv` is refused (it
    /// would be fitted against the truth); one without `survey.toml` has no seed.
    pub fn load(dir: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context as _;
        let read = |name: &str| {
            std::fs::read(dir.join(name))
                .with_context(|| format!("reading {}", dir.join(name).display()))
        };
        let site_text = String::from_utf8(read("site.toml")?).context("site.toml is not UTF-8")?;
        let truth_csv = String::from_utf8(read("truth.csv")?).context("truth.csv is not UTF-8")?;
        if !dir.join("reference.csv").is_file() {
            anyhow::bail!(
                "{} has no reference.csv: a survey stored before session 28 was fitted against \
                 the exact truth, which no installer has; remove that zenith-survey directory \
                 to survey again",
                dir.display()
            );
        }
        let reference_csv =
            String::from_utf8(read("reference.csv")?).context("reference.csv is not UTF-8")?;
        let seed = if dir.join("survey.toml").is_file() {
            let text =
                String::from_utf8(read("survey.toml")?).context("survey.toml is not UTF-8")?;
            #[derive(serde::Deserialize)]
            #[serde(deny_unknown_fields)]
            struct Stored {
                seed: u64,
            }
            let stored: Stored = toml::from_str(&text)
                .with_context(|| format!("reading {}", dir.join("survey.toml").display()))?;
            Some(stored.seed)
        } else {
            None
        };
        let site = aim_tracker::site::Site::parse(&site_text, &dir.join("site.toml"))?;
        let array_ids: Vec<u16> = site.arrays.iter().map(|a| a.id).collect();
        let links = array_ids
            .iter()
            .map(|id| read(&format!("frames-{id}.aimraw")))
            .collect::<anyhow::Result<_>>()?;
        Self::fit(seed, site_text, truth_csv, reference_csv, array_ids, links)
    }

    /// [`Survey::load`], refused if the survey says it was flown with a seed other than `seed`
    /// (a stored survey reused for a suite or flight that asks for another). One that does not
    /// say its seed is returned as it is, `seed` None.
    pub fn load_seeded(dir: &std::path::Path, seed: u64) -> anyhow::Result<Self> {
        let survey = Self::load(dir)?;
        match survey.seed {
            Some(s) if s != seed => {
                anyhow::bail!("{} was surveyed with seed {s}, not {seed}", dir.display())
            }
            _ => Ok(survey),
        }
    }

    /// Writes the survey to `dir` (created) as [`Survey::load`] reads it: its seed
    /// (`survey.toml`), site file, the installer's reference (`reference.csv`), the truth
    /// (`truth.csv`, scoring only), each array's frames (`frames-<id>.aimraw`, in scenario order)
    /// and the calibrated site file `site-calibrated.toml`: `aim calibrate frames-<id>.aimraw
    /// --reference reference.csv --site site.toml` gives the same.
    pub fn store(&self, dir: &std::path::Path) -> anyhow::Result<()> {
        use anyhow::Context as _;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let write = |name: &str, bytes: &[u8]| {
            std::fs::write(dir.join(name), bytes)
                .with_context(|| format!("writing {}", dir.join(name).display()))
        };
        match self.seed {
            Some(seed) => write(
                "survey.toml",
                format!("# The zenith survey's seed (host_sim::survey).\nseed = {seed}\n")
                    .as_bytes(),
            )?,
            // No seed to store: an older survey.toml in `dir` would name another survey's.
            None => {
                let _ = std::fs::remove_file(dir.join("survey.toml"));
            }
        }
        write("site.toml", self.site_text.as_bytes())?;
        write("truth.csv", self.truth_csv.as_bytes())?;
        write("reference.csv", self.reference_csv.as_bytes())?;
        for (id, bytes) in self.array_ids.iter().zip(&self.links) {
            write(&format!("frames-{id}.aimraw"), bytes)?;
        }
        let calibrated = aim_tracker::zenith::site_with_corrections(
            &self.site_text,
            &dir.join("site.toml"),
            &self.corrections(),
        )?;
        write("site-calibrated.toml", calibrated.as_bytes())
    }

    /// The corrections by array id (empty for an array whose fit gave no point: a site file
    /// written with them has no correction for it, not an older one).
    pub fn corrections(&self) -> Vec<(u16, aim_tracker::zenith::ZenithCorrection)> {
        self.fits.iter().map(|f| (f.array_id, f.correction.clone())).collect()
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
