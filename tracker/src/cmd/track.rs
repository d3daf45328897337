//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`, through the same intake),
//! until interrupted or the port goes away; then the statistics line on stderr.

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
    let mut session = args.options.build()?;
    let mut source = FrameSource::new(args.link.open()?);
    // Scripts and tests wait for this line before they send: the port is configured now.
    eprintln!("tracking {} at {} baud", args.link.serial, args.link.baud);
    track_frames(&args.link.serial, &mut source, &mut session, &args.options.site, true)
}
