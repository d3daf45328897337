//! End-to-end evaluation: simulated recordings through the on-chip pipeline and the wire
//! format into the tracker, and the track against the truth.
//!
//! - [`link`]: an array's recording → TDM words → `aim-dsp` → frames encoded by
//!   `aim_wire::from_dsp` into the bytes a board would send, and decoded again;
//! - [`metrics`]: position error (mean, median, p90), availability, motion-class accuracy;
//! - [`plot`]: a PNG of the track against the truth (top view and height), no text needed.

pub mod link;
pub mod metrics;
pub mod plot;
