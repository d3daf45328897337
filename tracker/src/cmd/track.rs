//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`, through the same intake),
//! until interrupted or the port goes away; then the statistics line on stderr.
//!
//! The port is a [`aim_tracker::link::serial::Link`]: unplugging the board is said on stderr
//! and tracking goes on when the port returns (`--reconnect`, `--give-up`). On Ctrl-C
//! (status 130) or a port that does not return (status 3) the statistics are printed too.

use aim_tracker::exit::Interrupted;
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
    let result =
        track_frames(&args.link.serial, &mut source, &mut session, &args.options.site, true);
    result?;
    if source.get_mut().interrupted() {
        return Err(Interrupted.into());
    }
    Ok(())
}
