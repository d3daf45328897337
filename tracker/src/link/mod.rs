//! Frame intake: the byte stream of an array, from a serial port, a recorded file or stdin,
//! turned into [`aim_wire::Frame`]s with link statistics.
//!
//! - [`FrameSource`]: any [`std::io::Read`] → frames (an iterator) and [`aim_wire::LinkStats`].
//! - [`serial`]: opens a serial port the way every `aim` command does (raw, 8N1, timeouts).
//! - [`record`]: copies a port's raw bytes to a file, unchanged, so a replay of the file
//!   decodes the very frame sequence the live link did.
//! - [`json`]: frames and statistics as the JSON objects `aim frames` prints.
//! - [`boards`]: the board behind each array id, from its `Hello`: reboots, duplicate ids.
//! - `bus` (feature `zenoh`): frames and fixes on the Zenoh bus (`aim gateway`, `--zenoh`).
//!
//! ```no_run
//! use aim_tracker::link::{self, FrameSource};
//! # fn main() -> anyhow::Result<()> {
//! let mut source = FrameSource::new(link::open_input("recording.aimraw")?);
//! for frame in source.by_ref() {
//!     let frame = frame?; // only I/O errors end up here; damaged frames are counted
//!     println!("{:?}", frame.header);
//! }
//! println!("{:?}", source.stats());
//! # Ok(()) }
//! ```

pub mod boards;
#[cfg(feature = "zenoh")]
pub mod bus;
mod frame_bytes;
pub mod json;
pub mod merge;
pub mod ports;
pub mod record;
pub mod serial;
mod source;

pub use merge::Merged;
pub use ports::Ports;
pub use source::{open_input, FrameSource};
