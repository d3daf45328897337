//! `aim record`: store the raw byte stream of a serial port in a file (or, with `--zenoh`, the
//! frames of every array on the Zenoh bus in arrival order: the same format).
//!
//! It ends after `--duration` or `--frames`, on Ctrl-C / SIGTERM (exit status 130) or when the
//! port is lost and does not come back (exit status 3); the summary line is printed on every
//! one of these paths and the file holds every byte read until then. While the board is
//! unplugged the recording waits (`--reconnect`, `--give-up`) and goes on in the same file.

use std::time::{Duration, Instant};

use aim_tracker::exit::{note, Interrupted};
use aim_tracker::link::{self, record::Until};
use anyhow::Context as _;

/// Longest `--duration` accepted, s (one year).
pub const MAX_DURATION_S: f64 = 365.0 * 86_400.0;

/// Arguments of `aim record`.
#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    link: super::SerialArgs,
    /// File to write the raw bytes to (replaced if it exists). Replay with `aim frames FILE`.
    #[arg(long)]
    out: std::path::PathBuf,
    /// Stop after this many seconds, at most a year (default: run until interrupted with
    /// Ctrl-C; everything read until then is in the file).
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many frames have been decoded.
    #[arg(long)]
    frames: Option<u64>,
}

/// The deadline `--duration` sets, or why the value is refused.
pub fn deadline(duration_s: Option<f64>, now: Instant) -> anyhow::Result<Option<Instant>> {
    let Some(s) = duration_s else { return Ok(None) };
    let refuse =
        || anyhow::anyhow!("--duration must be 0 to {MAX_DURATION_S} s (a year), not {s:?}");
    if !(s.is_finite() && (0.0..=MAX_DURATION_S).contains(&s)) {
        return Err(refuse());
    }
    let d = Duration::try_from_secs_f64(s).map_err(|_| refuse())?;
    now.checked_add(d).map(Some).ok_or_else(refuse)
}

/// Runs `aim record`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let deadline = deadline(args.duration, Instant::now())?;
    if args.link.zenoh {
        return run_zenoh(&args, Until { deadline, frames: args.frames });
    }
    let mut port = args.link.open()?;
    let serial = args.link.port()?;
    let mut out = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Tests and scripts wait for this line before they send: the port is configured now.
    note(&format!("recording {} at {} baud to {}", serial, args.link.baud, args.out.display()));
    let (stats, result) =
        record_with_spinner(&mut port, &mut out, Until { deadline, frames: args.frames });
    // The summary on every path: done, interrupted, port lost, file error.
    note(&format!(
        "recorded {} bytes ({} frames, {} damaged or unknown) to {}{}",
        stats.bytes,
        stats.frames,
        stats.errors(),
        args.out.display(),
        match port.losses() {
            0 => String::new(),
            n => format!("; the port was lost {n} time(s)"),
        }
    ));
    result.with_context(|| format!("recording {} to {}", serial, args.out.display()))?;
    if port.interrupted() {
        return Err(Interrupted.into());
    }
    Ok(())
}

/// `aim record --zenoh`: the frames of every array on the bus, in arrival order, to the file
/// (each sample's bytes as received: an ordinary recording).
#[cfg(feature = "zenoh")]
fn run_zenoh(args: &Args, until: Until) -> anyhow::Result<()> {
    use aim_tracker::link::bus::{FrameFeed, FRAMES_ALL};
    use zenoh::Wait as _;
    let session = args.link.bus.open()?;
    let mut feed = FrameFeed::subscribe(&session)?.stop_on(link::serial::interrupt_flag()?);
    let mut out = std::fs::File::create(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Tests and scripts wait for this line before they publish: the subscription is declared.
    note(&format!("recording {FRAMES_ALL} to {}", args.out.display()));
    let (stats, result) = record_with_spinner(&mut feed, &mut out, until);
    note(&format!(
        "recorded {} bytes ({} frames, {} damaged or unknown) to {}",
        stats.bytes,
        stats.frames,
        stats.errors(),
        args.out.display(),
    ));
    let _ = session.close().wait();
    result.with_context(|| format!("recording {FRAMES_ALL} to {}", args.out.display()))?;
    if feed.interrupted() {
        return Err(Interrupted.into());
    }
    Ok(())
}

/// `aim record --zenoh` in an `aim` built without the bus.
#[cfg(not(feature = "zenoh"))]
fn run_zenoh(_args: &Args, _until: Until) -> anyhow::Result<()> {
    Err(super::bus::unavailable())
}

/// [`link::record::record`] with a spinner showing the counts on stderr.
fn record_with_spinner(
    port: &mut dyn std::io::Read,
    out: &mut dyn std::io::Write,
    until: Until,
) -> (aim_wire::LinkStats, std::io::Result<()>) {
    let spinner = indicatif::ProgressBar::new_spinner();
    let mut last_draw = Instant::now();
    let (stats, result) = link::record::record(port, out, until, &mut |s| {
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
    });
    spinner.finish_and_clear();
    (stats, result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_out_of_range_are_refused_without_panic() {
        let now = Instant::now();
        for bad in [1e300, -1.0, f64::NAN, f64::INFINITY, MAX_DURATION_S * 2.0] {
            let e = deadline(Some(bad), now).unwrap_err().to_string();
            assert!(e.starts_with("--duration must be 0 to"), "{e}");
        }
        assert_eq!(deadline(Some(1.5), now).unwrap(), Some(now + Duration::from_millis(1500)));
        assert_eq!(deadline(None, now).unwrap(), None);
    }
}
