//! Where the fixes go besides the JSON lines of `aim track`/`aim replay`:
//!
//! - [`ned`]: the site's origin and heading (the `[origin]` table of the site file), and the
//!   turn of a site position and covariance into a local north–east–down frame;
//! - [`mavlink`]: fixes as MAVLink `VISION_POSITION_ESTIMATE` messages (with `HEARTBEAT`) to an
//!   autopilot over UDP or a serial port.

pub mod mavlink;
pub mod ned;
