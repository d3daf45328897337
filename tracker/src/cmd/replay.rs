//! `aim replay FRAMES [FRAMES...] --site SITE.toml`: track from a recording of frames (or `-`
//! for stdin; several recordings, one per board, are read as one link by
//! [`aim_tracker::link::Merged`]) and print one JSON fix per output period:
//! `{"t":..,"available":..,"x":..,"y":..,"z":..,"sigma":[..],"motion":"hover|yaw|horizontal|vertical","los":true|false,"heard":true|false,"drone":..}`
//! (`t`: the instant it describes; `available`: when the array had sent what it used, s;
//! `drone`: the classifier's verdict, whether a drone is there from the array's last three
//! disjoint windows of 6 `Mfcc` frames (`aim_tracker::id::chip::DECISION_WINDOWS`), which one
//! from up to six (`aim_tracker::id::chip::TYPE_WINDOWS`, since the drone was last gone),
//! `{"class":..,"p":..}`, `"none"`, or `null` before the first full window), then
//! one statistics line (`{"kind":"stats",...}`: link, intake and latency counts) on stderr.

use std::io::Write as _;
use std::path::PathBuf;

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::link::{self, FrameSource};
use aim_tracker::output::mavlink::MavlinkOut;
use aim_tracker::output::ned::Origin;
use aim_tracker::profile::Profile;
use aim_tracker::serve::tap::Tap;
use aim_tracker::session::{Identifier, Session};
use aim_tracker::site::Site;
use aim_tracker::tracker::{Tracker, TrackerConfig};
use anyhow::Context as _;

/// Options shared by `aim replay` and `aim track`.
#[derive(clap::Args)]
pub struct TrackOptions {
    /// Site file: the arrays' ids, positions and orientation (TOML).
    #[arg(long)]
    pub site: PathBuf,
    /// Drone profile: a TOML file or a bundled profile's name (`dji-mini-2`, `fpv-5in`,
    /// `camera-quad-1kg`, `hexacopter`, `toy-70g`, `consumer-400g`); default: the bundled DJI
    /// Mini 2, replaced by the profile of the type the drone classifier recognises (see
    /// `--id-profiles`). Given, it stays.
    #[arg(long)]
    pub profile: Option<PathBuf>,
    /// Drone classifier (`aim id train --features chip`) for the `drone` field of every fix,
    /// read from the tracked array's `Mfcc` frames; default: the bundled model trained on
    /// simulated drones (host-sim's six types and negatives).
    #[arg(long, value_name = "FILE")]
    pub id_model: Option<PathBuf>,
    /// No drone classifier: fixes without a `drone` field, the profile never changes.
    #[arg(long, conflicts_with = "id_model")]
    pub no_id: bool,
    /// Folder of profiles named after the classifier's classes (`<class>.toml`), which the
    /// tracker takes when it recognises a class (without `--profile`); a class with no file
    /// there takes its bundled profile.
    #[arg(long, value_name = "DIR")]
    pub id_profiles: Option<PathBuf>,
    /// Filter: `aim` (position–velocity EKF mixture), `paper` (the paper's baseline) or
    /// `triangulate` (several arrays: their DoA rays intersected, the paper's distributed
    /// baseline).
    #[arg(long, default_value = "aim")]
    pub filter: FilterKind,
    /// Array to track with (default: the site's first).
    #[arg(long)]
    pub array: Option<u16>,
    /// Only the tracked array's frames make the track (default: every array of the site
    /// that sends frames adds its bearings; one array's own dynamics still drive it).
    #[arg(long)]
    pub no_fuse: bool,
    /// Output period, s.
    #[arg(long, default_value_t = 0.1)]
    pub period: f64,
    #[command(flatten)]
    pub mavlink: MavlinkArgs,
    #[command(flatten)]
    pub serve: super::serve::ServeArgs,
}

/// The MAVLink output of `aim track`/`aim replay` (see `aim_tracker::output::mavlink`).
#[derive(clap::Args)]
pub struct MavlinkArgs {
    /// Also send each fix to an autopilot as MAVLink 2 VISION_POSITION_ESTIMATE (with
    /// HEARTBEAT at 1 Hz), in the local NED frame of the site file's `[origin]`:
    /// `udpout:HOST:PORT` or `serial:PORT:BAUD`.
    #[arg(long, value_name = "ADDRESS")]
    pub mavlink: Option<String>,
    /// MAVLink system id of the messages (the vehicle's; 1–255, 0 is MAVLink's broadcast).
    #[arg(long, default_value_t = aim_tracker::output::mavlink::DEFAULT_SYSTEM_ID,
          value_parser = clap::value_parser!(u8).range(1..))]
    pub mavlink_system_id: u8,
    /// Send fixes no rotor signature supports too (`"heard":false`: no `Peaks` frame with one
    /// in the last 5 s); by default they are withheld and counted, as their bearings may be
    /// of a machine or a fan.
    #[arg(long)]
    pub mavlink_send_unheard: bool,
}

impl MavlinkArgs {
    /// The MAVLink output, if `--mavlink` was given (the site file must have `[origin]`).
    pub fn open(&self, site: &std::path::Path) -> anyhow::Result<Option<MavlinkOut>> {
        let Some(address) = &self.mavlink else { return Ok(None) };
        let origin = Origin::load(site).context("--mavlink")?;
        Ok(Some(
            MavlinkOut::open(address, origin, self.mavlink_system_id)?
                .send_unheard(self.mavlink_send_unheard),
        ))
    }
}

impl TrackOptions {
    /// The session (intake and tracker) these options describe.
    pub fn build(&self) -> anyhow::Result<Session> {
        let site = Site::load(&self.site)?;
        let sync = aim_tracker::site::SiteSync::load(&self.site)?;
        let profile = match &self.profile {
            Some(p) => Profile::from_arg(p)?,
            None => Profile::dji_mini_2(),
        };
        let period = aim_tracker::config::check_flag(
            self.period,
            "--period",
            aim_tracker::config::PERIOD_RANGE_S,
            "s",
        )?;
        let config = TrackerConfig {
            output_period_s: period,
            array_id: self.array,
            fuse_arrays: !self.no_fuse,
            ..TrackerConfig::default()
        };
        let tracker = Tracker::new(site.clone(), profile, self.filter, config)
            .with_context(|| format!("site {}", self.site.display()))?
            .with_sync(&sync);
        let session = Session::new(tracker, site, IntakeConfig::default());
        if self.no_id {
            return Ok(session);
        }
        let model = match &self.id_model {
            Some(p) => aim_tracker::id::model::Model::load(p)?,
            None => aim_tracker::id::default_model(),
        };
        let profiles = if self.profile.is_some() {
            Vec::new()
        } else {
            aim_tracker::id::class_profiles(self.id_profiles.as_deref(), &model.classes)?
        };
        let identifier = Identifier::new(model, profiles).with_context(|| {
            format!(
                "--id-model {}",
                self.id_model.as_deref().map_or("(bundled)".into(), |p| p.display().to_string())
            )
        })?;
        Ok(session.with_identifier(identifier))
    }
}

/// Arguments of `aim replay`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording of frames (`aim record`, or any raw capture of the link); `-` for stdin.
    /// Several recordings (one per array, each its board's link) are read as one link, the
    /// arrays' frames interleaved by the end of their audio, as a host with one port per array
    /// receives them; the boards' clocks are taken to have started together.
    #[arg(required = true, num_args = 1..)]
    frames: Vec<String>,
    #[command(flatten)]
    options: TrackOptions,
    /// Replay pace: `free` (as fast as possible), `real` (the link's pace) or a speed-up such
    /// as `4`; with `--serve` the map then updates as it would live.
    #[arg(long, default_value = "free", value_name = "real|N|free")]
    pace: aim_tracker::serve::tap::Pace,
}

/// Feeds every frame of `source` through the session, printing fixes as JSON lines as soon as
/// they are available (`live`: flushed one by one) and sending them to `mavlink` if given,
/// then the statistics line on stderr (and `{"kind":"mavlink","sent":..,"withheld":..,"failed":..}`). Every
/// fix also goes to `also` after it is printed (the live map, the bus).
pub fn track_frames<R: std::io::Read>(
    name: &str,
    source: &mut FrameSource<R>,
    session: &mut Session,
    site: &std::path::Path,
    live: bool,
    mavlink: Option<&MavlinkOut>,
    also: &mut dyn FnMut(&aim_tracker::tracker::Fix) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let result = session.track_reader(source, &mut |fix| {
        writeln!(out, "{}", fix.to_json()).context("writing to stdout")?;
        if let Some(m) = mavlink {
            m.send(fix);
        }
        if live {
            out.flush().context("writing to stdout")?;
        }
        also(fix)
    });
    out.flush().context("writing to stdout")?;
    eprintln!("{}", session.stats_json(source.stats()));
    if live && source.stats().frames == 0 {
        eprintln!("warning: {name}: no frame decoded (is it an AIM link?)");
    }
    let inputs = session.intake_stats().inputs;
    if inputs > 0 && session.fix_stats().fixes == 0 {
        eprintln!(
            "warning: {name}: {inputs} inputs and no fix: the audio ended before the first \
             output instant (--period longer than the recording?) or held no bearing"
        );
    }
    if let Some(m) = mavlink {
        let (sent, withheld, failed) = m.counts();
        eprintln!(
            "{{\"kind\":\"mavlink\",\"sent\":{sent},\"withheld\":{withheld},\"failed\":{failed}}}"
        );
    }
    result.with_context(|| format!("{name} (site {})", site.display()))
}

/// Runs `aim replay`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut session = args.options.build()?;
    let mavlink = args.options.mavlink.open(&args.options.site)?;
    let map = args.options.serve.start(&args.options.site)?;
    let input: Box<dyn std::io::Read + Send> = match args.frames.as_slice() {
        [one] => link::open_input(one)?,
        many => Box::new(link::Merged::open(many, &Site::load(&args.options.site)?)?),
    };
    let mut source = FrameSource::new(Tap::new(input, map.clone(), args.pace));
    let result = track_frames(
        &args.frames.join(" + "),
        &mut source,
        &mut session,
        &args.options.site,
        false,
        mavlink.as_ref(),
        &mut |fix| super::serve::show(&map, fix),
    );
    // Bytes that held no frame at all are not a recording (an empty one is: nothing was sent).
    let stats = source.stats();
    let name = args.frames.join(" + ");
    let result = match result {
        Ok(()) if stats.frames == 0 && stats.bytes > 0 => Err(anyhow::anyhow!(
            "{name}: {} bytes and no AIM frame in them (not a recording of the link?)",
            stats.bytes
        )),
        Ok(()) if stats.frames == 0 => {
            eprintln!("warning: {name}: empty, no frame to track");
            Ok(())
        }
        other => other,
    };
    if let Some(map) = map {
        map.end();
        if result.is_ok() {
            super::serve::serve_until_interrupted(&map)?;
        }
    }
    result
}
