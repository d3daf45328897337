//! Site files: where the arrays are and how they face.
//!
//! ```toml
//! # one table per array
//! [[array]]
//! id = 0
//! position = [0.0, 0.0, 0.0]   # metres, world ENU
//! yaw_deg = 0.0                # array +x from world east, counter-clockwise
//! pitch_deg = 0.0              # optional: rotation about the array's y, degrees
//! roll_deg = 0.0               # optional: rotation about the array's x, degrees
//! geometry = "respeaker-6mic"  # optional, informative
//!
//! [room]                       # optional: the flight volume, world metres
//! min = [-1.0, -1.0, 0.0]
//! max = [12.0, 12.0, 4.0]
//! ```
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
        Self { id, position, rotation, geometry: None }
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
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SiteFile {
    #[serde(default)]
    array: Vec<toml::Spanned<ArrayEntry>>,
    room: Option<toml::Spanned<RoomEntry>>,
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
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RoomEntry {
    min: [f64; 3],
    max: [f64; 3],
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
            arrays.push(pose);
        }
        let room = match &file.room {
            Some(r) => {
                let e = r.get_ref();
                if (0..3)
                    .any(|i| !(e.min[i].is_finite() && e.max[i].is_finite() && e.min[i] < e.max[i]))
                {
                    return Err(err(r.span(), "room: every min must be below its max".into()));
                }
                Some(Room { min: e.min, max: e.max })
            }
            None => None,
        };
        Ok(Self { arrays, room })
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
