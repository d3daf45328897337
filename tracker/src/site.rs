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
//! geometry = "respeaker-6mic"  # optional, informative
//! positions = [[0.0463, 0.0]]  # optional: microphone positions, array frame, m (checked
//!                              # against the array's Hello)
//! clock_offset_s = 0.0         # optional: true time of the array's sample 0, s
//! clock_drift_ppm = 0.0        # optional: the array clock's rate error, ppm
//!
//! [room]                       # optional: the flight volume, world metres, either
//! min = [-1.0, -1.0, 0.0]
//! max = [12.0, 12.0, 4.0]
//! # or `size = [Lx, Ly, Lz]` for the shoebox [0, Lx] × [0, Ly] × [0, Lz]
//!
//! [[obstacle]]                 # optional, informative: name, min, max, loss_db
//! ```
//! This is a superset of the `site.toml` that `host-sim simulate` writes.
//! The array frame is x right, y forward, z up along the array normal; the rotation from the
//! array frame to the world is R = Rz(yaw)·Ry(pitch)·Rx(roll).

use std::path::Path;

use serde::Deserialize;

use crate::config::{line_of, parse_toml, read_text, ConfigError};

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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SiteFile {
    sample_rate_hz: Option<u32>,
    #[allow(dead_code)]
    speed_of_sound_mps: Option<f64>,
    #[serde(default)]
    array: Vec<toml::Spanned<ArrayEntry>>,
    room: Option<toml::Spanned<RoomEntry>>,
    #[serde(default)]
    #[allow(dead_code)]
    obstacle: Vec<toml::Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ArrayEntry {
    id: u16,
    position: [f64; 3],
    #[serde(default)]
    yaw_deg: f64,
    #[serde(default)]
    pitch_deg: f64,
    #[serde(default)]
    roll_deg: f64,
    geometry: Option<String>,
    #[serde(default)]
    positions: Vec<[f64; 2]>,
    #[serde(default)]
    clock_offset_s: f64,
    #[serde(default)]
    clock_drift_ppm: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RoomEntry {
    min: Option<[f64; 3]>,
    max: Option<[f64; 3]>,
    size: Option<[f64; 3]>,
}

impl Site {
    /// Reads and checks a site file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, path)
    }

    /// Parses and checks site TOML `text` (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
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
            let a = entry.get_ref();
            let finite = a
                .position
                .iter()
                .chain(&[a.yaw_deg, a.pitch_deg, a.roll_deg])
                .chain(&[a.clock_offset_s, a.clock_drift_ppm])
                .all(|v| v.is_finite());
            if !finite {
                return Err(err(
                    entry.span(),
                    format!("array {}: position and angles must be finite", a.id),
                ));
            }
            if arrays.iter().any(|p| p.id == a.id) {
                return Err(err(entry.span(), format!("array id {} appears twice", a.id)));
            }
            let mut pose = ArrayPose::new(
                a.id,
                a.position,
                a.yaw_deg.to_radians(),
                a.pitch_deg.to_radians(),
                a.roll_deg.to_radians(),
            );
            pose.geometry = a.geometry.clone();
            if !a.positions.iter().flatten().all(|v| v.is_finite()) {
                return Err(err(
                    entry.span(),
                    format!("array {}: microphone positions must be finite", a.id),
                ));
            }
            pose.mic_positions_m = a.positions.clone();
            pose.clock_offset_s = a.clock_offset_s;
            pose.clock_drift_ppm = a.clock_drift_ppm;
            arrays.push(pose);
        }
        let room = match &file.room {
            Some(r) => {
                let e = r.get_ref();
                let (min, max) = match (e.min, e.max, e.size) {
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
                Some(Room { min, max })
            }
            None => None,
        };
        if file.sample_rate_hz == Some(0) {
            return Err(ConfigError {
                path: path.to_path_buf(),
                line: None,
                message: "sample_rate_hz must be positive".into(),
            });
        }
        Ok(Self { arrays, room, sample_rate_hz: file.sample_rate_hz })
    }

    /// The array with this id.
    pub fn array(&self, id: u16) -> Option<&ArrayPose> {
        self.arrays.iter().find(|a| a.id == id)
    }
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
positions = [[0.0463, 0.0], [0.02315, 0.0401]]
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
        assert_eq!(e.line, Some(5), "{e}"); // the second [[array]] header
        assert!(e.to_string().starts_with("dup.toml:5: array id 1 appears twice"), "{e}");

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
    }
}
