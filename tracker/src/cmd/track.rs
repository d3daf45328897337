//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`), until interrupted.

use aim_tracker::link::{self, FrameSource};

use super::replay::{track_frames, TrackOptions};

/// Arguments of `aim track`.
#[derive(clap::Args)]
pub struct Args {
    /// Serial port of the array board (`/dev/ttyACM0`, `COM3`).
    #[arg(long)]
    serial: String,
    /// Baud rate.
    #[arg(long, default_value_t = link::serial::DEFAULT_BAUD)]
    baud: u32,
    #[command(flatten)]
    options: TrackOptions,
}

/// Runs `aim track`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (mut tracker, mut converter) = args.options.build()?;
    let mut source = FrameSource::new(link::serial::open(&args.serial, args.baud)?);
    track_frames(&args.serial, &mut source, &mut tracker, &mut converter, true)
}
