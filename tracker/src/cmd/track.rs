//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`), until interrupted.

use aim_tracker::link::FrameSource;

use super::replay::{track_frames, TrackOptions};

/// Arguments of `aim track`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    link: super::SerialArgs,
    #[command(flatten)]
    options: TrackOptions,
}

/// Runs `aim track`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (mut tracker, mut converter) = args.options.build()?;
    let mut source = FrameSource::new(args.link.open()?);
    track_frames(&args.link.serial, &mut source, &mut tracker, &mut converter, true)
}
