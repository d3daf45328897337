//! `aim record`: store the raw byte stream of a serial port in a file.

use std::time::{Duration, Instant};

use aim_tracker::link::{self, record::Until};
use anyhow::Context as _;

/// Arguments of `aim record`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    link: super::SerialArgs,
    /// File to write the raw bytes to (replaced if it exists). Replay with `aim frames FILE`.
    #[arg(long)]
    out: std::path::PathBuf,
    /// Stop after this many seconds (default: run until interrupted with Ctrl-C; everything
    /// read until then is in the file).
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many frames have been decoded.
    #[arg(long)]
    frames: Option<u64>,
}

/// Runs `aim record`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let deadline = match args.duration {
        Some(s) if s.is_finite() && s >= 0.0 => Some(Instant::now() + Duration::from_secs_f64(s)),
        Some(s) => anyhow::bail!("--duration must be a non-negative number of seconds, not {s}"),
        None => None,
    };
    let mut port = args.link.open()?;
    let mut out = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Tests and scripts wait for this line before they send: the port is configured now.
    eprintln!(
        "recording {} at {} baud to {}",
        args.link.serial,
        args.link.baud,
        args.out.display()
    );
    let spinner = indicatif::ProgressBar::new_spinner();
    let mut last_draw = Instant::now();
    let stats = link::record::record(
        &mut port,
        &mut out,
        Until { deadline, frames: args.frames },
        &mut |s| {
            if last_draw.elapsed() >= Duration::from_millis(200) {
                last_draw = Instant::now();
                spinner.set_message(format!(
                    "{} bytes, {} frames, {} damaged",
                    s.bytes,
                    s.frames,
                    s.errors()
                ));
                spinner.tick();
            }
        },
    )
    .with_context(|| format!("recording {} to {}", args.link.serial, args.out.display()))?;
    spinner.finish_and_clear();
    eprintln!(
        "recorded {} bytes ({} frames, {} damaged or unknown) to {}",
        stats.bytes,
        stats.frames,
        stats.errors(),
        args.out.display()
    );
    Ok(())
}
