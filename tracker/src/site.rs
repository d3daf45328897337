//! Site files: where the arrays are and how they face.
//!
//! ```toml
//! sample_rate_hz = 48000       # optional: nominal sample rate of the arrays, Hz
//! speed_of_sound_mps = 343.2   # optional, informative
//!
//! # one table per array
//! [[array]]
//! id = 0
//! position = [0.0, 0.0, 0.0]   # metres, world ENU
//! yaw_deg = 0.0                # array +x from world east, counter-clockwise
//! pitch_deg = 0.0              # optional: rotation about the array's y, degrees
//! roll_deg = 0.0               # optional: rotation about the array's x, degrees
//! geometry = "respeaker-6mic"  # optional: one of KNOWN_GEOMETRIES ("custom" needs positions)
//! positions = [[0.0463, 0.0], ...]  # optional: 4 to 8 microphone positions, array frame, m
//!                              # (checked against the array's Hello)
//! clock_offset_s = 0.0         # optional: true time of the array's sample 0, s
//! clock_drift_ppm = 0.0        # optional: the array clock's rate error, ppm
//! zenith_correction_deg = [[27.5, -0.8], [72.5, -5.5]]  # optional: the site's calibration
//!                              # of the zenith, [measured zenith °, measured − true °]
//!                              # (`aim calibrate`, crate::zenith)
//!
//! [room]                       # optional: the flight volume, world metres, either
//! min = [-1.0, -1.0, 0.0]
//! max = [12.0, 12.0, 4.0]
//! # or `size = [Lx, Ly, Lz]` for the shoebox [0, Lx] × [0, Ly] × [0, Lz]
//!
//! [[obstacle]]                 # optional, informative: name, min, max, loss_db
//!
//! [[beacon]]                   # optional: a loudspeaker of the clock sync (crate::multi::clock)
//! id = 1                       # 0–255, unique among beacons
//! position = [8.0, 0.2, 1.5]   # loudspeaker, world ENU m (surveyed)
//! period_s = 1.0               # nominal repetition period on the speaker's clock, s
//! sequence = "aim-beacon-v1"   # name of the aim_dsp::beacon sequence
//! level_db = 60.0              # optional, informative: dB SPL at 1 m
//!
//! [origin]                     # optional: the local NED frame of `--mavlink`
//! position = [0.0, 0.0, 0.0]   # (see crate::output::ned)
//! x_axis_from_north_deg = 90.0
//! ```
//! This is a superset of the `site.toml` that `host-sim simulate` writes. Every number is
//! range-checked at its line: positions within [`MAX_COORDINATE_M`] and inside the room (with
//! [`ROOM_TOLERANCE_M`]), angles within ±360°, offsets within [`MAX_CLOCK_OFFSET_S`], drifts
//! within [`MAX_CLOCK_DRIFT_PPM`], ids 0–255 (the wire's), sample rate 1–384 kHz, speed of sound
//! within [`SPEED_OF_SOUND_RANGE_MPS`], beacon periods within [`BEACON_PERIOD_RANGE_S`] and levels
//! within [`BEACON_LEVEL_RANGE_DB`].
//! The array frame is x right, y forward, z up along the array normal; the rotation from the
//! array frame to the world is R = Rz(yaw)·Ry(pitch)·Rx(roll).

use std::path::Path;

use serde::Deserialize;

use crate::config::{line_of, parse_toml, read_text, ConfigError, Coords};

/// One array's pose.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayPose {
    /// Array id, as in the frames.
    pub id: u16,
    /// Centre of the array, world ENU metres.
    pub position: [f64; 3],
    /// Rotation from the array frame to the world frame (row-major 3×3).
    pub rotation: [[f64; 3]; 3],
    /// Geometry name, if given.
    pub geometry: Option<String>,
    /// Microphone positions `[x, y]` in the array frame, m, if given (empty otherwise): a
    /// `Hello` announcing others is an error.
    pub mic_positions_m: Vec<[f64; 2]>,
    /// True time of the array's sample 0, s.
    pub clock_offset_s: f64,
    /// Rate error of the array's clock, ppm (its second lasts 1 + drift·1e-6 true seconds).
    pub clock_drift_ppm: f64,
    /// The site's calibration of this array's zenith ([`crate::zenith`]), applied by the
    /// intake to every bearing; empty: none.
    pub zenith_correction: crate::zenith::ZenithCorrection,
}

impl ArrayPose {
    /// A pose from position (m) and yaw, pitch, roll (rad).
    pub fn new(id: u16, position: [f64; 3], yaw: f64, pitch: f64, roll: f64) -> Self {
        let (sy, cy) = yaw.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sr, cr) = roll.sin_cos();
        let rotation = [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ];
        Self {
            id,
            position,
            rotation,
            geometry: None,
            mic_positions_m: Vec::new(),
            clock_offset_s: 0.0,
            clock_drift_ppm: 0.0,
            zenith_correction: crate::zenith::ZenithCorrection::default(),
        }
    }

    /// True time, s, of sample `index` of this array's clock at nominal rate `sample_rate_hz`.
    pub fn sample_time(&self, index: f64, sample_rate_hz: f64) -> f64 {
        self.clock_offset_s + index / sample_rate_hz * (1.0 + self.clock_drift_ppm * 1e-6)
    }

    /// A direction in the array frame turned into the world frame.
    pub fn to_world(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * v[0] + r[0][1] * v[1] + r[0][2] * v[2],
            r[1][0] * v[0] + r[1][1] * v[1] + r[1][2] * v[2],
            r[2][0] * v[0] + r[2][1] * v[1] + r[2][2] * v[2],
        ]
    }

    /// A world direction turned into the array frame.
    pub fn to_array(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
            r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
        ]
    }
}

/// The flight volume, world metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Room {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

/// A beacon loudspeaker of the clock sync (issue 14): where it is and what it plays.
#[derive(Clone, Debug, PartialEq)]
pub struct BeaconSpec {
    /// Beacon id.
    pub id: u8,
    /// Loudspeaker position, world ENU m.
    pub position: [f64; 3],
    /// Nominal repetition period on the speaker's own clock, s.
    pub period_s: f64,
    /// Name of the emitted sequence (`aim_dsp::beacon`).
    pub sequence: String,
    /// Emitted level, dB SPL at 1 m, if given (information only).
    pub level_db: Option<f64>,
}

/// A site: arrays and, optionally, the room.
#[derive(Clone, Debug, PartialEq)]
pub struct Site {
    /// The arrays, in file order.
    pub arrays: Vec<ArrayPose>,
    /// The flight volume, if known.
    pub room: Option<Room>,
    /// Nominal sample rate of the arrays, Hz, if given.
    pub sample_rate_hz: Option<u32>,
}

/// What a site file says for the clock sync of several arrays: the beacons and the speed of
/// sound. (Kept beside [`Site`] rather than in it because other crates build `Site` literals.)
#[derive(Clone, Debug, PartialEq, Default)]
pub struct SiteSync {
    /// Speed of sound at the site, m/s, if given.
    pub speed_of_sound_mps: Option<f64>,
    /// The beacon loudspeakers, in file order (empty: no clock sync).
    pub beacons: Vec<BeaconSpec>,
}

impl SiteSync {
    /// Reads and checks a site file (all of it, as [`Site::load`] does).
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, path)
    }

    /// Parses and checks site TOML `text` (`path` names it in errors), all of it.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        Ok(parse_site(text, path)?.1)
    }

    /// The beacon with this id.
    pub fn beacon(&self, id: u8) -> Option<&BeaconSpec> {
        self.beacons.iter().find(|b| b.id == id)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SiteFile {
    sample_rate_hz: Option<u32>,
    speed_of_sound_mps: Option<toml::Spanned<f64>>,
    #[serde(default)]
    array: Vec<toml::Spanned<ArrayEntry>>,
    #[serde(default)]
    beacon: Vec<toml::Spanned<BeaconEntry>>,
    room: Option<toml::Spanned<RoomEntry>>,
    /// Informative (the tracker does not use them), but checked like the rest.
    #[serde(default)]
    obstacle: Vec<toml::Spanned<ObstacleEntry>>,
    /// The NED origin for outputs that need one: read by [`crate::output::ned::Origin`], and
    /// checked by it whenever the site has one.
    origin: Option<toml::Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObstacleEntry {
    name: Option<String>,
    min: Coords<3>,
    max: Coords<3>,
    loss_db: Option<f64>,
}

/// An obstacle of a site file: informative (the live map draws it; the tracker does not use
/// it). World ENU metres.
#[derive(Clone, Debug, PartialEq)]
pub struct SiteObstacle {
    /// Its name (`obstacle` when the file gives none).
    pub name: String,
    /// Lowest corner, m.
    pub min: [f64; 3],
    /// Highest corner, m.
    pub max: [f64; 3],
}

/// The checked `[[obstacle]]` tables of site TOML `text` (`path` names it in errors); the
/// other tables are read but not checked here ([`Site::parse`] checks the whole file).
pub fn obstacles(text: &str, path: &Path) -> Result<Vec<SiteObstacle>, ConfigError> {
    let file: SiteFile = parse_toml(text, path)?;
    checked_obstacles(&file.obstacle, text, path)
}

/// Each obstacle's corners finite, within [`MAX_COORDINATE_M`] and in order, its loss 0 to
/// 200 dB; an error names the obstacle and its line.
fn checked_obstacles(
    list: &[toml::Spanned<ObstacleEntry>],
    text: &str,
    path: &Path,
) -> Result<Vec<SiteObstacle>, ConfigError> {
    let err = |span: std::ops::Range<usize>, message: String| ConfigError {
        path: path.to_path_buf(),
        line: Some(line_of(text, span.start)),
        message,
    };
    let mut out = Vec::new();
    for (k, o) in list.iter().enumerate() {
        let e = o.get_ref();
        let finite =
            e.min.iter().chain(e.max.iter()).all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE_M);
        if !finite || (0..3).any(|i| e.min[i] >= e.max[i]) {
            return Err(err(
                o.span(),
                format!(
                    "obstacle {}: min {:?} must be below max {:?} on every axis, finite and within \
                     {MAX_COORDINATE_M} m of the origin",
                    k + 1,
                    e.min,
                    e.max
                ),
            ));
        }
        if e.loss_db.is_some_and(|l| !(0.0..=200.0).contains(&l)) {
            return Err(err(o.span(), format!("obstacle {}: loss_db must be 0 to 200 dB", k + 1)));
        }
        let name = e.name.clone().unwrap_or_else(|| "obstacle".into());
        out.push(SiteObstacle { name, min: e.min.0, max: e.max.0 });
    }
    Ok(out)
}

/// A site file's microphone positions as plain arrays.
fn coords2(p: &[Coords<2>]) -> Vec<[f64; 2]> {
    p.iter().map(|c| c.0).collect()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ArrayEntry {
    id: toml::Spanned<u16>,
    position: toml::Spanned<Coords<3>>,
    yaw_deg: Option<toml::Spanned<f64>>,
    pitch_deg: Option<toml::Spanned<f64>>,
    roll_deg: Option<toml::Spanned<f64>>,
    geometry: Option<toml::Spanned<String>>,
    positions: Option<toml::Spanned<Vec<Coords<2>>>>,
    clock_offset_s: Option<toml::Spanned<f64>>,
    clock_drift_ppm: Option<toml::Spanned<f64>>,
    zenith_correction_deg: Option<toml::Spanned<Vec<Vec<f64>>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BeaconEntry {
    id: toml::Spanned<u16>,
    position: toml::Spanned<Coords<3>>,
    period_s: toml::Spanned<f64>,
    sequence: toml::Spanned<String>,
    level_db: Option<toml::Spanned<f64>>,
}

/// Speeds of sound a site may give, m/s (air from about −55 °C to +100 °C).
pub const SPEED_OF_SOUND_RANGE_MPS: std::ops::RangeInclusive<f64> = 290.0..=390.0;
/// Beacon repetition periods a site may give, s.
pub const BEACON_PERIOD_RANGE_S: std::ops::RangeInclusive<f64> = 0.05..=60.0;
/// Beacon levels a site may give, dB SPL at 1 m.
pub const BEACON_LEVEL_RANGE_DB: std::ops::RangeInclusive<f64> = 0.0..=140.0;

/// Largest coordinate a site accepts, m: arrays and rooms lie within 10 km of the origin (far
/// beyond any acoustic range; beyond about 1e15 m the filter's arithmetic breaks down).
pub const MAX_COORDINATE_M: f64 = 10_000.0;
/// Largest clock offset accepted, s (about 317 years: Unix times fit).
pub const MAX_CLOCK_OFFSET_S: f64 = 1e10;
/// Largest clock drift accepted, ppm (crystals are within ±100 ppm; a rate error of more than
/// 0.1 % is a wrong sample rate, not a drift).
pub const MAX_CLOCK_DRIFT_PPM: f64 = 1000.0;
/// How far outside the room an array may sit (on or in a wall), m.
pub const ROOM_TOLERANCE_M: f64 = 0.1;
/// The microphone positions of a named geometry (array frame, m, at the wire's 0.1 mm), None
/// for `custom` or an unknown name.
pub fn preset_positions(name: &str) -> Option<Vec<[f64; 2]>> {
    let g = match name {
        "respeaker-6mic" | "respeaker6" => aim_dsp::Geometry::respeaker_6mic(),
        "respeaker-4mic" | "respeaker4" => aim_dsp::Geometry::respeaker_4mic(),
        "circle-8mic" | "circle8" => aim_dsp::Geometry::circle_8mic(),
        _ => return None,
    };
    Some(g.positions().iter().map(|p| p.map(at_wire_resolution)).collect())
}

/// A microphone coordinate at the wire's 0.1 mm (as a `Hello` gives it), m.
pub fn at_wire_resolution(v: f32) -> f64 {
    (f64::from(v) * 1e4).round() / 1e4
}

/// Whether two lists of microphone positions (m) are the same array: as many microphones,
/// each within 1 mm on both axes (the wire quantises to 0.1 mm; 1 mm is another array).
pub fn same_microphones(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| (p[0] - q[0]).abs() <= 1e-3 && (p[1] - q[1]).abs() <= 1e-3)
}

/// Microphone-array geometries the tracker and the DSP know by name (plus `custom` with
/// `positions`).
pub const KNOWN_GEOMETRIES: &[&str] = &[
    "respeaker-6mic",
    "respeaker-4mic",
    "circle-8mic",
    "respeaker6",
    "respeaker4",
    "circle8",
    "custom",
];
/// Microphones per array the DSP takes (`aim_dsp::MIN_MICS`..=`aim_dsp::MAX_MICS`).
const MICS: std::ops::RangeInclusive<usize> = 4..=8;
/// Farthest a microphone may be from the array centre, m.
const MAX_MIC_RADIUS_M: f64 = 1.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RoomEntry {
    min: Option<Coords<3>>,
    max: Option<Coords<3>>,
    size: Option<Coords<3>>,
}

/// Closest two arrays' centres may be, m: the width of a microphone array (two closer
/// would overlap).
pub const MIN_ARRAY_SEPARATION_M: f64 = 0.1;

/// Checks one `[[array]]` table (every number against its range, at its own line) and
/// turns it into a pose; `earlier` are the arrays before it (for duplicate ids).
fn array_pose(
    a: &ArrayEntry,
    earlier: &[ArrayPose],
    err: &impl Fn(std::ops::Range<usize>, String) -> ConfigError,
) -> Result<ArrayPose, ConfigError> {
    let id = *a.id.get_ref();
    if id > 255 {
        return Err(err(a.id.span(), format!("array id {id}: frames carry ids 0 to 255")));
    }
    if earlier.iter().any(|p| p.id == id) {
        return Err(err(a.id.span(), format!("array id {id} appears twice")));
    }
    let position = a.position.get_ref().0;
    if !position.iter().all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE_M) {
        return Err(err(
            a.position.span(),
            format!(
                "array {id}: position must be finite and within {MAX_COORDINATE_M} m of the origin (got {position:?})"
            ),
        ));
    }
    // Two arrays closer than one array's width are a copy-paste slip: they would share their
    // microphones' places and give the fusion no baseline.
    if let Some((other, d)) = earlier
        .iter()
        .map(|p| (p, crate::observation::distance(p.position, position)))
        .find(|&(_, d)| d < MIN_ARRAY_SEPARATION_M)
    {
        return Err(err(
            a.position.span(),
            format!(
                "array {id}: position {position:?} is {d:.3} m from array {}'s; arrays must be at \
                 least {MIN_ARRAY_SEPARATION_M} m apart",
                other.id
            ),
        ));
    }
    let number = |v: &Option<toml::Spanned<f64>>, what: &str, limit: f64, unit: &str| {
        let Some(v) = v else { return Ok(0.0) };
        let x = *v.get_ref();
        if x.is_finite() && x.abs() <= limit {
            Ok(x)
        } else {
            Err(err(
                v.span(),
                format!("array {id}: {what} must be within ±{limit} {unit} (got {x:?})"),
            ))
        }
    };
    let yaw = number(&a.yaw_deg, "yaw_deg", 360.0, "degrees")?;
    let pitch = number(&a.pitch_deg, "pitch_deg", 360.0, "degrees")?;
    let roll = number(&a.roll_deg, "roll_deg", 360.0, "degrees")?;
    let offset = number(&a.clock_offset_s, "clock_offset_s", MAX_CLOCK_OFFSET_S, "s")?;
    let drift = number(&a.clock_drift_ppm, "clock_drift_ppm", MAX_CLOCK_DRIFT_PPM, "ppm")?;
    if let Some(g) = &a.geometry {
        if !KNOWN_GEOMETRIES.contains(&g.get_ref().as_str()) {
            return Err(err(
                g.span(),
                format!(
                    "array {id}: geometry `{}` is unknown (known: {})",
                    g.get_ref(),
                    KNOWN_GEOMETRIES.join(", ")
                ),
            ));
        }
        if g.get_ref() == "custom" && a.positions.is_none() {
            return Err(err(g.span(), format!("array {id}: geometry `custom` needs `positions`")));
        }
        if let (Some(preset), Some(p)) = (preset_positions(g.get_ref()), &a.positions) {
            // Both given: they must be the same array.
            if !same_microphones(&preset, &coords2(p.get_ref())) {
                return Err(err(
                    p.span(),
                    format!(
                        "array {id}: positions ({} microphones) are not those of geometry `{}` \
                         ({} microphones at {preset:?}); give geometry = \"custom\" for another \
                         layout",
                        p.get_ref().len(),
                        g.get_ref(),
                        preset.len()
                    ),
                ));
            }
        }
    }
    if let Some(p) = &a.positions {
        let mics = p.get_ref();
        if !MICS.contains(&mics.len()) {
            return Err(err(
                p.span(),
                format!(
                    "array {id}: positions lists {} microphones; an array has {} to {}",
                    mics.len(),
                    MICS.start(),
                    MICS.end()
                ),
            ));
        }
        if let Some(k) = mics
            .iter()
            .position(|m| !m.iter().all(|v| v.is_finite() && v.abs() <= MAX_MIC_RADIUS_M))
        {
            return Err(err(
                p.span(),
                format!(
                    "array {id}: microphone {k} at {:?} must be finite and within {MAX_MIC_RADIUS_M} m of the centre",
                    mics[k]
                ),
            ));
        }
    }
    let mut pose =
        ArrayPose::new(id, position, yaw.to_radians(), pitch.to_radians(), roll.to_radians());
    pose.geometry = a.geometry.as_ref().map(|g| g.get_ref().clone());
    // A named geometry without positions stands for its positions (checked against the Hello).
    pose.mic_positions_m = match (&a.positions, &a.geometry) {
        (Some(p), _) => coords2(p.get_ref()),
        (None, Some(g)) => preset_positions(g.get_ref()).unwrap_or_default(),
        (None, None) => Vec::new(),
    };
    pose.clock_offset_s = offset;
    pose.clock_drift_ppm = drift;
    if let Some(c) = &a.zenith_correction_deg {
        let bad = |e: String| err(c.span(), format!("array {id}: zenith_correction_deg: {e}"));
        // Each point exactly [measured zenith, bias]: a third number is a mistake, not extra.
        let points = c
            .get_ref()
            .iter()
            .enumerate()
            .map(|(k, p)| {
                <[f64; 2]>::try_from(p.as_slice()).map_err(|_| {
                    format!("point {}: give [zenith, bias], two numbers (got {})", k + 1, p.len())
                })
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(bad)?;
        pose.zenith_correction =
            crate::zenith::ZenithCorrection::from_degrees(&points).map_err(bad)?;
    }
    Ok(pose)
}

/// Checks one `[[beacon]]` table (each value at its own line); `earlier` are the beacons
/// before it (for duplicate ids).
fn beacon_spec(
    b: &BeaconEntry,
    earlier: &[BeaconSpec],
    room: Option<&Room>,
    err: &impl Fn(std::ops::Range<usize>, String) -> ConfigError,
) -> Result<BeaconSpec, ConfigError> {
    let id = *b.id.get_ref();
    let Ok(id) = u8::try_from(id) else {
        return Err(err(b.id.span(), format!("beacon id {id}: ids are 0 to 255")));
    };
    if earlier.iter().any(|e| e.id == id) {
        return Err(err(b.id.span(), format!("beacon id {id} appears twice")));
    }
    let position = b.position.get_ref().0;
    if !position.iter().all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE_M) {
        return Err(err(
            b.position.span(),
            format!(
                "beacon {id}: position must be finite and within {MAX_COORDINATE_M} m of the origin (got {position:?})"
            ),
        ));
    }
    if let Some(room) = room {
        if (0..3).any(|i| {
            position[i] < room.min[i] - ROOM_TOLERANCE_M
                || position[i] > room.max[i] + ROOM_TOLERANCE_M
        }) {
            return Err(err(
                b.position.span(),
                format!(
                    "beacon {id}: position {position:?} is outside the room {:?}..{:?}",
                    room.min, room.max
                ),
            ));
        }
    }
    let period_s = *b.period_s.get_ref();
    if !BEACON_PERIOD_RANGE_S.contains(&period_s) {
        return Err(err(
            b.period_s.span(),
            format!(
                "beacon {id}: period_s must be {:?} to {:?} s (got {period_s:?})",
                BEACON_PERIOD_RANGE_S.start(),
                BEACON_PERIOD_RANGE_S.end()
            ),
        ));
    }
    let sequence = b.sequence.get_ref().trim().to_string();
    if sequence.is_empty() {
        return Err(err(b.sequence.span(), format!("beacon {id}: sequence must name a sequence")));
    }
    if sequence != aim_dsp::beacon::SEQUENCE_NAME {
        return Err(err(
            b.sequence.span(),
            format!(
                "beacon {id}: sequence `{sequence}` is unknown; the arrays detect `{}`",
                aim_dsp::beacon::SEQUENCE_NAME
            ),
        ));
    }
    let level_db = match &b.level_db {
        Some(l) if !BEACON_LEVEL_RANGE_DB.contains(l.get_ref()) => {
            return Err(err(
                l.span(),
                format!(
                    "beacon {id}: level_db must be {:?} to {:?} dB SPL (got {:?})",
                    BEACON_LEVEL_RANGE_DB.start(),
                    BEACON_LEVEL_RANGE_DB.end(),
                    l.get_ref()
                ),
            ))
        }
        l => l.as_ref().map(|l| *l.get_ref()),
    };
    Ok(BeaconSpec { id, position, period_s, sequence, level_db })
}

impl Site {
    /// Reads and checks a site file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, path)
    }

    /// Parses and checks site TOML `text` (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        Ok(parse_site(text, path)?.0)
    }

    /// The array with this id.
    pub fn array(&self, id: u16) -> Option<&ArrayPose> {
        self.arrays.iter().find(|a| a.id == id)
    }
}

/// Parses and checks a whole site file.
fn parse_site(text: &str, path: &Path) -> Result<(Site, SiteSync), ConfigError> {
    let file: SiteFile = parse_toml(text, path)?;
    let err = |span: std::ops::Range<usize>, message: String| ConfigError {
        path: path.to_path_buf(),
        line: Some(line_of(text, span.start)),
        message,
    };
    if file.array.is_empty() {
        return Err(ConfigError {
            path: path.to_path_buf(),
            line: None,
            message: "no [[array]] table: a site needs at least one array".into(),
        });
    }
    let mut arrays: Vec<ArrayPose> = Vec::new();
    for entry in &file.array {
        arrays.push(array_pose(entry.get_ref(), &arrays, &err)?);
    }
    if file.origin.is_some() {
        crate::output::ned::Origin::parse(text, path)?;
    }
    checked_obstacles(&file.obstacle, text, path)?;
    let room = match &file.room {
        Some(r) => {
            let e = r.get_ref();
            let (min, max) = match (e.min.map(|c| c.0), e.max.map(|c| c.0), e.size.map(|c| c.0)) {
                (Some(min), Some(max), None) => (min, max),
                (None, None, Some(size)) => ([0.0; 3], size),
                _ => {
                    return Err(err(
                        r.span(),
                        "room: give either `min` and `max`, or `size`".into(),
                    ))
                }
            };
            if (0..3).any(|i| !(min[i].is_finite() && max[i].is_finite() && min[i] < max[i])) {
                return Err(err(
                    r.span(),
                    "room: every min must be below its max (sizes positive)".into(),
                ));
            }
            if min.iter().chain(&max).any(|v| v.abs() > MAX_COORDINATE_M) {
                return Err(err(
                    r.span(),
                    format!("room: corners must lie within {MAX_COORDINATE_M} m of the origin"),
                ));
            }
            Some(Room { min, max })
        }
        None => None,
    };
    if let Some(room) = &room {
        for (entry, pose) in file.array.iter().zip(&arrays) {
            let outside = (0..3).any(|i| {
                pose.position[i] < room.min[i] - ROOM_TOLERANCE_M
                    || pose.position[i] > room.max[i] + ROOM_TOLERANCE_M
            });
            if outside {
                return Err(err(
                    entry.get_ref().position.span(),
                    format!(
                        "array {}: position {:?} is outside the room {:?}..{:?}",
                        pose.id, pose.position, room.min, room.max
                    ),
                ));
            }
        }
    }
    if let Some(fs) = file.sample_rate_hz.filter(|fs| !(1_000..=384_000).contains(fs)) {
        return Err(ConfigError {
            path: path.to_path_buf(),
            line: text
                .lines()
                .position(|l| l.trim_start().starts_with("sample_rate_hz"))
                .map(|i| i + 1),
            message: format!("sample_rate_hz must be 1000 to 384000 Hz (got {fs})"),
        });
    }
    let speed_of_sound_mps = match &file.speed_of_sound_mps {
        Some(c) if !SPEED_OF_SOUND_RANGE_MPS.contains(c.get_ref()) => {
            return Err(err(
                c.span(),
                format!(
                    "speed_of_sound_mps must be {:?} to {:?} m/s (got {:?})",
                    SPEED_OF_SOUND_RANGE_MPS.start(),
                    SPEED_OF_SOUND_RANGE_MPS.end(),
                    c.get_ref()
                ),
            ))
        }
        c => c.as_ref().map(|c| *c.get_ref()),
    };
    let mut beacons: Vec<BeaconSpec> = Vec::new();
    for entry in &file.beacon {
        beacons.push(beacon_spec(entry.get_ref(), &beacons, room.as_ref(), &err)?);
    }
    Ok((
        Site { arrays, room, sample_rate_hz: file.sample_rate_hz },
        SiteSync { speed_of_sound_mps, beacons },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rotates() {
        let text = "[[array]]\nid = 2\nposition = [1.0, 2.0, 0.5]\nyaw_deg = 90.0\n\n[room]\nmin = [0.0, 0.0, 0.0]\nmax = [10.0, 10.0, 3.0]\n";
        let site = Site::parse(text, Path::new("s.toml")).unwrap();
        let a = site.array(2).unwrap();
        let w = a.to_world([1.0, 0.0, 0.0]);
        assert!((w[0]).abs() < 1e-12 && (w[1] - 1.0).abs() < 1e-12);
        let back = a.to_array(w);
        assert!((back[0] - 1.0).abs() < 1e-12);
        assert_eq!(site.room.unwrap().max[2], 3.0);
    }

    #[test]
    fn reads_the_simulators_site_file() {
        let text = r#"# AIM site file written by host-sim.
sample_rate_hz = 48000
speed_of_sound_mps = 343.2

[[array]]
id = 1
geometry = "respeaker-6mic"
positions = [[0.0463, 0.0], [0.02315, 0.040096976], [-0.02315, 0.040096976], [-0.0463, 0.0], [-0.02315, -0.040096976], [0.02315, -0.040096976]]
position = [10.0, 2.0, 0.05]
yaw_deg = 0.0
clock_offset_s = 0.5
clock_drift_ppm = 0.0

[room]
size = [20.0, 20.0, 5.0]

[[obstacle]]
name = "shelf"
min = [6.5, 7.6, 0.0]
max = [9.5, 8.4, 2.0]
loss_db = 15.0
"#;
        let site = Site::parse(text, Path::new("site.toml")).unwrap();
        assert_eq!(site.sample_rate_hz, Some(48_000));
        assert_eq!(site.room.unwrap().max, [20.0, 20.0, 5.0]);
        let a = site.array(1).unwrap();
        assert!((a.sample_time(48_000.0, 48_000.0) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn bad_files_name_file_and_line() {
        let dup = "[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n\n[[array]]\nid = 1\nposition = [1.0, 0.0, 0.0]\n";
        let e = Site::parse(dup, Path::new("dup.toml")).unwrap_err();
        assert_eq!(e.line, Some(6), "{e}"); // the second array's id
        assert!(e.to_string().starts_with("dup.toml:6: array id 1 appears twice"), "{e}");

        let stacked = "[[array]]\nid = 1\nposition = [1.0, 0.0, 0.0]\n\n[[array]]\nid = 2\nposition = [1.0, 0.05, 0.0]\n";
        let e = Site::parse(stacked, Path::new("st.toml")).unwrap_err();
        assert_eq!(e.line, Some(7), "{e}"); // the second array's position
        assert!(e.message.contains("0.050 m from array 1's"), "{e}");

        let typo = "[[array]]\nid = 1\npositon = [0.0, 0.0, 0.0]\n";
        let e = Site::parse(typo, Path::new("typo.toml")).unwrap_err();
        assert_eq!(e.line, Some(3), "{e}");
        assert!(e.message.contains("positon"), "{e}");

        let syntax = "[[array]]\nid = 1\nposition = [0.0, 0.0\n";
        let e = Site::parse(syntax, Path::new("syn.toml")).unwrap_err();
        assert!(e.line.is_some() && e.to_string().starts_with("syn.toml:"), "{e}");

        let room = "[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n[room]\nmin = [0.0, 0.0, 5.0]\nmax = [1.0, 1.0, 3.0]\n";
        let e = Site::parse(room, Path::new("room.toml")).unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");

        let e = Site::load(Path::new("/nonexistent/site.toml")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/site.toml: cannot read"), "{e}");

        // Whole numbers are numbers.
        let ints = "[[array]]\nid = 1\nposition = [1, 2, 0]\n[room]\nsize = [20, 20, 5]\n";
        let site = Site::parse(ints, Path::new("i.toml")).unwrap();
        assert_eq!(site.array(1).unwrap().position, [1.0, 2.0, 0.0]);

        // A number too many is refused, not dropped (serde's [f64; 3] took the first three).
        for (text, line, got) in [
            ("[[array]]\nid = 1\nposition = [0.0, 0.0, 0.05, 9.0]\n", 3, 4),
            ("[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\npositions = [[0.05, 0.0], [0.0, 0.05, 1.0], [-0.05, 0.0], [0.0, -0.05]]\n", 4, 3),
            ("[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n[room]\nsize = [9.0, 7.0, 3.0, 1.0]\n", 5, 4),
            ("[[array]]\nid = 1\nposition = [0.0, 0.0, 0.0]\n[[obstacle]]\nmin = [1.0, 1.0, 0.0]\nmax = [2.0, 2.0, 1.0, 0.0]\n", 6, 4),
        ] {
            let e = Site::parse(text, Path::new("n.toml")).unwrap_err();
            assert_eq!(e.line, Some(line), "{e}");
            assert!(e.message.contains(&format!("invalid length {got}, expected an array of")), "{e}");
        }
    }

    #[test]
    fn reads_beacons_and_refuses_bad_ones_at_their_line() {
        let base = "speed_of_sound_mps = 343.2\n[[array]]\nid = 1\nposition = [1.0, 1.0, 0.0]\n\n[room]\nsize = [10.0, 10.0, 3.0]\n\n[[beacon]]\nid = 1\nposition = [8.0, 0.2, 1.5]\nperiod_s = 1.0\nsequence = \"aim-beacon-v1\"\nlevel_db = 60.0\n";
        Site::parse(base, Path::new("s.toml")).unwrap();
        let site = SiteSync::parse(base, Path::new("s.toml")).unwrap();
        assert_eq!(site.speed_of_sound_mps, Some(343.2));
        let b = site.beacon(1).unwrap();
        assert_eq!(b.position, [8.0, 0.2, 1.5]);
        assert_eq!(
            (b.period_s, b.sequence.as_str(), b.level_db),
            (1.0, "aim-beacon-v1", Some(60.0))
        );
        // Without beacons and speed of sound: both absent.
        let plain =
            SiteSync::parse("[[array]]\nid = 1\nposition = [1.0, 1.0, 0.0]\n", Path::new("p"))
                .unwrap();
        assert!(plain.beacons.is_empty() && plain.speed_of_sound_mps.is_none());
        let cases: &[(&str, &str, usize, &str)] = &[
            ("period_s = 1.0", "period_s = 0.0", 12, "period_s must be"),
            ("level_db = 60.0", "level_db = 900.0", 14, "level_db must be"),
            ("position = [8.0, 0.2, 1.5]", "position = [8.0, 20.0, 1.5]", 11, "outside the room"),
            ("position = [8.0, 0.2, 1.5]", "position = [nan, 0.2, 1.5]", 11, "must be finite"),
            ("sequence = \"aim-beacon-v1\"", "sequence = \" \"", 13, "must name a sequence"),
            ("sequence = \"aim-beacon-v1\"", "sequence = \"nope\"", 13, "`nope` is unknown"),
            ("sequence = \"aim-beacon-v1\"", "sequenc = \"x\"", 13, "sequenc"),
            ("period_s = 1.0", "period_s = 1.0\nclock_offset_s = 0.2", 13, "clock_offset_s"),
            ("id = 1\nposition = [8.0", "id = 256\nposition = [8.0", 10, "ids are 0 to 255"),
            ("speed_of_sound_mps = 343.2", "speed_of_sound_mps = 3432.0", 1, "speed_of_sound_mps"),
        ];
        for (from, to, line, message) in cases {
            let text = base.replace(from, to);
            assert_ne!(text, base, "{from}");
            let e = Site::parse(&text, Path::new("s.toml")).unwrap_err();
            assert_eq!(e.line, Some(*line), "{to}: {e}");
            assert!(e.message.contains(message), "{to}: {e}");
        }
        let twice = format!("{base}\n[[beacon]]\nid = 1\nposition = [1.0, 1.0, 1.0]\nperiod_s = 2.0\nsequence = \"s\"\n");
        let e = Site::parse(&twice, Path::new("s.toml")).unwrap_err();
        assert_eq!(e.line, Some(17), "{e}");
        assert!(e.message.contains("beacon id 1 appears twice"), "{e}");
    }

    /// Every site input of issue 17 that used to be accepted (or to reach the filter as NaN)
    /// is refused at the line of the offending value.
    #[test]
    fn absurd_values_are_refused_at_their_line() {
        let base = "[[array]]\nid = 1\nposition = [1.0, 1.0, 0.0]\n";
        let cases: &[(&str, usize, &str)] = &[
            ("position = [1e16, 0.0, 0.0]", 3, "position must be finite and within"),
            ("position = [1e300, 0.0, 0.0]", 3, "position must be finite and within"),
            ("position = [nan, 0.0, 0.0]", 3, "position must be finite"),
            ("position = [1.0, 1.0, 0.0]\nclock_drift_ppm = 1e12", 4, "clock_drift_ppm must be within"),
            ("position = [1.0, 1.0, 0.0]\nclock_offset_s = inf", 4, "clock_offset_s must be within"),
            ("position = [1.0, 1.0, 0.0]\nyaw_deg = 1e20", 4, "yaw_deg must be within"),
            ("position = [1.0, 1.0, 0.0]\ngeometry = \"respeaker-7mic\"", 4, "geometry `respeaker-7mic` is unknown"),
            ("position = [1.0, 1.0, 0.0]\npositions = []", 4, "positions lists 0 microphones"),
            (
                "position = [1.0, 1.0, 0.0]\npositions = [[0.0, 0.0], [1e9, 0.0], [0.0, 0.1], [0.1, 0.1]]",
                4,
                "microphone 1",
            ),
            ("position = [1.0, 1.0, 0.0]\ngeometry = \"custom\"", 4, "needs `positions`"),
            (
                "position = [1.0, 1.0, 0.0]\ngeometry = \"respeaker-4mic\"\n\
                 positions = [[0.0463, 0.0], [0.0, 0.0463], [-0.0463, 0.0], [0.0, -0.0463]]",
                5,
                "are not those of geometry `respeaker-4mic`",
            ),
        ];
        for (array_lines, line, message) in cases {
            let text = base.replace("position = [1.0, 1.0, 0.0]", array_lines);
            let e = Site::parse(&text, Path::new("s.toml")).unwrap_err();
            assert_eq!(e.line, Some(*line), "{array_lines}: {e}");
            assert!(e.message.contains(message), "{array_lines}: {e}");
        }
        // The informative obstacles and the `[origin]` are checked even when nothing uses them.
        let tables: &[(&str, usize, &str)] = &[
            ("[[obstacle]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, nan, 1.0]", 4, "obstacle 1: min"),
            ("[[obstacle]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nbogus = 1", 7, "bogus"),
            (
                "[[obstacle]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nloss_db = -5.0",
                4,
                "loss_db",
            ),
            (
                "[origin]\nposition = [nan, 0.0, 0.0]\nx_axis_from_north_deg = 0.0",
                5,
                "origin position",
            ),
            ("[origin]\nx_axis_from_north_deg = 0.0\nfoo = 1", 6, "foo"),
        ];
        for (table, line, message) in tables {
            let e = Site::parse(&format!("{base}{table}\n"), Path::new("s.toml")).unwrap_err();
            assert_eq!(e.line, Some(*line), "{table}: {e}");
            assert!(e.message.contains(message), "{table}: {e}");
        }
        // A named geometry without positions stands for its microphones (the Hello is checked
        // against them); with the preset's own positions it reads.
        let named = base.replace("0.0]\n", "0.0]\ngeometry = \"circle-8mic\"\n");
        let site = Site::parse(&named, Path::new("s.toml")).unwrap();
        let eight = aim_dsp::Geometry::circle_8mic();
        assert_eq!(site.arrays[0].mic_positions_m.len(), 8);
        for (m, g) in site.arrays[0].mic_positions_m.iter().zip(eight.positions()) {
            assert!((m[0] - f64::from(g[0])).abs() < 1e-4 && (m[1] - f64::from(g[1])).abs() < 1e-4);
        }
        let six = "geometry = \"respeaker6\"\npositions = [[0.0463, 0.0], [0.02315, 0.040096976], \
                   [-0.02315, 0.040096976], [-0.0463, 0.0], [-0.02315, -0.040096976], \
                   [0.02315, -0.040096976]]\n";
        Site::parse(&base.replace("0.0]\n", &format!("0.0]\n{six}")), Path::new("s.toml")).unwrap();
        let outside = format!("{base}[room]\nsize = [5.0, 5.0, 3.0]\n")
            .replace("[1.0, 1.0, 0.0]", "[1.0, 9.0, 0.0]");
        let e = Site::parse(&outside, Path::new("s.toml")).unwrap_err();
        assert_eq!(e.line, Some(3), "{e}");
        assert!(e.message.contains("outside the room"), "{e}");
        let huge_room = format!("{base}[room]\nsize = [1e300, 5.0, 3.0]\n");
        let e = Site::parse(&huge_room, Path::new("s.toml")).unwrap_err();
        assert!(e.message.contains("corners must lie within"), "{e}");
        let e =
            Site::parse(&format!("sample_rate_hz = 7\n{base}"), Path::new("s.toml")).unwrap_err();
        assert_eq!(e.line, Some(1), "{e}");
        let e = Site::parse(&base.replace("id = 1", "id = 300"), Path::new("s.toml")).unwrap_err();
        assert!(e.message.contains("ids 0 to 255"), "{e}");
        // On the wall is inside; the bundled simulator site still reads.
        let wall = format!("{base}[room]\nsize = [5.0, 5.0, 3.0]\n")
            .replace("[1.0, 1.0, 0.0]", "[5.0, 1.0, 3.05]");
        Site::parse(&wall, Path::new("s.toml")).unwrap();
    }
}
