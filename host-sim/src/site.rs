//! The site file, `site.toml`: where the arrays are, for the tracker.
//!
//! Format (TOML; all positions ENU metres, angles in degrees):
//!
//! ```toml
//! sample_rate_hz = 48000          # nominal sample rate of the arrays
//! speed_of_sound_mps = 343.2      # in the simulated air
//!
//! [[array]]
//! id = 1                          # array id, as in the frame header (0..=255)
//! geometry = "respeaker-6mic"     # preset name, or "custom"
//! positions = [[0.0463, 0.0], ...] # microphone positions in the array frame, m (always written)
//! position = [8.0, 2.0, 0.05]     # array centre, ENU m
//! yaw_deg = 0.0                   # array x axis from ENU +x towards +y, degrees
//! roll_deg = 180.0                # only for an array facing down (turned over about its x axis)
//!
//! [room]                          # optional
//! size = [16.0, 16.0, 5.0]        # shoebox [0, Lx] × [0, Ly] × [0, Lz], m
//!
//! [[obstacle]]                    # optional, any number
//! name = "shelf"
//! min = [6.5, 7.6, 0.0]           # box corners, m
//! max = [9.5, 8.4, 2.0]
//! loss_db = 15.0
//!
//! [[beacon]]                      # optional, any number: synchronisation loudspeakers
//! id = 1                          # beacon id
//! position = [8.0, 0.2, 1.5]      # loudspeaker, ENU m (surveyed)
//! period_s = 1.0                  # nominal repetition period on the speaker's clock, s
//! sequence = "aim-beacon-v1"      # name of the aim_dsp::beacon sequence
//! level_db = 60.0                 # information: RMS dB SPL at 1 m
//! ```
//!
//! Array frame: x right, y forward, z up (normal); azimuth from +x towards +y, zenith from +z.
//! A reader needs `id`, `positions` (or a known `geometry`), `position`, `yaw_deg` and
//! `roll_deg` (180 for an array facing down; a reader that ignores it mirrors that array's
//! bearings); the rest is information.
//!
//! Only what a real site knows goes here: the arrays' clock offsets and drifts and the drone's
//! airframe are simulation truth (`truth.toml`, [`crate::truth::Truth::to_toml`]); the tracker
//! times frames by each array's own sample clock.
use std::path::Path;

use anyhow::Context as _;
use serde::{Deserialize, Serialize};

/// One array in the site.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteArray {
    /// Array id.
    pub id: u8,
    /// Geometry preset name, or `custom`.
    pub geometry: String,
    /// Microphone positions, array frame, m.
    #[serde(default)]
    pub positions: Vec<[f64; 2]>,
    /// Array centre, ENU m.
    pub position: [f64; 3],
    /// Rotation of the array's x axis from ENU +x towards +y, degrees.
    pub yaw_deg: f64,
    /// Rotation about the array's x axis before the yaw, degrees: 180 for an array facing
    /// down, 0 (not written) for one facing up.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roll_deg: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The room, as far as the site file tells it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteRoom {
    /// Shoebox dimensions, m.
    pub size: [f64; 3],
}

/// An obstacle box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteObstacle {
    /// Name.
    pub name: String,
    /// Lowest corner, ENU m.
    pub min: [f64; 3],
    /// Highest corner, ENU m.
    pub max: [f64; 3],
    /// Transmission loss, dB.
    pub loss_db: f64,
}

/// A synchronisation beacon: where it is and what it plays (never its clock).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteBeacon {
    /// Beacon id.
    pub id: u8,
    /// Loudspeaker position, ENU m.
    pub position: [f64; 3],
    /// Nominal repetition period on the speaker's clock, s.
    pub period_s: f64,
    /// Name of the `aim_dsp::beacon` sequence.
    pub sequence: String,
    /// RMS level of an emission, dB SPL at 1 m (information).
    pub level_db: f64,
}

/// The site file's content.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Nominal sample rate, Hz.
    pub sample_rate_hz: u32,
    /// Speed of sound, m/s.
    pub speed_of_sound_mps: f64,
    /// The arrays.
    #[serde(rename = "array")]
    pub arrays: Vec<SiteArray>,
    /// The room, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub room: Option<SiteRoom>,
    /// Obstacles.
    #[serde(default, rename = "obstacle", skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<SiteObstacle>,
    /// Synchronisation beacons.
    #[serde(default, rename = "beacon", skip_serializing_if = "Vec::is_empty")]
    pub beacons: Vec<SiteBeacon>,
}

impl Site {
    /// The TOML text, with a header comment.
    pub fn to_toml(&self) -> anyhow::Result<String> {
        let body = toml::to_string(self).context("serializing the site")?;
        Ok(format!(
            "# AIM site file written by host-sim. ENU metres; yaw_deg in degrees from +x towards +y;\n\
             # arrays face up unless roll_deg = 180 (facing down); microphone positions in the array frame (x right, y forward).\n{body}"
        ))
    }

    /// Reads a site file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Self::parse(&text, path)
    }

    /// Parses the text of a site file read from `path` (named in errors).
    pub fn parse(text: &str, path: &Path) -> anyhow::Result<Self> {
        toml::from_str(text).with_context(|| format!("in site file {}", path.display()))
    }
}
