//! Scenarios: TOML files under `host-sim/scenarios/` describing a flight, the room, obstacles,
//! noise and arrays. `Scenario::load` reads and checks one; every problem is reported with the
//! file (and, where the TOML parser knows it, the line and column).
//!
//! A file may name a `base = "other.toml"` (relative to itself): the base is read first and
//! this file's tables are merged into it key by key; arrays of tables (`[[array]]`, `[[noise]]`,
//! `[[obstacle]]`) replace the base's list as a whole. Sweeps are written this way.
//!
//! Keys (units in the names; defaults in brackets):
//!
//! ```toml
//! name = "square10-los"            # [file stem]
//! description = "..."
//! seed = 1                         # [1] every random draw derives from it
//! sample_rate_hz = 48000           # [48000]
//! duration_s = 40.0                # [the flight plan's duration]
//! truth_rate_hz = 100.0            # [100]
//! [air]       temperature_c = 20.0, humidity_percent = 50.0, pressure_pa = 101325.0
//! [drone]     preset = "dji-mini-2", plus any `DroneProfile` field to override it
//! [airframe]  the population each run's airframe is drawn from (`profile::Population`; all
//!             [0] = the nominal airframe): wake_spread (±fraction of the wake slope),
//!             wake_curvature_per_mps, cg_offset_mm (largest CG offset), thrust_spread (±fraction
//!             per motor), jitter_spread (±fraction per rotor), chipped_probability,
//!             chipped_thrust_loss [0.03], chipped_line_db [10]
//! [path]      kind = "square" | "waypoints" | "hover" | "smooth" | "circle" | "eight" | "walk"
//!             square: side_m, start = [x, y], height_m, clockwise [false], loops [1]
//!             waypoints: points = [[x, y, z], ...];  hover: position = [x, y, z]
//!             (square and waypoints stop at every corner; the kinds below never stop)
//!             smooth: points = [[x, y, z], ...] flown as one smooth spline (heights may change)
//!             circle: centre = [x, y], radius_m, height_m, start_deg [-90] (start point's angle
//!             from the centre), clockwise [false], loops [1]
//!             eight: centre = [x, y], length_m, height_m, axis_deg [0], loops [1] (lemniscate of
//!             Bernoulli: width length_m / 2√2, tightest radius length_m / 6)
//!             walk (hand-flown random walk, fixed heading): position = [x, y, z] (start),
//!             area_min = [x, y, z], area_max = [x, y, z], wander_s [40], walk_tau_s [2],
//!             max_climb_mps [1], max_jerk_mps3 [3 × max_accel_mps2]; speed_mps is its top speed
//!             speed_mps [1.5], max_accel_mps2 [1.0], hover_start_s [3], corner_pause_s [0.5],
//!             hover_end_s [3], heading = "fixed" | "along-track" ["fixed"]
//!             fixed: yaw_deg [0], the heading held throughout
//!             along-track: nose first, turning at each corner (`path` module docs) with
//!             yaw_rate_dps [90] (peak yaw rate) and yaw_accel_dps2 [180] (peak yaw acceleration)
//! [room]      size_m = [Lx, Ly, Lz], absorption = α or [x0, x1, y0, y1, floor, ceiling] [0.2],
//!             reflection_order [1] (0..=12), rt60_s (instead of absorption: all walls alike,
//!             absorbing so that the image model's T30 is rt60_s, `reverb`), late_tail [true with rt60_s, else false] (the
//!             reflections above reflection_order as a statistical tail, `reverb`)
//!             (no [room]: free field)
//! [[obstacle]] name, min = [x, y, z], max = [x, y, z], loss_db [20]
//! [[noise]]   position = [x, y, z], centre_hz, bandwidth_hz [100], spl_db, distance_m [1]
//! [diffuse_noise] spl_db, low_hz [100], high_hz [8000], directions [32]
//! [[beacon]]  id [index + 1], position = [x, y, z], level_db [60] (RMS dB SPL at 1 m),
//!             period_s [1], clock_drift_ppm [0] (the speaker's own clock; truth only),
//!             start_s [0.5] (true time of the first emission) (`beacon`)
//! [[array]]   id, geometry ["respeaker-6mic"] or positions = [[x, y], ...], position = [x, y, z],
//!             yaw_deg [0], facing = "up" | "down" ["up"] (down: under a ceiling or shelf, turned
//!             over about its x axis), clock_offset_s [0], clock_drift_ppm [0], self_noise_db [35],
//!             gain_mismatch_db [0.3], phase_mismatch_us [2], dead_mics [[]] (indices of
//!             microphones that output 0), stuck_mics [[]] (indices stuck at a constant 5 Pa),
//!             link_down_s = [from, to] [none] (the link is down then, s of the array's clock:
//!             its frames are lost, the board runs on)
//! [render]    rotor_sources = "each" | "direct" | "centre" ["direct"], block_samples [128],
//!             control_rate_hz [1000], diffraction_ref_hz [500], absorption [true]
//! ```
use std::path::{Path, PathBuf};

use aim_tracker::config::Coords;
use anyhow::{anyhow, bail, Context as _};
use nalgebra::Vector3;
use serde::Deserialize;

use crate::air::Air;
use crate::array::{preset_positions, ArrayConfig, Clock, GEOMETRY_PRESETS};
use crate::noise::{DiffuseNoise, NoiseSource};
use crate::obstacle::Obstacle;
use crate::path::{square, FlightPlan, Heading, Shape, Spline, WalkSpec};

/// Default peak yaw rate of nose-first flight, °/s. DJI lists the Mini 2's maximum angular
/// velocity as 130 °/s (Sport mode); its Normal mode turns at about 60 °/s; 90 °/s is between.
pub const DEFAULT_YAW_RATE_DPS: f64 = 90.0;
/// Default peak yaw acceleration of nose-first flight, °/s². Not published; chosen so a 90°
/// turn of the simulated DJI Mini 2 (I_z 7.5e-4 kg·m², k_h/k_v 12 mm) needs about ±8 % of hover
/// thrust between odd and even rotors (±4 % rotor speed), well inside the motors' headroom.
pub const DEFAULT_YAW_ACCEL_DPS2: f64 = 180.0;
use crate::profile::{DroneProfile, Population};
use crate::room::Room;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileAir {
    #[serde(default = "d_temp")]
    temperature_c: f64,
    #[serde(default = "d_hum")]
    humidity_percent: f64,
    #[serde(default = "d_press")]
    pressure_pa: f64,
}
fn d_temp() -> f64 {
    20.0
}
fn d_hum() -> f64 {
    50.0
}
fn d_press() -> f64 {
    101_325.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FilePath {
    kind: String,
    side_m: Option<f64>,
    start: Option<Coords<2>>,
    height_m: Option<f64>,
    #[serde(default)]
    clockwise: bool,
    #[serde(default = "d_one")]
    loops: u32,
    points: Option<Vec<Coords<3>>>,
    position: Option<Coords<3>>,
    #[serde(default = "d_speed")]
    speed_mps: f64,
    #[serde(default = "d_one_f")]
    max_accel_mps2: f64,
    #[serde(default = "d_hover")]
    hover_start_s: f64,
    #[serde(default = "d_pause")]
    corner_pause_s: f64,
    #[serde(default = "d_hover")]
    hover_end_s: f64,
    yaw_deg: Option<f64>,
    centre: Option<Coords<2>>,
    radius_m: Option<f64>,
    start_deg: Option<f64>,
    length_m: Option<f64>,
    axis_deg: Option<f64>,
    area_min: Option<Coords<3>>,
    area_max: Option<Coords<3>>,
    wander_s: Option<f64>,
    walk_tau_s: Option<f64>,
    max_climb_mps: Option<f64>,
    max_jerk_mps3: Option<f64>,
    heading: Option<String>,
    yaw_rate_dps: Option<f64>,
    yaw_accel_dps2: Option<f64>,
}
fn d_one() -> u32 {
    1
}
fn d_one_f() -> f64 {
    1.0
}
fn d_speed() -> f64 {
    1.5
}
fn d_hover() -> f64 {
    3.0
}
fn d_pause() -> f64 {
    0.5
}

/// `room.absorption`: one coefficient for every surface, or six.
enum Absorption {
    All(f64),
    Each([f64; 6]),
}

impl<'de> Deserialize<'de> for Absorption {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Absorption;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(
                    "a number (every surface) or an array of 6 numbers (walls x = 0, x = Lx, \
                     y = 0, y = Ly, floor, ceiling)",
                )
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Absorption, E> {
                Ok(Absorption::All(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Absorption, E> {
                Ok(Absorption::All(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Absorption, E> {
                Ok(Absorption::All(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<Absorption, A::Error> {
                // A wrong count names the surface order (this visitor's wording), not only 6.
                aim_tracker::config::exactly_from_seq(seq, &self).map(Absorption::Each)
            }
        }
        d.deserialize_any(Visitor)
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileAirframe {
    wake_spread: Option<f64>,
    wake_curvature_per_mps: Option<f64>,
    cg_offset_mm: Option<f64>,
    thrust_spread: Option<f64>,
    jitter_spread: Option<f64>,
    chipped_probability: Option<f64>,
    chipped_thrust_loss: Option<f64>,
    chipped_line_db: Option<f64>,
}

impl FileAirframe {
    fn population(&self) -> Result<Population, String> {
        let d = Population::default();
        let p = Population {
            wake_spread: self.wake_spread.unwrap_or(d.wake_spread),
            wake_curvature_per_mps: self.wake_curvature_per_mps.unwrap_or(d.wake_curvature_per_mps),
            cg_offset_m: self.cg_offset_mm.map_or(d.cg_offset_m, |mm| mm * 1e-3),
            thrust_spread: self.thrust_spread.unwrap_or(d.thrust_spread),
            jitter_spread: self.jitter_spread.unwrap_or(d.jitter_spread),
            chipped_probability: self.chipped_probability.unwrap_or(d.chipped_probability),
            chipped_thrust_loss: self.chipped_thrust_loss.unwrap_or(d.chipped_thrust_loss),
            chipped_line_db: self.chipped_line_db.unwrap_or(d.chipped_line_db),
        };
        p.validate()
            .map_err(|e| e.replace("airframe.cg_offset_m", "airframe.cg_offset_mm (in m)"))?;
        Ok(p)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRoom {
    size_m: Coords<3>,
    absorption: Option<Absorption>,
    #[serde(default = "d_one")]
    reflection_order: u32,
    rt60_s: Option<f64>,
    late_tail: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileObstacle {
    name: Option<String>,
    min: Coords<3>,
    max: Coords<3>,
    #[serde(default = "d_loss")]
    loss_db: f64,
}
fn d_loss() -> f64 {
    20.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileNoise {
    position: Coords<3>,
    centre_hz: f64,
    #[serde(default = "d_bw")]
    bandwidth_hz: f64,
    spl_db: f64,
    #[serde(default = "d_one_f")]
    distance_m: f64,
}
fn d_bw() -> f64 {
    100.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileBeacon {
    id: Option<u8>,
    position: Coords<3>,
    #[serde(default = "d_beacon_level")]
    level_db: f64,
    #[serde(default = "d_one_f")]
    period_s: f64,
    #[serde(default)]
    clock_drift_ppm: f64,
    #[serde(default = "d_beacon_start")]
    start_s: f64,
}
fn d_beacon_level() -> f64 {
    60.0
}
fn d_beacon_start() -> f64 {
    0.5
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDiffuse {
    spl_db: f64,
    #[serde(default = "d_low")]
    low_hz: f64,
    #[serde(default = "d_high")]
    high_hz: f64,
    #[serde(default = "d_dirs")]
    directions: usize,
}
fn d_low() -> f64 {
    100.0
}
fn d_high() -> f64 {
    8000.0
}
fn d_dirs() -> usize {
    32
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileArray {
    id: u8,
    geometry: Option<String>,
    positions: Option<Vec<Coords<2>>>,
    position: Coords<3>,
    #[serde(default)]
    yaw_deg: f64,
    facing: Option<String>,
    #[serde(default)]
    clock_offset_s: f64,
    #[serde(default)]
    clock_drift_ppm: f64,
    #[serde(default = "d_self_noise")]
    self_noise_db: f64,
    #[serde(default = "d_gain_mm")]
    gain_mismatch_db: f64,
    #[serde(default = "d_phase_mm")]
    phase_mismatch_us: f64,
    #[serde(default)]
    dead_mics: Vec<usize>,
    #[serde(default)]
    stuck_mics: Vec<usize>,
    link_down_s: Option<Coords<2>>,
}
fn d_self_noise() -> f64 {
    35.0
}
fn d_gain_mm() -> f64 {
    0.3
}
fn d_phase_mm() -> f64 {
    2.0
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileRender {
    rotor_sources: Option<RotorSources>,
    block_samples: Option<usize>,
    control_rate_hz: Option<f64>,
    diffraction_ref_hz: Option<f64>,
    absorption: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    name: Option<String>,
    #[serde(default)]
    description: String,
    #[allow(dead_code)] // consumed before deserialization; listed so the key is accepted
    base: Option<String>,
    #[serde(default = "d_seed")]
    seed: u64,
    #[serde(default = "d_fs")]
    sample_rate_hz: u32,
    duration_s: Option<f64>,
    #[serde(default = "d_truth")]
    truth_rate_hz: f64,
    air: Option<FileAir>,
    drone: toml::Table,
    #[serde(default)]
    airframe: FileAirframe,
    path: FilePath,
    room: Option<FileRoom>,
    #[serde(default)]
    obstacle: Vec<FileObstacle>,
    #[serde(default)]
    noise: Vec<FileNoise>,
    diffuse_noise: Option<FileDiffuse>,
    #[serde(default)]
    beacon: Vec<FileBeacon>,
    #[serde(default)]
    array: Vec<FileArray>,
    #[serde(default)]
    render: FileRender,
}
fn d_seed() -> u64 {
    1
}
fn d_fs() -> u32 {
    48_000
}
fn d_truth() -> f64 {
    100.0
}

/// How the rotors radiate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RotorSources {
    /// Each rotor is a point source at its hub on every path (cost grows with the rotor count).
    Each,
    /// Each rotor at its hub on the straight path, which the array hears first and strongest;
    /// on reflected and diffracted paths, weaker and later, all rotors radiate from the centre
    /// of mass (moving a hub to the centre changes a path by at most the arm length). The
    /// default: about the cost of two `centre` renders.
    Direct,
    /// All rotors radiate from the centre of mass (N times cheaper; no inter-rotor phase).
    Centre,
}

/// Rendering settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Render {
    /// How the rotors radiate.
    pub rotor_sources: RotorSources,
    /// Output samples per block of delay/gain interpolation.
    pub block_samples: usize,
    /// Flight controller and log rate, Hz.
    pub control_rate_hz: f64,
    /// Reference frequency of the diffraction loss, Hz.
    pub diffraction_ref_hz: f64,
    /// Whether air absorption is simulated.
    pub absorption: bool,
}

/// A checked scenario, ready to simulate.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Name (the file stem unless given).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The file it came from, if any.
    pub source: Option<PathBuf>,
    /// Seed of every random draw.
    pub seed: u64,
    /// Nominal sample rate of the arrays, Hz.
    pub sample_rate_hz: u32,
    /// Simulated duration from t = 0, s.
    pub duration_s: f64,
    /// Rate of the truth rows, Hz.
    pub truth_rate_hz: f64,
    /// The air.
    pub air: Air,
    /// The drone (its profile).
    pub drone: DroneProfile,
    /// The population each run's airframe is drawn from (seeded by `seed`).
    pub population: Population,
    /// Its flight plan.
    pub plan: FlightPlan,
    /// Heading it holds, rad (with `heading = "along-track"`, the plan's initial heading; the
    /// plan then steers it).
    pub yaw_rad: f64,
    /// The room (None: free field).
    pub room: Option<Room>,
    /// Obstacles.
    pub obstacles: Vec<Obstacle>,
    /// Point noise sources.
    pub noise: Vec<NoiseSource>,
    /// Diffuse noise.
    pub diffuse_noise: Option<DiffuseNoise>,
    /// Synchronisation beacon loudspeakers.
    pub beacons: Vec<crate::beacon::BeaconSpeaker>,
    /// Arrays.
    pub arrays: Vec<ArrayConfig>,
    /// Rendering settings.
    pub render: Render,
}

/// A TOML syntax or type error as one line, `FILE:LINE: message`
/// ([`aim_tracker::config::toml_error`], as the tracker's own files report them).
pub fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> anyhow::Error {
    anyhow::Error::new(aim_tracker::config::toml_error(text, path, e))
}

/// Whether following `base` links from `from` (at most 8) comes back to `to`.
fn base_loops_to(from: &Path, to: &Path) -> bool {
    let Ok(target) = to.canonicalize() else { return false };
    let mut at = from.to_path_buf();
    for _ in 0..8 {
        if at.canonicalize().is_ok_and(|p| p == target) {
            return true;
        }
        let Some(next) = std::fs::read_to_string(&at)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .and_then(|t| t.get("base").and_then(|b| b.as_str().map(String::from)))
        else {
            return false;
        };
        at = at.parent().unwrap_or(Path::new(".")).join(next);
    }
    false
}

/// Reads `path` as a TOML table, following `base` links (at most 8 deep).
fn load_table(path: &Path, depth: usize) -> anyhow::Result<(toml::Table, bool)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| toml_error(path, &text, &e))?;
    let Some(base) = table.get("base") else { return Ok((table, false)) };
    if depth >= 8 {
        bail!("{}: `base` chain longer than 8 files", path.display());
    }
    let base =
        base.as_str().ok_or_else(|| anyhow!("{}: `base` must be a file name", path.display()))?;
    let base_path = path.parent().unwrap_or(Path::new(".")).join(base);
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same(&base_path, path) || (depth == 0 && base_loops_to(&base_path, path)) {
        bail!("{}: its `base` chain ({}) loops back to it", path.display(), base_path.display());
    }
    let (mut merged, _) = load_table(&base_path, depth + 1)
        .with_context(|| format!("{}: reading its base {}", path.display(), base_path.display()))?;
    merge(&mut merged, table);
    merged.remove("base");
    merged.remove("name");
    Ok((merged, true))
}

/// Merges `over` into `base`: tables recursively, everything else (arrays included) replaced.
fn merge(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

impl Scenario {
    /// Reads and checks a scenario file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let (table, based) = load_table(path, 0)?;
        let file: File = if based {
            table.try_into().map_err(|e: toml::de::Error| {
                // The merged table has no lines: a wrong type in this file's own keys is
                // found, with its line, by reading the file alone (its missing keys are the
                // base's to give, so a missing field there says nothing).
                let text = std::fs::read_to_string(path).unwrap_or_default();
                match toml::from_str::<File>(&text) {
                    Err(own) if !own.message().starts_with("missing field") => {
                        toml_error(path, &text, &own)
                    }
                    _ => {
                        anyhow!("{} (merged with its base): {}", path.display(), e.message().trim())
                    }
                }
            })?
        } else {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            toml::from_str(&text).map_err(|e| toml_error(path, &text, &e))?
        };
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let mut s = Self::from_file(file, stem).map_err(|e| {
            let text = std::fs::read_to_string(path).unwrap_or_default();
            match key_line(&text, &e) {
                Some(line) => anyhow!("{}:{line}: {e}", path.display()),
                None => anyhow!("{}: {e}", path.display()),
            }
        })?;
        s.source = Some(path.to_path_buf());
        Ok(s)
    }

    /// Reads and checks a scenario file as [`Scenario::load`] does, with its `seed` replaced by
    /// `seed` and the keys of `overrides` merged over its tables (e.g. an `[airframe]` table
    /// from a bench suite). Every seed-dependent part (a random walk's course, the airframe
    /// drawn) follows the new seed.
    pub fn load_with(path: &Path, seed: u64, overrides: &toml::Table) -> anyhow::Result<Self> {
        let (mut table, _) = load_table(path, 0)?;
        merge(&mut table, overrides.clone());
        table.insert("seed".into(), toml::Value::Integer(seed as i64));
        table.remove("base");
        let file: File = table
            .try_into()
            .map_err(|e| anyhow!("{} (with the suite's overrides): {e}", path.display()))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let mut s = Self::from_file(file, stem).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        s.source = Some(path.to_path_buf());
        Ok(s)
    }

    /// Parses and checks scenario text (no `base`); `name` is used when the text has none.
    pub fn from_toml(text: &str, name: &str) -> anyhow::Result<Self> {
        let file: File = toml::from_str(text).map_err(|e| anyhow!("scenario `{name}`: {e}"))?;
        if file.base.is_some() {
            bail!("scenario `{name}`: `base` needs a file; use Scenario::load");
        }
        Self::from_file(file, name.to_string()).map_err(|e| anyhow!("scenario `{name}`: {e}"))
    }

    fn from_file(f: File, stem: String) -> Result<Self, String> {
        let fs = f.sample_rate_hz;
        if !(8_000..=192_000).contains(&fs) {
            return Err(format!("sample_rate_hz {fs} is outside 8000..=192000"));
        }
        let air = f.air.map_or_else(Air::default, |a| Air {
            temperature_c: a.temperature_c,
            humidity_percent: a.humidity_percent,
            pressure_pa: a.pressure_pa,
        });
        for (key, value, range, unit) in [
            ("temperature_c", air.temperature_c, -50.0..=60.0, "°C"),
            ("humidity_percent", air.humidity_percent, 0.0..=100.0, "%"),
            ("pressure_pa", air.pressure_pa, 10_000.0..=200_000.0, "Pa"),
        ] {
            if !range.contains(&value) {
                return Err(format!(
                    "air.{key} must be {} to {} {unit}, got {value}",
                    range.start(),
                    range.end()
                ));
            }
        }

        // Drone: a preset, then overrides.
        let mut dt = f.drone;
        let preset = match dt.remove("preset") {
            Some(toml::Value::String(s)) => Some(s),
            Some(_) => return Err("drone.preset must be a string".into()),
            None => None,
        };
        let drone: DroneProfile = match preset {
            Some(p) => {
                let base = DroneProfile::preset(&p).ok_or_else(|| {
                    format!(
                        "drone.preset `{p}` is unknown (known: {})",
                        DroneProfile::PRESETS.join(", ")
                    )
                })?;
                let mut t = toml::Table::try_from(&base).map_err(|e| e.to_string())?;
                merge(&mut t, dt);
                t.try_into().map_err(|e: toml::de::Error| format!("drone: {}", e.message()))?
            }
            None => toml::Value::Table(dt)
                .try_into()
                .map_err(|e: toml::de::Error| format!("drone: {}", e.message()))?,
        };
        drone.validate()?;
        let population = f.airframe.population()?;

        let p = &f.path;
        check_path_file(p)?;
        let need = |v: Option<f64>, key: &str| {
            v.ok_or_else(|| format!("path.{key} is required for kind `{}`", p.kind))
        };
        let heading = match p.heading.as_deref().unwrap_or("fixed") {
            "fixed" => {
                if p.yaw_rate_dps.is_some() || p.yaw_accel_dps2.is_some() {
                    return Err(
                        "path.yaw_rate_dps and path.yaw_accel_dps2 apply to heading = \"along-track\""
                            .into(),
                    );
                }
                Heading::Fixed
            }
            "along-track" => {
                if p.yaw_deg.is_some() {
                    return Err("path.yaw_deg applies to heading = \"fixed\" (along-track faces \
                                each leg)"
                        .into());
                }
                let rate = p.yaw_rate_dps.unwrap_or(DEFAULT_YAW_RATE_DPS);
                let accel = p.yaw_accel_dps2.unwrap_or(DEFAULT_YAW_ACCEL_DPS2);
                if !(rate > 0.0 && rate <= 720.0) {
                    return Err(format!("path.yaw_rate_dps {rate} must be in (0, 720]"));
                }
                if !(accel > 0.0 && accel <= 7200.0) {
                    return Err(format!("path.yaw_accel_dps2 {accel} must be in (0, 7200]"));
                }
                Heading::AlongTrack {
                    max_rate_rad_s: rate.to_radians(),
                    max_accel_rad_s2: accel.to_radians(),
                }
            }
            h => return Err(format!("path.heading `{h}` is unknown (fixed, along-track)")),
        };
        if p.speed_mps > 20.0 {
            return Err(format!(
                "path.speed_mps {} is beyond what the drone model flies (20 m/s)",
                p.speed_mps
            ));
        }
        let height = || need(p.height_m, "height_m");
        let centre = || {
            p.centre
                .map(|c| c.0)
                .ok_or(format!("path.centre = [x, y] is required for kind `{}`", p.kind))
        };
        let loops = p.loops.max(1);
        let continuous = |shape: Shape| {
            FlightPlan::continuous(
                shape,
                p.speed_mps,
                p.max_accel_mps2,
                p.hover_start_s,
                p.hover_end_s,
                heading,
            )
        };
        let plan = match p.kind.as_str() {
            "smooth" => {
                let points: Vec<Vector3<f64>> = p
                    .points
                    .as_ref()
                    .ok_or("path.points = [[x, y, z], ...] is required for kind `smooth`")?
                    .iter()
                    .map(|q| Vector3::from(**q))
                    .collect();
                if points.iter().flat_map(|w| w.iter()).any(|v| !v.is_finite()) {
                    return Err("path: points must be finite".into());
                }
                let spline = Spline::through(&points)
                    .ok_or("path.points: kind `smooth` needs at least two distinct points")?;
                continuous(Shape::Spline(spline))
            }
            "circle" => {
                let radius_m = need(p.radius_m, "radius_m")?;
                if !(radius_m > 0.0 && radius_m.is_finite()) {
                    return Err("path.radius_m must be positive".into());
                }
                continuous(Shape::Circle {
                    centre: centre()?,
                    height_m: height()?,
                    radius_m,
                    start_rad: p.start_deg.unwrap_or(-90.0).to_radians(),
                    sense: if p.clockwise { -1.0 } else { 1.0 },
                    loops,
                })
            }
            "eight" => {
                let length_m = need(p.length_m, "length_m")?;
                if !(length_m > 0.0 && length_m.is_finite()) {
                    return Err("path.length_m must be positive".into());
                }
                continuous(Shape::Eight {
                    centre: centre()?,
                    height_m: height()?,
                    length_m,
                    axis_rad: p.axis_deg.unwrap_or(0.0).to_radians(),
                    loops,
                })
            }
            "walk" => {
                if heading != Heading::Fixed {
                    return Err("path.heading: kind `walk` flies with a fixed heading".into());
                }
                let corner = |v: Option<Coords<3>>, key: &str| {
                    v.map(|c| Vector3::from(c.0))
                        .ok_or(format!("path.{key} = [x, y, z] is required for kind `walk`"))
                };
                let spec = WalkSpec {
                    start: corner(p.position, "position")?,
                    area_min: corner(p.area_min, "area_min")?,
                    area_max: corner(p.area_max, "area_max")?,
                    wander_s: p.wander_s.unwrap_or(40.0),
                    tau_s: p.walk_tau_s.unwrap_or(2.0),
                    max_speed_mps: p.speed_mps,
                    max_climb_mps: p.max_climb_mps.unwrap_or(1.0),
                    max_accel_mps2: p.max_accel_mps2,
                    max_jerk_mps3: p.max_jerk_mps3.unwrap_or(3.0 * p.max_accel_mps2),
                    seed: crate::sub_seed(f.seed, 3),
                };
                FlightPlan::walk(&spec, p.hover_start_s, p.hover_end_s)
            }
            _ => {
            let waypoints: Vec<Vector3<f64>> = match p.kind.as_str() {
                "square" => {
                    let side = need(p.side_m, "side_m")?;
                    let height = need(p.height_m, "height_m")?;
                    let start = p.start.map(|c| c.0).ok_or("path.start = [x, y] is required for kind `square`")?;
                    if !(side > 0.0 && height.is_finite()) {
                        return Err("path.side_m must be positive".into());
                    }
                    square(start, side, height, p.clockwise, p.loops)
                }
                "waypoints" => p
                    .points
                    .as_ref()
                    .ok_or("path.points = [[x, y, z], ...] is required for kind `waypoints`")?
                    .iter()
                    .map(|q| Vector3::from(**q))
                    .collect(),
                "hover" => vec![Vector3::from(
                    *p.position.ok_or("path.position = [x, y, z] is required for kind `hover`")?,
                )],
                k => {
                        return Err(format!(
                            "path.kind `{k}` is unknown (square, waypoints, hover, smooth, circle, eight, walk)"
                        ))
                    }
            };
            if waypoints.iter().flat_map(|w| w.iter()).any(|v| !v.is_finite()) {
                return Err("path: waypoints must be finite".into());
            }
            FlightPlan::new(
                &waypoints,
                p.speed_mps,
                p.max_accel_mps2,
                p.hover_start_s,
                p.corner_pause_s,
                p.hover_end_s,
                heading,
            )
            }
        }
        .map_err(|e| format!("path: {e}"))?;
        let yaw_rad =
            plan.heading_at(0.0).map_or(p.yaw_deg.unwrap_or(0.0).to_radians(), |h| h.yaw_rad);
        let duration_s = f.duration_s.unwrap_or(plan.duration_s());
        if !(duration_s > 0.0 && duration_s <= 3600.0) {
            return Err(format!("duration_s {duration_s} must be in (0, 3600]"));
        }

        let room = match f.room {
            Some(r) => {
                let absorption = match (r.absorption, r.rt60_s) {
                    (Some(_), Some(_)) => {
                        return Err("room: give absorption or rt60_s, not both".into());
                    }
                    (None, Some(t)) if !(t.is_finite() && (0.05..=10.0).contains(&t)) => {
                        return Err(format!("room.rt60_s {t} must lie in 0.05..=10 s"));
                    }
                    (None, Some(t)) => {
                        let c = air.speed_of_sound_mps();
                        [crate::reverb::absorption_for_t30(r.size_m.0, t, c); 6]
                    }
                    (None, None) => [0.2; 6],
                    (Some(Absorption::All(a)), None) => [a; 6],
                    (Some(Absorption::Each(a)), None) => a,
                };
                let room = Room {
                    size_m: r.size_m.0,
                    absorption,
                    reflection_order: r.reflection_order,
                    late_tail: r.late_tail.unwrap_or(r.rt60_s.is_some()),
                };
                room.validate()?;
                Some(room)
            }
            None => None,
        };
        let obstacles: Vec<Obstacle> = f
            .obstacle
            .into_iter()
            .enumerate()
            .map(|(i, o)| Obstacle {
                name: o.name.unwrap_or_else(|| format!("obstacle{}", i + 1)),
                min: Vector3::from(*o.min),
                max: Vector3::from(*o.max),
                loss_db: o.loss_db,
            })
            .collect();
        for (i, o) in obstacles.iter().enumerate() {
            o.validate().map_err(|e| format!("obstacle[{i}].{e}"))?;
        }
        let noise: Vec<NoiseSource> = f
            .noise
            .into_iter()
            .map(|n| NoiseSource {
                position_m: Vector3::from(*n.position),
                centre_hz: n.centre_hz,
                bandwidth_hz: n.bandwidth_hz,
                spl_db: n.spl_db,
                distance_m: n.distance_m,
            })
            .collect();
        for (k, n) in noise.iter().enumerate() {
            n.validate(fs as f64).map_err(|e| format!("noise[{k}].{e}"))?;
        }
        let diffuse_noise = f.diffuse_noise.map(|d| DiffuseNoise {
            spl_db: d.spl_db,
            low_hz: d.low_hz,
            high_hz: d.high_hz,
            directions: d.directions,
        });
        if let Some(d) = &diffuse_noise {
            d.validate(fs as f64).map_err(|e| format!("diffuse_noise.{e}"))?;
        }
        let mut beacons = Vec::new();
        for (i, b) in f.beacon.into_iter().enumerate() {
            let speaker = crate::beacon::BeaconSpeaker {
                id: b.id.unwrap_or(i as u8 + 1),
                position_m: Vector3::from(*b.position),
                level_db: b.level_db,
                period_s: b.period_s,
                clock_drift_ppm: b.clock_drift_ppm,
                start_s: b.start_s,
            };
            speaker.validate()?;
            beacons.push(speaker);
        }
        if !beacons.is_empty() && fs != aim_dsp::beacon::SAMPLE_RATE_HZ {
            return Err(format!("[[beacon]] needs sample_rate_hz = 48000 (got {fs})"));
        }
        // The beacon is rendered along the image model's paths only: in a room with a late
        // reverberant tail it would sound cleaner than the drone (not modelled: refused).
        if !beacons.is_empty() && room.as_ref().is_some_and(|r| r.late_tail) {
            return Err("[[beacon]] in a room with a late reverberant tail (room.late_tail, \
                        the default with rt60_s) is not modelled: set late_tail = false"
                .into());
        }

        if f.array.is_empty() {
            return Err("no [[array]]: the scenario needs at least one microphone array".into());
        }
        let mut arrays = Vec::new();
        for a in f.array {
            let (geometry, positions) = match (a.geometry, a.positions) {
                (Some(_), Some(_)) => {
                    return Err(format!(
                        "array {}: give either geometry or positions, not both",
                        a.id
                    ))
                }
                (None, Some(p)) => ("custom".to_string(), p.iter().map(|c| c.0).collect()),
                (g, None) => {
                    let g = g.unwrap_or_else(|| "respeaker-6mic".into());
                    let p = preset_positions(&g).ok_or_else(|| {
                        format!(
                            "array {}: geometry `{g}` is unknown (known: {})",
                            a.id,
                            GEOMETRY_PRESETS.join(", ")
                        )
                    })?;
                    (g, p)
                }
            };
            if arrays.iter().any(|x: &ArrayConfig| x.id == a.id) {
                return Err(format!("array id {} appears twice", a.id));
            }
            // The tracker's site refuses arrays closer than an array's width; so does the world.
            let here = Vector3::from(*a.position);
            if let Some((x, d)) = arrays
                .iter()
                .map(|x: &ArrayConfig| (x, (x.position_m - here).norm()))
                .find(|&(_, d)| d < aim_tracker::site::MIN_ARRAY_SEPARATION_M)
            {
                return Err(format!(
                    "array {}: position is {d:.3} m from array {}'s; arrays must be at least {} m \
                     apart",
                    a.id,
                    x.id,
                    aim_tracker::site::MIN_ARRAY_SEPARATION_M
                ));
            }
            let facing_down = match a.facing.as_deref() {
                None | Some("up") => false,
                Some("down") => true,
                Some(other) => {
                    return Err(format!(
                        "array {}: facing = \"{other}\" is unknown (\"up\" or \"down\")",
                        a.id
                    ))
                }
            };
            let cfg = ArrayConfig {
                id: a.id,
                geometry,
                positions,
                position_m: Vector3::from(*a.position),
                yaw_rad: a.yaw_deg.to_radians(),
                facing_down,
                clock: Clock { offset_s: a.clock_offset_s, drift_ppm: a.clock_drift_ppm },
                self_noise_db: a.self_noise_db,
                gain_mismatch_db: a.gain_mismatch_db,
                phase_mismatch_us: a.phase_mismatch_us,
                dead_mics: a.dead_mics.clone(),
                stuck_mics: a.stuck_mics.clone(),
                link_down_s: a.link_down_s.map(|c| c.0),
            };
            if let Some(m) =
                cfg.dead_mics.iter().chain(&cfg.stuck_mics).find(|&&m| m >= cfg.positions.len())
            {
                return Err(format!(
                    "array {}: dead_mics/stuck_mics name microphone {m}, but it has {} (0..{})",
                    a.id,
                    cfg.positions.len(),
                    cfg.positions.len()
                ));
            }
            cfg.validate()?;
            arrays.push(cfg);
        }

        let render = Render {
            rotor_sources: f.render.rotor_sources.unwrap_or(RotorSources::Direct),
            block_samples: f.render.block_samples.unwrap_or(crate::propagation::DEFAULT_BLOCK),
            control_rate_hz: f.render.control_rate_hz.unwrap_or(1000.0),
            diffraction_ref_hz: f.render.diffraction_ref_hz.unwrap_or(500.0),
            absorption: f.render.absorption.unwrap_or(true),
        };
        if !(1..=4096).contains(&render.block_samples) {
            return Err("render.block_samples must be in 1..=4096".into());
        }
        if !(200.0..=10_000.0).contains(&render.control_rate_hz) {
            return Err("render.control_rate_hz must be in 200..=10000".into());
        }
        if render.diffraction_ref_hz.is_nan() || render.diffraction_ref_hz <= 0.0 {
            return Err("render.diffraction_ref_hz must be positive".into());
        }
        if !(f.truth_rate_hz > 0.0 && f.truth_rate_hz <= render.control_rate_hz) {
            return Err("truth_rate_hz must be positive and at most render.control_rate_hz".into());
        }

        let scenario = Self {
            name: f.name.unwrap_or(stem),
            description: f.description,
            source: None,
            seed: f.seed,
            sample_rate_hz: fs,
            duration_s,
            truth_rate_hz: f.truth_rate_hz,
            air,
            drone,
            population,
            plan,
            yaw_rad,
            room,
            obstacles,
            noise,
            diffuse_noise,
            beacons,
            arrays,
            render,
        };
        scenario.check_limits()?;
        Ok(scenario)
    }
}

/// Largest coordinate accepted anywhere in a scenario (waypoints, arrays, noise sources,
/// obstacles), m.
pub const MAX_COORDINATE_M: f64 = 10_000.0;
/// Longest side of a room or of a square path, m.
pub const MAX_SIDE_M: f64 = 1000.0;
/// Most loops of a square path (the duration limit ends a run long before).
pub const MAX_LOOPS: u32 = 1000;
/// Most waypoints of a path.
pub const MAX_WAYPOINTS: usize = 10_000;
/// Most plane waves of the diffuse noise field (each is a full-length source signal).
pub const MAX_DIFFUSE_DIRECTIONS: usize = 1024;
/// Loudest level accepted for any source, dB SPL (beyond the threshold of pain; the
/// microphones clip at 120 dB).
pub const MAX_SPL_DB: f64 = 150.0;

/// `value` within `range`, else a message naming `key` (`path.loops 4000000000 must be 1 to
/// 1000`); `key` leads the message so that [`key_line`] finds its line.
fn within<T: PartialOrd + std::fmt::Debug + Copy>(
    key: &str,
    value: T,
    range: std::ops::RangeInclusive<T>,
    unit: &str,
) -> Result<T, String> {
    if range.contains(&value) {
        Ok(value)
    } else {
        Err(format!("{key} {value:?} must be {:?} to {:?} {unit}", range.start(), range.end()))
    }
}

/// Every coordinate of `p` finite and within [`MAX_COORDINATE_M`].
fn point(key: &str, p: &[f64]) -> Result<(), String> {
    if p.iter().all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE_M) {
        Ok(())
    } else {
        Err(format!("{key} {p:?} must be finite and within {MAX_COORDINATE_M} m of the origin"))
    }
}

/// The `[path]` table's numbers, checked before any waypoint is built from them.
fn check_path_file(p: &FilePath) -> Result<(), String> {
    within("path.loops", p.loops, 1..=MAX_LOOPS, "")?;
    if let Some(side) = p.side_m {
        if !(side > 0.0 && side <= MAX_SIDE_M) {
            return Err(format!(
                "path.side_m {side:?} must be positive and at most {MAX_SIDE_M} m"
            ));
        }
    }
    if let Some(h) = p.height_m {
        within("path.height_m", h, -MAX_SIDE_M..=MAX_SIDE_M, "m")?;
    }
    if let Some(start) = p.start {
        point("path.start", start.as_slice())?;
    }
    if let Some(points) = &p.points {
        within("path.points", points.len(), 1..=MAX_WAYPOINTS, "waypoints")?;
        for q in points {
            point("path.points", q.as_slice())?;
        }
    }
    if let Some(q) = p.position {
        point("path.position", q.as_slice())?;
    }
    if !(p.speed_mps > 0.0 && p.speed_mps <= 20.0) {
        return Err(format!(
            "path.speed_mps {:?} must be positive and at most 20 m/s (what the drone model flies)",
            p.speed_mps
        ));
    }
    within("path.max_accel_mps2", p.max_accel_mps2, 0.1..=20.0, "m/s²")?;
    within("path.hover_start_s", p.hover_start_s, 0.0..=3600.0, "s")?;
    within("path.corner_pause_s", p.corner_pause_s, 0.0..=3600.0, "s")?;
    within("path.hover_end_s", p.hover_end_s, 0.0..=3600.0, "s")?;
    if let Some(yaw) = p.yaw_deg {
        within("path.yaw_deg", yaw, -360.0..=360.0, "degrees")?;
    }
    // The continuous kinds' numbers (NaN fails every range).
    if let Some(c) = p.centre {
        point("path.centre", c.as_slice())?;
    }
    for (key, corner) in [("path.area_min", p.area_min), ("path.area_max", p.area_max)] {
        if let Some(c) = corner {
            point(key, c.as_slice())?;
        }
    }
    if let Some(r) = p.radius_m {
        within("path.radius_m", r, 0.0..=MAX_SIDE_M, "m")?;
    }
    if let Some(l) = p.length_m {
        within("path.length_m", l, 0.0..=MAX_SIDE_M, "m")?;
    }
    for (key, angle) in [("path.start_deg", p.start_deg), ("path.axis_deg", p.axis_deg)] {
        if let Some(a) = angle {
            within(key, a, -360.0..=360.0, "degrees")?;
        }
    }
    if let Some(w) = p.wander_s {
        within("path.wander_s", w, 0.0..=3600.0, "s")?;
    }
    if let Some(t) = p.walk_tau_s {
        within("path.walk_tau_s", t, 0.01..=600.0, "s")?;
    }
    if let Some(v) = p.max_climb_mps {
        within("path.max_climb_mps", v, 0.01..=20.0, "m/s")?;
    }
    if let Some(j) = p.max_jerk_mps3 {
        within("path.max_jerk_mps3", j, 0.01..=1000.0, "m/s³")?;
    }
    Ok(())
}

impl Scenario {
    /// Range checks beyond each part's own `validate`: sizes, levels, inertias and counts that
    /// would exhaust memory, overflow the physics or give NaN audio, and what the on-chip
    /// pipeline (`aim_dsp::Config::validate`) would refuse only after the whole simulation.
    fn check_limits(&self) -> Result<(), String> {
        let d = &self.drone;
        within("drone.mass_kg", d.mass_kg, 0.01..=100.0, "kg")?;
        within("drone.arm_m", d.arm_m, 0.01..=5.0, "m")?;
        within("drone.hover_rotor_hz", d.hover_rotor_hz, 10.0..=1000.0, "Hz")?;
        within("drone.max_rotor_hz", d.max_rotor_hz, 10.0..=2000.0, "Hz")?;
        within("drone.torque_to_thrust_m", d.torque_to_thrust_m, 1e-4..=1.0, "m")?;
        for (i, &inertia) in d.inertia_kgm2.iter().enumerate() {
            within(&format!("drone.inertia_kgm2[{i}]"), inertia, 1e-6..=100.0, "kg·m²")?;
        }
        within("drone.drag_h", d.drag_h, 0.0..=100.0, "N·s²/m²")?;
        within("drone.drag_v", d.drag_v, 0.0..=100.0, "N·s²/m²")?;
        within("drone.motor_time_constant_s", d.motor_time_constant_s, 1e-4..=10.0, "s")?;
        within("drone.rotor_jitter", d.rotor_jitter, 0.0..=0.5, "")?;
        within("drone.rotor_jitter_time_s", d.rotor_jitter_time_s, 1e-3..=100.0, "s")?;
        within("drone.wake_loss_per_mps", d.wake_loss_per_mps, 0.0..=0.2, "per m/s")?;
        within("drone.spl_1m_db", d.spl_1m_db, 0.0..=MAX_SPL_DB, "dB")?;
        within("drone.harmonic_slope_db", d.harmonic_slope_db, -60.0..=20.0, "dB")?;
        within("drone.shaft_line_db", d.shaft_line_db, -100.0..=20.0, "dB")?;
        within("drone.broadband_db", d.broadband_db, -100.0..=20.0, "dB")?;
        within("drone.level_exponent", d.level_exponent, 0.01..=10.0, "")?;
        within("drone.blades", d.blades, 1..=8, "")?;
        within("drone.bpf_harmonics", d.bpf_harmonics, 1..=64, "")?;
        if let Some(room) = &self.room {
            for (i, &l) in room.size_m.iter().enumerate() {
                within(&format!("room.size_m[{i}]"), l, 0.1..=MAX_SIDE_M, "m")?;
            }
        }
        for (i, o) in self.obstacles.iter().enumerate() {
            point(&format!("obstacle[{i}].min (`{}`)", o.name), o.min.as_slice())?;
            point(&format!("obstacle[{i}].max (`{}`)", o.name), o.max.as_slice())?;
            let loss = format!("obstacle[{i}].loss_db (`{}`)", o.name);
            within(&loss, o.loss_db, 0.0..=200.0, "dB")?;
        }
        for (k, n) in self.noise.iter().enumerate() {
            point(&format!("noise[{k}].position"), n.position_m.as_slice())?;
            within(&format!("noise[{k}].spl_db"), n.spl_db, -50.0..=MAX_SPL_DB, "dB")?;
            within(&format!("noise[{k}].distance_m"), n.distance_m, 0.01..=1000.0, "m")?;
        }
        if let Some(dn) = &self.diffuse_noise {
            within("diffuse_noise.spl_db", dn.spl_db, -50.0..=MAX_SPL_DB, "dB")?;
            within("diffuse_noise.directions", dn.directions, 1..=MAX_DIFFUSE_DIRECTIONS, "")?;
        }
        for (k, a) in self.arrays.iter().enumerate() {
            let key = |name: &str| format!("array[{k}].{name}");
            point(&key("position"), a.position_m.as_slice())?;
            if let Some(room) = &self.room {
                if !room.contains(&a.position_m) {
                    return Err(format!(
                        "{} {:?} (array {}) is outside the room [0, 0, 0]..{:?}",
                        key("position"),
                        a.position_m.as_slice(),
                        a.id,
                        room.size_m
                    ));
                }
            }
            within(&key("yaw_deg"), a.yaw_rad.to_degrees(), -360.0..=360.0, "degrees")?;
            within(&key("self_noise_db"), a.self_noise_db, -50.0..=120.0, "dB")?;
            within(&key("gain_mismatch_db"), a.gain_mismatch_db, 0.0..=6.0, "dB")?;
            within(&key("phase_mismatch_us"), a.phase_mismatch_us, 0.0..=100.0, "µs")?;
            // What `fly` and `analyze` will run: the same configuration `eval::link` builds.
            let positions: Vec<[f32; 2]> =
                a.positions.iter().map(|p| [p[0] as f32, p[1] as f32]).collect();
            aim_dsp::Geometry::from_positions(&positions)
                .and_then(|g| aim_dsp::Config::new(g, self.sample_rate_hz).validate())
                .map_err(|e| {
                    format!(
                        "{} (array {}): the on-chip pipeline refuses this array at {} Hz: {e}",
                        key("positions"),
                        a.id,
                        self.sample_rate_hz
                    )
                })?;
        }
        // Where the drone cannot be: outside the room, inside a solid obstacle, on top of an
        // array. Checked every 0.1 s of the flight (at least 200 points).
        let t_end = self.plan.duration_s();
        let n = ((t_end / 0.1).ceil() as usize).max(200);
        for i in 0..=n {
            let t = t_end * i as f64 / n as f64;
            let p = self.plan.at(t).position;
            if let Some(room) = self.room.as_ref().filter(|r| !r.contains(&p)) {
                return Err(format!(
                    "path leaves the room [0, 0, 0]..{:?} (at {:?}, t = {t:.1} s)",
                    room.size_m,
                    p.as_slice()
                ));
            }
            if let Some(o) = self.obstacles.iter().find(|o| o.contains(&p)) {
                return Err(format!(
                    "path passes through obstacle `{}` (at {:?}, t = {t:.1} s): a drone cannot \
                     fly through a solid box",
                    o.name,
                    p.as_slice()
                ));
            }
            if let Some(a) =
                self.arrays.iter().find(|a| (a.position_m - p).norm() < MIN_DRONE_ARRAY_DISTANCE_M)
            {
                return Err(format!(
                    "path comes within {MIN_DRONE_ARRAY_DISTANCE_M} m of array {}'s centre (at \
                     {:?}, t = {t:.1} s)",
                    a.id,
                    p.as_slice()
                ));
            }
        }
        Ok(())
    }

    /// Memory a streamed simulation of this scenario (`host-sim simulate`, `host-sim fly`)
    /// needs at its peak, bytes (an estimate, on the high side): every source's window of
    /// signal and second difference (f32 over one output block, the longest path's delay and the
    /// clocks' spread, with room for the window's growth), one output block per microphone, the
    /// flight log at the control rate and the truth rows, the two that still grow with the
    /// duration. [`Self::recordings_bytes`] more when the recordings are kept in memory
    /// (`host_sim::simulate_with`).
    pub fn memory_estimate_bytes(&self) -> u64 {
        let fs = f64::from(self.sample_rate_hz);
        let offsets = self.arrays.iter().map(|a| a.clock.offset_s);
        let spread = offsets.clone().fold(0.0f64, f64::max) - offsets.fold(0.0f64, f64::min);
        // Pre-roll: the longest path (room diagonal times the reflection order) at 343 m/s,
        // with the renderer's margin.
        let pre_roll = self.room.as_ref().map_or(0.5, |r| {
            let diagonal = r.size_m.iter().map(|l| l * l).sum::<f64>().sqrt();
            let tail = if r.late_tail { crate::reverb::tail_reach_estimate_s(r) } else { 0.0 };
            (diagonal * (2.0 * f64::from(r.reflection_order) + 2.0) / 343.0).max(tail) + 0.05
        });
        let block_s = crate::OUTPUT_BLOCK as f64 / fs;
        let window = (block_s + spread + 1.25 * pre_roll + 0.1) * fs;
        let rotors = self.drone.rotor_count() as f64;
        let rotor_emitters = match self.render.rotor_sources {
            RotorSources::Each => rotors,
            RotorSources::Direct => rotors + 1.0,
            RotorSources::Centre => 1.0,
        };
        let emitters = rotor_emitters
            + self.noise.len() as f64
            + self.diffuse_noise.as_ref().map_or(0.0, |d| d.directions as f64);
        let mics: usize = self.arrays.iter().map(|a| a.positions.len()).sum();
        // Signal and second difference per emitter (a window's vector may hold up to twice
        // what it uses), the rotors' block, and one output block per microphone.
        let samples =
            window * (2.0 * 2.0 * emitters + rotors) + crate::OUTPUT_BLOCK as f64 * mics as f64;
        // The flight log (~400 B per control step) and the truth (~300 B per row).
        let span = self.duration_s + spread + pre_roll;
        let log = span * self.render.control_rate_hz * 400.0 + span * self.truth_rate_hz * 300.0;
        // The late tail's spectra: per microphone an FFT of the output block plus the tail
        // (complex f32), and the convolution's buffer per worker (counted once per microphone).
        let tail = self.room.as_ref().filter(|r| r.late_tail).map_or(0.0, |r| {
            let len = crate::reverb::tail_reach_estimate_s(r) * fs;
            let n_fft = ((crate::OUTPUT_BLOCK as f64 + len) as usize).next_power_of_two();
            (n_fft * 8 * 2 * mics) as f64
        });
        (samples * 4.0 + log + tail) as u64
    }

    /// Memory of every microphone's whole recording (f32), bytes.
    pub fn recordings_bytes(&self) -> u64 {
        let mics: usize = self.arrays.iter().map(|a| a.positions.len()).sum();
        (self.duration_s * f64::from(self.sample_rate_hz)) as u64 * mics as u64 * 4
    }
}

/// Nearest a drone's centre may come to an array's centre, m: about a small drone's own
/// radius (closer, its rotors would strike the array).
pub const MIN_DRONE_ARRAY_DISTANCE_M: f64 = 0.25;

/// The line of `text` holding the key an error message starts with (`path.loops …`,
/// `array[1].position …`, `duration_s …`): the first whitespace-separated word, as
/// `table.key`, `table[k].key` (the k-th `[[table]]`) or a top-level `key`; None when the key
/// is not in the text (a default, or set in a `base` file).
pub fn key_line(text: &str, message: &str) -> Option<usize> {
    // `array 3: …` / `beacon 2: …` (an item's own check): the line of that item's `id`.
    let mut words = message.split_whitespace();
    if let (Some(kind @ ("array" | "beacon")), Some(id)) = (words.next(), words.next()) {
        if let Ok(id) = id.trim_end_matches(':').parse::<u64>() {
            return item_id_line(text, kind, id);
        }
    }
    let word = message.split_whitespace().next()?.trim_end_matches(':');
    let (table, index, key) = match word.split_once('.') {
        Some((table, key)) => match table.split_once('[') {
            Some((t, rest)) => (t, rest.trim_end_matches(']').parse::<usize>().ok(), key),
            None => (table, None, key),
        },
        None => ("", None, word),
    };
    let key = key.split('[').next()?;
    let mut header = String::new();
    let mut seen = std::collections::HashMap::<String, usize>::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            header = name.trim().to_string();
            *seen.entry(header.clone()).or_insert(0) += 1;
            continue;
        }
        if let Some(name) = l.strip_prefix('[').and_then(|r| r.split(']').next()) {
            header = name.trim().to_string();
            continue;
        }
        let in_table =
            header == table && index.is_none_or(|k| seen.get(table).copied() == Some(k + 1));
        let is_key = l.strip_prefix(key).is_some_and(|rest| rest.trim_start().starts_with('='));
        if in_table && is_key {
            return Some(i + 1);
        }
    }
    None
}

/// The line of `id = ID` inside a `[[KIND]]` table of `text`.
fn item_id_line(text: &str, kind: &str, id: u64) -> Option<usize> {
    let mut inside = false;
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.starts_with('[') {
            inside = l.strip_prefix("[[").and_then(|r| r.split("]]").next()).map(str::trim)
                == Some(kind);
            continue;
        }
        let value = l.strip_prefix("id").map(str::trim_start).and_then(|r| r.strip_prefix('='));
        if inside && value.and_then(|v| v.trim().parse::<u64>().ok()) == Some(id) {
            return Some(i + 1);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: &str = r#"
[drone]
preset = "dji-mini-2"
[path]
kind = "square"
side_m = 4.0
start = [0.0, 0.0]
height_m = 2.0
[[array]]
id = 1
position = [2.0, -1.0, 0.05]
"#;

    fn with_path(extra: &str) -> anyhow::Result<Scenario> {
        let text = BASE.replace("height_m = 2.0", &format!("height_m = 2.0\n{extra}"));
        Scenario::from_toml(&text, "t")
    }

    /// `room.absorption` reads one number for every surface or six, and says which it wants.
    #[test]
    fn room_absorption_is_one_number_or_six_and_anything_else_is_named() {
        let room = |a: &str| {
            let text = BASE.replace("[2.0, -1.0, 0.05]", "[2.0, 1.0, 0.05]");
            Scenario::from_toml(&format!("{text}\n[room]\nsize_m = [20.0, 20.0, 5.0]\n{a}\n"), "t")
        };
        let all = room("absorption = 0.3").unwrap();
        assert_eq!(all.room.unwrap().absorption, [0.3; 6]);
        let whole = room("absorption = 1").unwrap();
        assert_eq!(whole.room.unwrap().absorption, [1.0; 6]);
        let each = room("absorption = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]").unwrap();
        assert_eq!(each.room.unwrap().absorption, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        let e = format!("{:#}", room("absorption = [0.1, 0.2, 0.3]").unwrap_err());
        assert!(
            e.contains("invalid length 3, expected a number (every surface) or an array of 6 numbers (walls x = 0, x = Lx, y = 0, y = Ly, floor, ceiling)"),
            "{e}"
        );
        let e = format!("{:#}", room("absorption = \"high\"").unwrap_err());
        assert!(e.contains("expected a number (every surface) or an array of 6 numbers"), "{e}");
    }

    #[test]
    fn heading_defaults_to_fixed_and_along_track_reads_its_limits() {
        let fixed = with_path("yaw_deg = 30.0").unwrap();
        assert_eq!(fixed.plan.heading(), Heading::Fixed);
        assert!((fixed.yaw_rad - 30f64.to_radians()).abs() < 1e-12);
        let nose = with_path("heading = \"along-track\"\nyaw_rate_dps = 60.0").unwrap();
        assert_eq!(
            nose.plan.heading(),
            Heading::AlongTrack {
                max_rate_rad_s: 60f64.to_radians(),
                max_accel_rad_s2: DEFAULT_YAW_ACCEL_DPS2.to_radians(),
            }
        );
        // Three corners, three turns; the drone starts facing its first leg (+x).
        assert_eq!(nose.plan.turns().len(), 3);
        assert_eq!(nose.yaw_rad, 0.0);
    }

    #[test]
    fn heading_keys_that_do_not_fit_are_named() {
        let e = with_path("heading = \"sideways\"").unwrap_err().to_string();
        assert!(e.contains("path.heading `sideways` is unknown"), "{e}");
        let e = with_path("heading = \"along-track\"\nyaw_deg = 10.0").unwrap_err().to_string();
        assert!(e.contains("path.yaw_deg applies to heading = \"fixed\""), "{e}");
        let e = with_path("yaw_rate_dps = 90.0").unwrap_err().to_string();
        assert!(e.contains("apply to heading = \"along-track\""), "{e}");
        let e =
            with_path("heading = \"along-track\"\nyaw_accel_dps2 = -1.0").unwrap_err().to_string();
        assert!(e.contains("path.yaw_accel_dps2 -1 must be in"), "{e}");
    }

    #[test]
    fn bundled_nose_first_scenario_turns_at_three_corners() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        let s = Scenario::load(&dir.join("square10-nlos-yaw.toml")).unwrap();
        let turns = s.plan.turns();
        assert_eq!(turns.len(), 3);
        assert!(turns.iter().all(|t| (t.2 - std::f64::consts::FRAC_PI_2).abs() < 1e-12));
        assert!(s.duration_s >= turns[2].1);
        assert_eq!(s.obstacles.len(), 1);
    }
}
