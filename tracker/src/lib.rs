//! AIM host tracker: from array frames (bearings and BPF peaks) to drone positions, with the
//! method of ALGORITHMS.md §4–8 (single array).
//!
//! - [`observation`]: the plain inputs (bearings, BPF peaks);
//! - [`iqr`], [`doa`]: IQR smoothing, DoA trend and the LoS decision per array;
//! - [`motion`]: motion classes (paper Table I);
//! - [`doppler`]: the Doppler of the BPF lines, the range cue of one array;
//! - [`dynamics`]: thrust, hover self-calibration, accelerations and speeds;
//! - [`filter`]: the paper's position-only Kalman filter and the `aim` EKF mixture;
//! - [`tracker`]: the pipeline that runs them at a fixed output period;
//! - [`link`], [`intake`], [`session`]: link bytes → frames → inputs in time order on one time
//!   base → the tracker, the one path of `aim track`, `aim replay` and `host-sim fly`;
//! - [`status`]: per-array link and board counters, the status line of `aim track`;
//! - [`serve`]: the live map in the browser (`--serve`);
//! - [`profile`], [`site`]: drone profiles and site files (TOML);
//! - [`zenith`]: the site calibration of each array's zenith (`aim calibrate`);
//! - [`id`]: is a drone in a recording, and which type (`aim id`);
//! - [`output`]: fixes to other systems (MAVLink to an autopilot, in the site's NED frame);
//! - [`multi`]: several arrays (§9): beacon clock sync, multilateration, array selection,
//!   complementary fusion, DoA-ray triangulation (library pieces, not yet in the pipeline).
#![warn(missing_docs)]

pub mod config;
pub mod doa;
pub mod doppler;
pub mod dynamics;
pub mod exit;
pub mod filter;
pub mod id;
pub mod intake;
pub mod interarray;
pub mod iqr;
pub mod linalg;
pub mod link;
pub mod motion;
pub mod multi;
pub mod observation;
pub mod output;
pub mod profile;
pub mod serve;
pub mod session;
pub mod site;
pub mod status;
#[cfg(test)]
mod testutil;
pub mod tracker;
pub mod wake;
pub mod yaw;
pub mod zenith;
