//! `aim track --serial PORT [--baud N] --site SITE.toml`: track live from an array's serial
//! link and print one JSON fix per output period (as `aim replay`, through the same intake),
//! until interrupted or the port goes away; then the statistics line on stderr.
//!
//! The port is a [`aim_tracker::link::serial::Link`]: unplugging the board is said on stderr
//! and tracking goes on when the port returns (`--reconnect`, `--give-up`). On Ctrl-C
//! (status 130) or a port that does not return (status 3) the statistics are printed too.
//!
//! Every `--status-every` seconds (default 10, 0: never) a status line goes to stderr
//! ([`aim_tracker::status::Status::line`]): per array its frames, sequence gaps (frames
//! missed), restarts, announced reboots, the board's `Health` counters (ring and SAI overruns,
//! DSP overloads, uplink drops, UART errors, clipped samples), the age of its last frame and a
//! dead-microphone flag; the link's CRC and framing errors; frames from arrays not in the site.

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
    /// Print the status line on stderr every this many seconds (0: never).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    status_every: f64,
}

/// Runs `aim track`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let every = aim_tracker::config::check_flag(
        args.status_every,
        "--status-every",
        STATUS_EVERY_RANGE_S,
        "s",
    )?;
    if every > 0.0 && every < MIN_STATUS_EVERY_S {
        anyhow::bail!(
            "--status-every must be 0 (never) or at least {MIN_STATUS_EVERY_S} s, not {every}"
        );
    }
    let mut session = args.options.build()?;
    if every > 0.0 {
        spawn_status_line(&session, every);
    }
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

/// Allowed `--status-every`, s (0: off; up to a day).
const STATUS_EVERY_RANGE_S: std::ops::RangeInclusive<f64> = 0.0..=86_400.0;
/// Shortest status period, s: a line more often would flood stderr.
const MIN_STATUS_EVERY_S: f64 = 0.1;

/// Prints the session's status line on stderr every `every_s` seconds, from a thread of its
/// own so a silent link still shows (its last frame's age grows); ends with the process.
fn spawn_status_line(session: &aim_tracker::session::Session, every_s: f64) {
    let status = session.status();
    let started = session.started();
    std::thread::spawn(move || loop {
        std::thread::sleep(std::time::Duration::from_secs_f64(every_s));
        let now = started.elapsed().as_secs_f64();
        let line = status.lock().unwrap_or_else(std::sync::PoisonError::into_inner).line(now, now);
        eprintln!("{line}");
    });
}
