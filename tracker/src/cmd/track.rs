//! `aim track --serial PORT [--serial PORT2 ...] [--baud N] --site SITE.toml`: track live from
//! the arrays' serial links (several read at once by [`aim_tracker::link::Ports`]) and print
//! one JSON fix per output period (as `aim replay`, through the same intake), until
//! interrupted or the ports go away; then the statistics line on stderr.
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

use aim_tracker::serve::tap::{Pace, Tap};
use aim_tracker::serve::LiveMap;

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
    /// With `--zenoh`: this tracker's name on the bus, its fixes go to `aim/track/<name>/fix`
    /// (default: the site file's name without `.toml`).
    #[arg(long)]
    name: Option<String>,
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
    let mavlink = args.options.mavlink.open(&args.options.site)?;
    if every > 0.0 {
        spawn_status_line(&session, every);
    }
    let map = args.options.serve.start(&args.options.site)?;
    if args.link.zenoh {
        return track_zenoh(&args, &mut session, mavlink.as_ref(), map);
    }
    if args.link.serial.len() > 1 {
        return track_ports(&args, &mut session, mavlink.as_ref(), map);
    }
    let port = args.link.port()?;
    let mut source = FrameSource::new(Tap::new(args.link.open()?, map.clone(), Pace::Free));
    // Scripts and tests wait for this line before they send: the port is configured now.
    eprintln!("tracking {} at {} baud", port, args.link.baud);
    let site = &args.options.site;
    let result =
        track_frames(port, &mut source, &mut session, site, true, mavlink.as_ref(), &mut |fix| {
            super::serve::show(&map, fix)
        });
    ended(map.as_ref(), result, || Ok(source.get_mut().get_mut().interrupted()))
}

/// The end of a track: the live map told, then the stream's error, else exit status 130 if
/// the stream ended on Ctrl-C / SIGTERM (`interrupted`).
fn ended(
    map: Option<&LiveMap>,
    result: anyhow::Result<()>,
    interrupted: impl FnOnce() -> anyhow::Result<bool>,
) -> anyhow::Result<()> {
    if let Some(map) = map {
        map.end();
    }
    result?;
    if interrupted()? {
        return Err(Interrupted.into());
    }
    Ok(())
}

/// `aim track --serial A --serial B ...`: every board's link read at once, the frames through
/// the intake in the order they arrive ([`aim_tracker::link::Ports`]).
fn track_ports(
    args: &Args,
    session: &mut aim_tracker::session::Session,
    mavlink: Option<&aim_tracker::output::mavlink::MavlinkOut>,
    map: Option<LiveMap>,
) -> anyhow::Result<()> {
    let ports = &args.link.serial;
    if let Some(p) = ports.iter().enumerate().find_map(|(i, p)| ports[..i].contains(p).then_some(p))
    {
        anyhow::bail!("--serial {p} is given twice");
    }
    let mut links: Vec<(String, Box<dyn std::io::Read + Send>)> = Vec::new();
    for p in ports {
        let link = args.link.reconnect.open(p, args.link.baud)?;
        links.push((p.clone(), Box::new(link)));
    }
    let feed = aim_tracker::link::Ports::spawn(links)
        .map_err(|e| anyhow::anyhow!("starting the port readers: {e}"))?;
    let mut source = FrameSource::new(Tap::new(feed, map.clone(), Pace::Free));
    // Scripts and tests wait for this line before they send: every port is configured now.
    eprintln!("tracking {} at {} baud", ports.join(", "), args.link.baud);
    let name = ports.join(" + ");
    let site = &args.options.site;
    let result = track_frames(&name, &mut source, session, site, true, mavlink, &mut |fix| {
        super::serve::show(&map, fix)
    });
    ended(map.as_ref(), result, || {
        Ok(aim_tracker::link::serial::interrupt_flag()?.load(std::sync::atomic::Ordering::SeqCst))
    })
}

/// `aim track --zenoh`: the frames of every array on the bus through the same intake; each fix
/// printed and published on `aim/track/<name>/fix`. Ends on Ctrl-C / SIGTERM (status 130)
/// with the last fixes and the statistics line.
#[cfg(feature = "zenoh")]
fn track_zenoh(
    args: &Args,
    session: &mut aim_tracker::session::Session,
    mavlink: Option<&aim_tracker::output::mavlink::MavlinkOut>,
    map: Option<LiveMap>,
) -> anyhow::Result<()> {
    use aim_tracker::link::bus::{fix_key, FrameFeed, LinePublisher, FRAMES_ALL};
    use zenoh::Wait as _;
    let name = match &args.name {
        Some(name) => name.clone(),
        None => args.options.site.file_stem().unwrap_or_default().to_string_lossy().into_owned(),
    };
    let bus = args.link.bus.open()?;
    let fixes = LinePublisher::new(&bus, fix_key(&name)?)?;
    let feed = FrameFeed::subscribe(&bus)?.stop_on(aim_tracker::link::serial::interrupt_flag()?);
    let mut source = FrameSource::new(Tap::new(feed, map.clone(), Pace::Free));
    // Scripts and tests wait for this line before they publish: the subscription is declared.
    eprintln!("tracking {FRAMES_ALL} on the Zenoh bus, fixes on {}", fixes.key());
    let site = &args.options.site;
    let result = track_frames(FRAMES_ALL, &mut source, session, site, true, mavlink, &mut |fix| {
        fixes.put(&fix.to_json())?;
        super::serve::show(&map, fix)
    });
    // Closing sends the last fixes still queued before the process ends.
    let _ = bus.close().wait();
    ended(map.as_ref(), result, || Ok(source.get_mut().get_mut().interrupted()))
}

/// `aim track --zenoh` in an `aim` built without the bus.
#[cfg(not(feature = "zenoh"))]
fn track_zenoh(
    _args: &Args,
    _session: &mut aim_tracker::session::Session,
    _mavlink: Option<&aim_tracker::output::mavlink::MavlinkOut>,
    _map: Option<LiveMap>,
) -> anyhow::Result<()> {
    Err(super::bus::unavailable())
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
