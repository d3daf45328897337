//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`), until interrupted.
//!
//! The port is a [`aim_tracker::link::serial::Link`]: unplugging the board is said on stderr
//! and tracking goes on when the port returns (`--reconnect`, `--give-up`). On Ctrl-C
//! (status 130) or a port that does not return (status 3) the link statistics are printed
//! on stderr.

use aim_tracker::exit::{note, Interrupted};
use aim_tracker::link::{self, FrameSource};

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
    let result = track_frames(&args.link.serial, &mut source, &mut tracker, &mut converter, true);
    note(&format!("{}: {}", args.link.serial, link::json::stats(source.stats())));
    result?;
    if source.get_mut().interrupted() {
        return Err(Interrupted.into());
    }
    Ok(())
}
