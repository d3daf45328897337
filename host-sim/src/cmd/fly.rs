//! `host-sim fly SCENARIO.toml [--filter paper|aim|triangulate|both] [--out DIR]`: simulate,
//! run every array's recording (block by block as it is rendered, never held whole; memory refused up
//! front past `--max-memory-mb` as `host-sim simulate` does) through the on-chip pipeline and the wire format into the bytes a board
//! would send, then track from those bytes exactly as `aim replay DIR/frames-<id>.aimraw --site
//! DIR/site.toml` does (the same [`aim_tracker::session::Session`], the frames in link order,
//! nothing but the bytes and the site file), and compare with the truth.
//!
//! Prints the error summary (mean, median, p90, availability, motion-class accuracy, the share
//! of fixes inside their own 95 % ellipsoid, latency)
//! and the intake's statistics line, and writes
//! `DIR/track.csv` (`t,x,y,z,vx,vy,vz,sigma_x,sigma_y,sigma_z,motion,los,truth_x,truth_y,truth_z,error,cov_xy,cov_xz,cov_yz`;
//! the `cov_*` are the position covariance's off-diagonal terms, m²),
//! `DIR/fixes.jsonl` (what `aim replay` prints for the same frames), `DIR/track.png` (track
//! against truth), `DIR/site.toml`, `DIR/frames-<id>.aimraw` and `DIR/truth.csv`. With
//! `--filter both` the tracks go to `DIR/paper/` and `DIR/aim/` from one simulation.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use aim_tracker::filter::FilterKind;
use aim_tracker::intake::IntakeConfig;
use aim_tracker::link::FrameSource;
use aim_tracker::profile::Profile;
use aim_tracker::session::Session;
use aim_tracker::tracker::{Fix, Tracker, TrackerConfig};
use host_sim::eval::{link, metrics, plot};
use host_sim::scenario::Scenario;

/// Arguments of `host-sim fly`.
#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML), e.g. `host-sim/scenarios/square10-los.toml`.
    scenario: PathBuf,
    /// Filter: `aim`, `paper`, `triangulate` (several arrays: DoA rays intersected), or `both`
    /// (`paper` and `aim`: one simulation, two tracks).
    #[arg(long, default_value = "aim")]
    filter: String,
    /// Output directory (default: `fly-<scenario name>`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Drone profile for the tracker: a TOML file (see `tracker/profiles/`) or a bundled
    /// profile's name; default: the bundled DJI Mini 2 profile, replaced by the profile of
    /// the type the drone classifier recognises (as `aim replay` does).
    #[arg(long)]
    profile: Option<PathBuf>,
    /// Output period of the tracker, s.
    #[arg(long, default_value_t = 0.1)]
    period: f64,
    /// Worker threads of the simulation (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Refuse scenarios whose simulation needs more memory than this, MB (1 MB = 10⁶ bytes).
    #[arg(long, default_value_t = 4000)]
    max_memory_mb: u64,
    /// Track from the first array's recording alone, as `aim replay frames-<id>.aimraw
    /// --no-fuse` (default with several arrays: every array's recording, merged as one
    /// host receives them, each array's bearings in the filter).
    #[arg(long)]
    no_fuse: bool,
    /// First fly the site's zenith calibration survey (`host_sim::survey`: spokes out from
    /// each array and back, at 1 and 2.5 m, in this room, by the installer's nominal Mini 2)
    /// with this seed (not the flight's), fit each array's `zenith_correction_deg` from its
    /// frames against the installer's reference (the truth with 2 cm of noise and a clock up
    /// to 50 ms off) as `aim calibrate` does, and track with it. The survey's files go to
    /// `OUT/zenith-survey/`.
    #[arg(long, value_name = "SEED")]
    zenith_survey: Option<u64>,
}

/// How the recordings of a run are tracked (shared by `fly` and `bench`).
pub(crate) struct Tracking<'a> {
    /// Tracker profile.
    pub profile: &'a Profile,
    /// Filters, one track each.
    pub kinds: &'a [FilterKind],
    /// Output period, s.
    pub period: f64,
    /// The profile follows the type the bundled classifier recognises.
    pub choose_profile: bool,
    /// Every array's recording, merged ([`aim_tracker::link::Merged`]), and their bearings
    /// fused ([`TrackerConfig::fuse_arrays`]); false: the tracked array's recording alone.
    pub fuse_arrays: bool,
    /// The site's calibration of each array's zenith (a survey's, [`host_sim::survey`]),
    /// written into the site file the tracker reads; empty: the site file's own.
    pub zenith: &'a [(u16, aim_tracker::zenith::ZenithCorrection)],
    /// Take every zenith correction out of the site file first (a re-score without the
    /// calibration of runs that were tracked with one).
    pub strip_zenith: bool,
}

/// What one tracker run gave.
pub(crate) struct TrackRun {
    /// The filter.
    pub kind: FilterKind,
    /// Its errors against the truth.
    pub summary: metrics::Summary,
    /// Its fixes' latency.
    pub latency: aim_tracker::session::FixStats,
    /// With a beacon: the clock model's sync error [`SYNC_AFTER_S`] after its first beacon.
    pub sync: Option<host_sim::eval::sync::SyncError>,
}

/// When the clock sync error is read: this long after the first beacon arrival, s (issue 14:
/// "clock sync error ≤ 20 µs 10 s after start").
pub(crate) const SYNC_AFTER_S: f64 = 10.0;

/// Runs `host-sim fly`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let kinds: Vec<FilterKind> = match args.filter.as_str() {
        "both" => vec![FilterKind::Paper, FilterKind::Aim],
        other => vec![other.parse().map_err(anyhow::Error::msg).context("--filter")?],
    };
    aim_tracker::config::check_flag(
        args.period,
        "--period",
        aim_tracker::config::PERIOD_RANGE_S,
        "s",
    )?;
    let scenario = Scenario::load(&args.scenario)?;
    crate::cmd::simulate::check_memory(&scenario, args.max_memory_mb)?;
    // Checked before minutes of simulation, not after.
    for &kind in &kinds {
        aim_tracker::tracker::check_filter_arrays(kind, scenario.arrays.len(), !args.no_fuse)
            .with_context(|| format!("{}: --filter", args.scenario.display()))?;
    }
    if let Some(seed) = args.zenith_survey.filter(|&s| s == scenario.seed) {
        anyhow::bail!(
            "--zenith-survey {seed} is the flight's own seed ({}): a survey needs a seed of its \
             own, or its noise would repeat the flight's",
            args.scenario.display()
        );
    }
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("fly-{}", scenario.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let profile = match &args.profile {
        Some(p) => Profile::from_arg(p)?,
        None => Profile::dji_mini_2(),
    };

    let zenith = match args.zenith_survey {
        Some(seed) => {
            let progress = host_sim::progress_bar("zenith survey");
            let survey = host_sim::survey::calibrate(&scenario, seed, args.threads)
                .with_context(|| format!("{}: the zenith survey", args.scenario.display()))?;
            progress.finish_and_clear();
            let dir = out.join("zenith-survey");
            survey.store(&dir)?;
            for f in &survey.fits {
                eprintln!(
                    "zenith survey: array {}: {} frames, {} points ({})",
                    f.array_id,
                    f.frames,
                    f.correction.to_degrees().len(),
                    dir.display()
                );
            }
            survey.corrections()
        }
        None => Vec::new(),
    };

    // The audio goes through every array's pipeline as it is rendered (never held whole).
    let progress = host_sim::progress_bar("simulating");
    let (sim, links) = link::simulate_links(
        &scenario,
        &host_sim::Options { threads: args.threads },
        &progress,
        host_sim::DEFAULT_FULL_SCALE_PA,
    )
    .with_context(|| format!("simulating {}", args.scenario.display()))?;
    progress.finish_and_clear();
    let tracking = Tracking {
        profile: &profile,
        kinds: &kinds,
        period: args.period,
        choose_profile: args.profile.is_none(),
        fuse_arrays: !args.no_fuse,
        zenith: &zenith,
        strip_zenith: false,
    };
    let runs = track(&sim, &links, &out, &tracking)?;
    for r in &runs {
        if let Some(line) = no_fix_line(&scenario.name, r) {
            println!("{line}");
            continue;
        }
        let s = &r.summary;
        println!(
            "{} {}: mean {:.2} m, median {:.2} m, p90 {:.2} m, live mean {:.2} m, availability {:.1} % ({}/{}, {:.1} % within {} m), motion class {:.1} %{}, in its 95 % ellipsoid {:.1} %, latency mean {:.2} s, max {:.2} s",
            scenario.name,
            filter_name(r.kind),
            s.mean_m,
            s.median_m,
            s.p90_m,
            s.live_mean_m,
            100.0 * s.availability,
            s.fixes,
            s.due,
            100.0 * s.good_availability,
            host_sim::eval::metrics::GOOD_FIX_M,
            100.0 * s.motion_accuracy,
            s.los_accuracy.map_or(String::new(), |a| format!(", LoS flag {:.1} %", 100.0 * a)),
            100.0 * s.coverage_95,
            r.latency.mean_latency_s,
            r.latency.max_latency_s,
        );
    }
    Ok(())
}

/// Everything `host-sim fly` does after simulating, shared with `host-sim bench`: writes the
/// site and truth files and every array's frame bytes (`links`, in the simulation's array
/// order, from [`link::simulate_links`]) into `out`, runs them through the tracker with each
/// filter of `how.kinds` (fixes every `how.period` s) and compares with the truth.
pub(crate) fn track(
    sim: &host_sim::Simulation,
    links: &[Vec<u8>],
    out: &Path,
    how: &Tracking,
) -> anyhow::Result<Vec<TrackRun>> {
    // The tracker reads the site file the simulator writes, as `aim replay` would (with the
    // site's zenith calibration, when it has one).
    let site_path = out.join("site.toml");
    let site_text = calibrated(sim.site.to_toml()?, &site_path, how)?;
    std::fs::write(&site_path, &site_text)
        .with_context(|| format!("writing {}", site_path.display()))?;
    std::fs::write(out.join("truth.csv"), sim.truth.to_csv()).context("writing truth.csv")?;
    std::fs::write(out.join("truth.toml"), sim.truth.to_toml()).context("writing truth.toml")?;

    // Every array through the pipeline and the link, into the files a board's link would fill.
    let mut raw_paths = Vec::new();
    for (rec, bytes) in sim.arrays.iter().zip(links) {
        let raw_path = out.join(format!("frames-{}.aimraw", rec.id));
        std::fs::write(&raw_path, bytes)
            .with_context(|| format!("writing {}", raw_path.display()))?;
        raw_paths.push((u16::from(rec.id), raw_path));
    }
    let recorded =
        Recorded { site_text, site: sim.site.clone(), truth: sim.truth.clone(), raw_paths };
    track_recorded(&recorded, out, how)
}

/// The site file's text with `how.zenith`'s corrections (without any: its own, or none with
/// `how.strip_zenith`).
fn calibrated(text: String, path: &Path, how: &Tracking) -> anyhow::Result<String> {
    let text = if how.strip_zenith {
        aim_tracker::zenith::site_without_corrections(&text, path)?
    } else {
        text
    };
    if how.zenith.is_empty() {
        return Ok(text);
    }
    Ok(aim_tracker::zenith::site_with_corrections(&text, path, how.zenith)?)
}

/// A run as `fly` leaves it on disk: the site file's text and content, the truth, and each
/// array's link recording.
pub(crate) struct Recorded {
    /// `site.toml` as written (what the tracker reads).
    pub site_text: String,
    /// The same site, for the plot.
    pub site: host_sim::site::Site,
    /// The truth (scoring only; the tracker never sees it).
    pub truth: host_sim::truth::Truth,
    /// `(array id, frames-<id>.aimraw)` per array.
    pub raw_paths: Vec<(u16, PathBuf)>,
}

impl Recorded {
    /// Reads a run directory `fly` (or `bench`) wrote: `site.toml`, `truth.csv`, `truth.toml`
    /// and every `frames-<id>.aimraw`.
    pub(crate) fn load(dir: &Path) -> anyhow::Result<Self> {
        let read = |name: &str| {
            let p = dir.join(name);
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))
        };
        let site_text = read("site.toml")?;
        let site = host_sim::site::Site::parse(&site_text, &dir.join("site.toml"))?;
        let truth = host_sim::truth::Truth::parse(
            &read("truth.csv")?,
            &dir.join("truth.csv").display().to_string(),
            &read("truth.toml")?,
            &dir.join("truth.toml").display().to_string(),
        )?;
        let mut raw_paths = Vec::new();
        for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
            let path = entry?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            if let Some(id) = name.strip_prefix("frames-").and_then(|n| n.strip_suffix(".aimraw")) {
                let id =
                    id.parse::<u16>().with_context(|| format!("{}: array id", path.display()))?;
                raw_paths.push((id, path));
            }
        }
        raw_paths.sort();
        if raw_paths.is_empty() {
            anyhow::bail!("{}: no frames-<id>.aimraw recording", dir.display());
        }
        Ok(Self { site_text, site, truth, raw_paths })
    }
}

/// Tracks a recorded run with each filter of `how.kinds`, exactly as `aim replay` reads it
/// (the site file's text, the link's bytes in link order; with `how.fuse_arrays` and several
/// arrays, every array's recording merged as `aim replay frames-1.aimraw frames-2.aimraw ...`
/// does), scores the fixes against the truth and writes each filter's `track.csv`,
/// `fixes.jsonl` and plot under `out`. With `how.choose_profile` the profile follows the drone
/// type the bundled classifier recognises.
pub(crate) fn track_recorded(
    rec: &Recorded,
    out: &Path,
    how: &Tracking,
) -> anyhow::Result<Vec<TrackRun>> {
    let (profile, period) = (how.profile, how.period);
    let site_path = out.join("site.toml");
    let site_text = calibrated(rec.site_text.clone(), &site_path, how)?;
    if !how.zenith.is_empty() || how.strip_zenith {
        std::fs::write(&site_path, &site_text)
            .with_context(|| format!("writing {}", site_path.display()))?;
    }
    let site = aim_tracker::site::Site::parse(&site_text, &site_path)?;
    let sync = aim_tracker::site::SiteSync::parse(&site_text, &site_path)?;
    // The drone classifier `aim replay` runs by default (the bundled model); the profile
    // follows the recognised type only when none was given, as there. Read once for every
    // filter.
    let model = aim_tracker::id::default_model();
    let profiles = if how.choose_profile {
        aim_tracker::id::class_profiles(None, &model.classes)?
    } else {
        Vec::new()
    };
    let mut runs = Vec::new();
    for &kind in how.kinds {
        let config = TrackerConfig {
            output_period_s: period,
            fuse_arrays: how.fuse_arrays,
            ..TrackerConfig::default()
        };
        let tracker = Tracker::new(site.clone(), profile.clone(), kind, config)?
            .with_sync(&sync)
            .keep_clock_history();
        let tracked = tracker.array_id();
        let array_index =
            rec.truth.array_ids.iter().position(|&id| u16::from(id) == tracked).unwrap_or(0);
        // `aim replay frames-<id>.aimraw --site site.toml`: the bytes, in link order.
        let (_, raw_path) = rec
            .raw_paths
            .iter()
            .find(|(id, _)| *id == tracked)
            .with_context(|| format!("no recording of array {tracked}"))?;
        let (name, input): (String, Box<dyn std::io::Read + Send>) =
            if how.fuse_arrays && rec.raw_paths.len() > 1 {
                let paths: Vec<String> =
                    rec.raw_paths.iter().map(|(_, p)| p.display().to_string()).collect();
                let name = format!("{} recordings in {}", rec.raw_paths.len(), out.display());
                (name, Box::new(aim_tracker::link::Merged::open(&paths, &site)?))
            } else {
                let name = raw_path.display().to_string();
                let input = aim_tracker::link::open_input(&name)?;
                (name, input)
            };
        let mut source = FrameSource::new(input);
        let identifier = aim_tracker::session::Identifier::new(model.clone(), profiles.clone())?;
        let mut session = Session::new(tracker, site.clone(), IntakeConfig::default())
            .with_identifier(identifier);
        let mut fixes = Vec::new();
        session
            .track_reader(&mut source, &mut |f| {
                fixes.push(f.clone());
                Ok(())
            })
            .with_context(|| format!("tracking {name}"))?;
        eprintln!("{}: {}", filter_name(kind), session.stats_json(source.stats()));
        let Some((first, last)) = session.inputs_span() else {
            anyhow::bail!("the pipeline produced no observation");
        };
        let summary = metrics::evaluate(&fixes, &rec.truth, period, first, last, array_index);
        let latency = session.fix_stats();
        let dir = if how.kinds.len() > 1 { out.join(filter_name(kind)) } else { out.to_path_buf() };
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        write_track(&dir.join("track.csv"), &fixes, &rec.truth)?;
        let jsonl: String = fixes.iter().map(|f| f.to_json() + "\n").collect();
        std::fs::write(dir.join("fixes.jsonl"), jsonl).context("writing fixes.jsonl")?;
        let tracker = session.tracker();
        plot::plot_track(&dir.join("track.png"), &fixes, &rec.truth, &rec.site)?;
        eprintln!(
            "{}: k_v calibrated to {:.4e} N/Hz² (profile `{}`: {:.4e})",
            filter_name(kind),
            tracker.k_v(),
            tracker.profile().name,
            tracker.profile().k_v
        );
        let fs = f64::from(site.sample_rate_hz.unwrap_or(48_000));
        let sync = host_sim::eval::sync::error_after(
            tracker.clock_history(),
            &rec.truth,
            fs,
            SYNC_AFTER_S,
        );
        if let Some(e) = &sync {
            eprintln!(
                "{}: clock sync {SYNC_AFTER_S} s after the first beacon: max {:.2} µs, rms {:.2} µs over {} of {} arrays",
                filter_name(kind),
                e.max_us,
                e.rms_us,
                e.synced,
                e.arrays
            );
        }
        runs.push(TrackRun { kind, summary, latency, sync });
    }
    Ok(runs)
}

/// What `fly` prints for a run without any fix to compare with the truth: there is no error
/// to state (issue 17: it printed "mean -0.00 m, median NaN m"), so it says so. None when
/// there were fixes.
pub(crate) fn no_fix_line(name: &str, r: &TrackRun) -> Option<String> {
    (r.summary.fixes == 0).then(|| {
        format!(
            "{name} {}: no fix to compare with the truth (0 of {} due)",
            filter_name(r.kind),
            r.summary.due
        )
    })
}

/// The filter's name on the command line and in output paths.
pub(crate) fn filter_name(kind: FilterKind) -> &'static str {
    match kind {
        FilterKind::Paper => "paper",
        FilterKind::Aim => "aim",
        FilterKind::Triangulate => "triangulate",
    }
}

/// Writes the track with the truth beside it.
fn write_track(path: &Path, fixes: &[Fix], truth: &host_sim::truth::Truth) -> anyhow::Result<()> {
    let mut s = String::from(
        "t,x,y,z,vx,vy,vz,sigma_x,sigma_y,sigma_z,motion,los,truth_x,truth_y,truth_z,error,cov_xy,cov_xz,cov_yz\n",
    );
    for f in fixes {
        let (tp, err) = match metrics::truth_at(truth, f.t) {
            Some((p, _, _)) => {
                let e = ((f.position[0] - p[0]).powi(2)
                    + (f.position[1] - p[1]).powi(2)
                    + (f.position[2] - p[2]).powi(2))
                .sqrt();
                (format!("{:.3},{:.3},{:.3}", p[0], p[1], p[2]), format!("{e:.3}"))
            }
            None => (",,".to_string(), String::new()),
        };
        let _ = writeln!(
            s,
            "{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{},{:.6},{:.6},{:.6}",
            f.t,
            f.position[0],
            f.position[1],
            f.position[2],
            f.velocity[0],
            f.velocity[1],
            f.velocity[2],
            f.sigma[0],
            f.sigma[1],
            f.sigma[2],
            f.motion.as_str(),
            f.los,
            tp,
            err,
            f.covariance[0][1],
            f.covariance[0][2],
            f.covariance[1][2],
        );
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_without_fixes_says_so_instead_of_nan() {
        let row = |k: usize| host_sim::truth::TruthRow {
            t_s: k as f64 * 0.01,
            position: [k as f64 * 0.01, 0.0, 2.0],
            velocity: [1.0, 0.0, 0.0],
            acceleration: [0.0; 3],
            yaw_rad: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            rotor_hz: vec![164.0; 4],
            los: vec![true],
        };
        let truth = host_sim::truth::Truth {
            blades: 2,
            array_ids: vec![1],
            clocks: Vec::new(),
            airframe: None,
            rows: (0..=1200).map(row).collect(),
        };
        // The inputs spanned 0–12 s but the tracker gave no fix: the median is undefined.
        let summary = metrics::evaluate(&[], &truth, 0.1, 0.0, 12.0, 0);
        assert!(summary.median_m.is_nan() && summary.due > 100);
        let run =
            TrackRun { kind: FilterKind::Aim, summary, latency: Default::default(), sync: None };
        let line = no_fix_line("s", &run).expect("no fixes");
        assert_eq!(
            line,
            format!("s aim: no fix to compare with the truth (0 of {} due)", run.summary.due)
        );
    }
}
