//! `host-sim bench SUITE.toml --out DIR [--seeds evaluation|tuning] [--family NAME]...
//! [--threads N]`: runs a declared suite, scenario families × seeds, each run through the same
//! simulation and tracking `host-sim fly` does (its [`crate::cmd::fly::track`]), both filters,
//! on all cores, and writes per family the mean ± sd over seeds of the mean, median and p90
//! error, availability and motion-class accuracy.
//!
//! Suite file (TOML; paths relative to it):
//!
//! ```toml
//! description = "..."
//! tuning_seeds = [101, 102]          # seeds filters may be tuned on (never reported)
//! evaluation_seeds = [1001, 1002]    # held-out seeds the tables report; disjoint from tuning
//! filters = ["paper", "aim"]         # [both]
//! period_s = 0.1                     # [0.1] tracker output period
//! profile = "../../tracker/profiles/dji-mini-2.toml"   # [none: the bundled DJI Mini 2, then
//!                                    #  the profile of the type the classifier recognises]
//! fuse_arrays = true                 # [true] with several arrays, all tracked together;
//!                                    #  false: the first array's recording alone
//! zenith_survey_seed = 7             # [none] calibrate each family's arrays' zenith first:
//!                                    #  its room's survey flight (host_sim::survey) with this
//!                                    #  seed, fitted as `aim calibrate` does, into every run's
//!                                    #  site file (stored under DIR/zenith-survey/<family>/)
//! [airframe]                         # the population every run draws its airframe from
//! wake_spread = 0.3                  # (keys of a scenario's [airframe]; merged over each file's)
//!
//! [[family]]
//! name = "square10-los"
//! scenario = "../scenarios/square10-los.toml"
//! # [family.airframe] overrides the suite's population for this family only
//! # profile = "fpv-5in"              # this family's tracker profile (a file or a bundled name)
//! # [family.drone] preset = "fpv-5in" # keys merged over the scenario's [drone] table
//! ```
//!
//! Each seed replaces the scenario's `seed`, so it draws the noise, the microphones' mismatch,
//! the airframe and (for a random walk) the course. Writes `DIR/runs.csv` (one row per family,
//! seed and filter; the last four columns each true motion class's recall), `DIR/summary.csv`
//! and `DIR/summary.md` (per family and filter, mean ± sd over seeds, then the motion class
//! by the truth's class pooled over seeds), and each run's `fly` output under
//! `DIR/runs/<family>/seed-<n>/`.
//!
//! `--rescore FROM` skips the simulation: it tracks the frames an earlier bench of the same
//! suite stored under `FROM/runs/<family>/seed-<n>/` (their bytes in link order, with the site
//! file's text, as `aim replay` would) and scores them against the truth read back from
//! `truth.csv` and `truth.toml` at their printed precision. For work on the tracker: the same
//! frames, re-scored in seconds instead of minutes. `DIR` may be `FROM`.
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{anyhow, bail, Context as _};
use serde::Deserialize;

use aim_tracker::filter::FilterKind;
use aim_tracker::profile::Profile;
use aim_tracker::zenith::ZenithCorrection;
use host_sim::eval::metrics::{class_index, recall, Summary, CLASSES};
use host_sim::scenario::Scenario;

use super::fly::{filter_name, track, track_recorded, Recorded, Tracking};

/// Arguments of `host-sim bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Suite file (TOML), e.g. `host-sim/suites/default.toml`.
    suite: PathBuf,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Which of the suite's seeds to run: `evaluation` (reported) or `tuning`.
    #[arg(long, default_value = "evaluation")]
    seeds: String,
    /// Run only these families (repeatable; default: all).
    #[arg(long = "family")]
    families: Vec<String>,
    /// Runs at once (0: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Do not simulate: track the frames an earlier `bench` of this suite stored in this
    /// directory (`FROM/runs/<family>/seed-<n>/`) and score them again.
    #[arg(long, value_name = "FROM")]
    rescore: Option<PathBuf>,
    /// Track without the suite's zenith calibration (`zenith_survey_seed`), for comparison:
    /// with `--rescore`, also without the one the stored runs' site files carry.
    #[arg(long)]
    no_zenith_survey: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SuiteFile {
    #[serde(default)]
    description: String,
    tuning_seeds: Vec<u64>,
    evaluation_seeds: Vec<u64>,
    filters: Option<Vec<String>>,
    period_s: Option<f64>,
    profile: Option<PathBuf>,
    fuse_arrays: Option<bool>,
    zenith_survey_seed: Option<u64>,
    #[serde(default)]
    airframe: toml::Table,
    family: Vec<FamilyFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FamilyFile {
    name: String,
    scenario: PathBuf,
    #[serde(default)]
    airframe: toml::Table,
    #[serde(default)]
    drone: toml::Table,
    profile: Option<PathBuf>,
}

/// One scenario family of a suite.
#[derive(Clone, Debug, PartialEq)]
pub struct Family {
    /// Name in the tables.
    pub name: String,
    /// Scenario file.
    pub scenario: PathBuf,
    /// Overrides merged over the scenario (its `[airframe]` population, its `[drone]`).
    pub overrides: toml::Table,
    /// Tracker profile for this family (a file or a bundled name), over the suite's.
    pub profile: Option<PathBuf>,
}

/// A checked suite.
#[derive(Clone, Debug, PartialEq)]
pub struct Suite {
    /// Free text.
    pub description: String,
    /// Seeds the filters may be tuned on.
    pub tuning_seeds: Vec<u64>,
    /// Held-out seeds the tables report.
    pub evaluation_seeds: Vec<u64>,
    /// Filters to run.
    pub filters: Vec<FilterKind>,
    /// Tracker output period, s.
    pub period_s: f64,
    /// Tracker profile, a file or a bundled name (None: the bundled DJI Mini 2 profile, then
    /// the one of the type the classifier recognises).
    pub profile: Option<PathBuf>,
    /// With several arrays, every array's recording is tracked, their bearings fused
    /// (default); false: the first array's alone.
    pub fuse_arrays: bool,
    /// Seed of each family's zenith survey (`host_sim::survey`), whose fitted corrections go
    /// into every run's site file; None: no zenith calibration.
    pub zenith_survey_seed: Option<u64>,
    /// The families.
    pub families: Vec<Family>,
}

impl Suite {
    /// Reads and checks a suite file: seeds present, unique, the two lists disjoint (the
    /// error names the shared seeds), families named once, their scenario files readable with
    /// every seed's overrides.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        Self::parse(&text, path)
    }

    /// [`Suite::load`] on text; `path` names the file in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> anyhow::Result<Self> {
        let f: SuiteFile =
            toml::from_str(text).map_err(|e| host_sim::scenario::toml_error(path, text, &e))?;
        // The message leads with its key (`filters`, `family[2].name`): its line is named.
        let err = |m: String| match host_sim::scenario::key_line(text, &m) {
            Some(line) => anyhow!("{}:{line}: {m}", path.display()),
            None => anyhow!("{}: {m}", path.display()),
        };
        for (name, list) in
            [("tuning_seeds", &f.tuning_seeds), ("evaluation_seeds", &f.evaluation_seeds)]
        {
            if list.is_empty() {
                return Err(err(format!("{name} is empty")));
            }
            let unique: BTreeSet<u64> = list.iter().copied().collect();
            if unique.len() != list.len() {
                return Err(err(format!("{name} lists a seed twice")));
            }
            if let Some(s) = list.iter().find(|&&s| s > i64::MAX as u64) {
                return Err(err(format!("{name}: seed {s} is above {}", i64::MAX)));
            }
        }
        let tuning: BTreeSet<u64> = f.tuning_seeds.iter().copied().collect();
        let shared: Vec<String> =
            f.evaluation_seeds.iter().filter(|s| tuning.contains(s)).map(u64::to_string).collect();
        if !shared.is_empty() {
            return Err(err(format!(
                "tuning_seeds and evaluation_seeds must be disjoint; both list {}",
                shared.join(", ")
            )));
        }
        if let Some(z) = f.zenith_survey_seed {
            if tuning.contains(&z) || f.evaluation_seeds.contains(&z) {
                return Err(err(format!(
                    "zenith_survey_seed {z} is also a flight's seed: the survey needs a seed of \
                     its own, or its noise and drone would repeat that flight's"
                )));
            }
        }
        let filters = match &f.filters {
            None => vec![FilterKind::Paper, FilterKind::Aim],
            Some(names) => names
                .iter()
                .map(|n| n.parse::<FilterKind>().map_err(|e| err(format!("filters: {e}"))))
                .collect::<anyhow::Result<Vec<_>>>()?,
        };
        if filters.is_empty() {
            return Err(err("filters is empty".into()));
        }
        if let Some(i) = (0..filters.len()).find(|&i| filters[..i].contains(&filters[i])) {
            let first = filters.iter().position(|x| *x == filters[i]).unwrap_or(0);
            let name = f.filters.as_ref().map_or("", |n| n[i].as_str());
            return Err(err(format!(
                "filters lists `{name}` twice (entries {} and {}): each run would be counted as \
                 two seeds",
                first + 1,
                i + 1
            )));
        }
        let period_s = f.period_s.unwrap_or(0.1);
        let range = aim_tracker::config::PERIOD_RANGE_S;
        if !(range.contains(&period_s) && period_s <= 10.0) {
            return Err(err(format!("period_s {period_s} must be {} to 10 s", range.start())));
        }
        if f.family.is_empty() {
            return Err(err("no [[family]]".into()));
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let profile = f.profile.map(|p| relative_or_name(dir, p));
        if let Some(p) = &profile {
            Profile::from_arg(p).map_err(|e| err(format!("profile: {e:#}")))?;
        }
        let mut families: Vec<Family> = Vec::new();
        for (k, fam) in f.family.into_iter().enumerate() {
            if let Some(first) = families.iter().position(|x| x.name == fam.name) {
                return Err(err(format!(
                    "family[{k}].name `{}` appears twice (also family {})",
                    fam.name,
                    first + 1
                )));
            }
            if !plain_name(&fam.name) {
                return Err(err(format!(
                    "family[{k}].name `{}` must be a plain word: letters, digits, `-`, `_`, `+` \
                     and `.` (not first); it names a folder and a column of the tables",
                    fam.name.escape_debug()
                )));
            }
            let mut airframe = f.airframe.clone();
            for (k, v) in fam.airframe {
                airframe.insert(k, v);
            }
            let mut overrides = toml::Table::new();
            if !airframe.is_empty() {
                overrides.insert("airframe".into(), toml::Value::Table(airframe));
            }
            if !fam.drone.is_empty() {
                overrides.insert("drone".into(), toml::Value::Table(fam.drone));
            }
            let fam_profile = fam.profile.map(|p| relative_or_name(dir, p));
            if let Some(p) = &fam_profile {
                Profile::from_arg(p).map_err(|e| {
                    err(format!("family[{k}].profile (family `{}`): {e:#}", fam.name))
                })?;
            }
            let scenario = dir.join(&fam.scenario);
            // Check it now (with one seed) rather than after an hour of other runs.
            Scenario::load_with(&scenario, f.evaluation_seeds[0], &overrides)
                .map_err(|e| err(format!("family[{k}].scenario (family `{}`): {e:#}", fam.name)))?;
            families.push(Family { name: fam.name, scenario, overrides, profile: fam_profile });
        }
        Ok(Self {
            description: f.description,
            tuning_seeds: f.tuning_seeds,
            evaluation_seeds: f.evaluation_seeds,
            filters,
            period_s,
            profile,
            fuse_arrays: f.fuse_arrays.unwrap_or(true),
            zenith_survey_seed: f.zenith_survey_seed,
            families,
        })
    }
}

/// Whether `name` can name a family: a folder of the runs and a cell of the CSV and markdown
/// tables (no separators, quotes or control characters).
fn plain_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && name.chars().all(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | '+' | '.'))
}

/// A profile path of a suite file: relative to the suite's folder when that names a file,
/// else as written (a bundled profile's name).
fn relative_or_name(dir: &Path, p: PathBuf) -> PathBuf {
    let joined = dir.join(&p);
    if joined.is_file() {
        joined
    } else {
        p
    }
}

/// One finished run: a family, a seed, a filter.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// Family name.
    pub family: String,
    /// Seed.
    pub seed: u64,
    /// Filter.
    pub filter: FilterKind,
    /// Its errors.
    pub summary: Summary,
    /// With a beacon: the largest clock sync error over the arrays 10 s after the first
    /// beacon, µs (`host-sim fly`'s `SYNC_AFTER_S`); NaN without.
    pub sync_max_us: f64,
}

/// Mean and sample standard deviation (0 for one value).
pub fn mean_sd(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    if x.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let mean = x.iter().sum::<f64>() / n;
    let var = if x.len() > 1 {
        x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// Per family and filter, over seeds: (family, filter, seeds, [mean, median, p90,
/// availability, motion class, live mean, good availability, clock sync max, 95 % coverage]
/// as (mean, sd); the sync over the runs that have one, NaN if none).
type Row = (String, FilterKind, usize, [(f64, f64); 9]);

fn aggregate(suite: &Suite, results: &[RunResult]) -> Vec<Row> {
    let mut rows = Vec::new();
    for fam in &suite.families {
        for &filter in &suite.filters {
            let of_family: Vec<&RunResult> =
                results.iter().filter(|r| r.family == fam.name && r.filter == filter).collect();
            let runs: Vec<&Summary> = of_family.iter().map(|r| &r.summary).collect();
            let syncs: Vec<f64> =
                of_family.iter().map(|r| r.sync_max_us).filter(|v| v.is_finite()).collect();
            if runs.is_empty() {
                continue;
            }
            let stat =
                |f: fn(&Summary) -> f64| mean_sd(&runs.iter().map(|s| f(s)).collect::<Vec<_>>());
            rows.push((
                fam.name.clone(),
                filter,
                runs.len(),
                [
                    stat(|s| s.mean_m),
                    stat(|s| s.median_m),
                    stat(|s| s.p90_m),
                    stat(|s| s.availability),
                    stat(|s| s.motion_accuracy),
                    stat(|s| s.live_mean_m),
                    stat(|s| s.good_availability),
                    mean_sd(&syncs),
                    stat(|s| s.coverage_95),
                ],
            ));
        }
    }
    rows
}

/// The CSV of one row per run.
pub fn runs_csv(results: &[RunResult]) -> String {
    let mut s = String::from(
        "family,seed,filter,mean_m,median_m,p90_m,availability,fixes,due,motion_accuracy,los_accuracy,live_mean_m,good_availability,sync_max_us,coverage_95,recall_hover,recall_yaw,recall_horizontal,recall_vertical\n",
    );
    for r in results {
        let m = &r.summary;
        let recalls: Vec<String> = CLASSES
            .iter()
            .map(|&c| m.class_recall(c).map_or(String::new(), |x| format!("{x:.4}")))
            .collect();
        let _ = writeln!(
            s,
            "{},{},{},{:.4},{:.4},{:.4},{:.4},{},{},{:.4},{},{:.4},{:.4},{},{:.4},{}",
            r.family,
            r.seed,
            filter_name(r.filter),
            m.mean_m,
            m.median_m,
            m.p90_m,
            m.availability,
            m.fixes,
            m.due,
            m.motion_accuracy,
            m.los_accuracy.map_or(String::new(), |a| format!("{a:.4}")),
            m.live_mean_m,
            m.good_availability,
            if r.sync_max_us.is_finite() { format!("{:.2}", r.sync_max_us) } else { String::new() },
            m.coverage_95,
            recalls.join(","),
        );
    }
    s
}

/// The markdown table of motion class by the truth's class: per family and filter, of the
/// fixes at instants of each true class (pooled over the seeds), the share that name it, and
/// how many fixes that is.
fn class_table(suite: &Suite, results: &[RunResult]) -> String {
    let mut md = String::from(
        "Motion class by the truth's class: of the fixes at instants the drone truly hovers, \
         yaws, moves horizontally or vertically (pooled over the seeds), the share whose class \
         is that one, and their number.\n\n\
         | family | filter | hover | yaw | horizontal | vertical |\n|---|---|---|---|---|---|\n",
    );
    for fam in &suite.families {
        for &filter in &suite.filters {
            let mut counts = [[0usize; 4]; 4];
            let mut any = false;
            for r in results.iter().filter(|r| r.family == fam.name && r.filter == filter) {
                any = true;
                for (row, add) in counts.iter_mut().zip(&r.summary.class_counts) {
                    for (c, a) in row.iter_mut().zip(add) {
                        *c += a;
                    }
                }
            }
            if !any {
                continue;
            }
            let cells: Vec<String> = CLASSES
                .iter()
                .map(|&c| {
                    let n: usize = counts[class_index(c)].iter().sum();
                    recall(&counts, c).map_or("—".into(), |x| format!("{:.1} % ({n})", 100.0 * x))
                })
                .collect();
            let _ =
                writeln!(md, "| {} | {} | {} |", fam.name, filter_name(filter), cells.join(" | "));
        }
    }
    md
}

/// The summary as CSV and as a markdown table.
fn summary_tables(suite: &Suite, results: &[RunResult], seeds_label: &str) -> (String, String) {
    let rows = aggregate(suite, results);
    let mut csv = String::from(
        "family,filter,seeds,mean_m,mean_m_sd,median_m,median_m_sd,p90_m,p90_m_sd,availability,availability_sd,motion_accuracy,motion_accuracy_sd,live_mean_m,live_mean_m_sd,good_availability,good_availability_sd,sync_max_us,sync_max_us_sd,coverage_95,coverage_95_sd\n",
    );
    let mut md = format!(
        "{} seeds; each cell: mean ± sd over seeds of the per-run figure. Errors are at the \
         instant a fix describes; *live* is against where the drone is when the fix becomes \
         available; *fixes ≤ {good} m* is the share of due output instants with a fix that close; \
         *clock sync* is the largest error of the beacon clock model over the arrays 10 s after \
         the first beacon (scenarios with a beacon); *in 95 % ellipsoid* is the share of fixes \
         whose error lies inside their own reported 95 % ellipsoid (95 % if the covariance is \
         honest).\n\n\
         | family | filter | seeds | mean error | median error | p90 error | live mean error | availability | fixes ≤ {good} m | motion class | clock sync | in 95 % ellipsoid |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        seeds_label,
        good = host_sim::eval::metrics::GOOD_FIX_M,
    );
    for (family, filter, n, st) in &rows {
        let _ = write!(csv, "{family},{},{n}", filter_name(*filter));
        for (m, sd) in st {
            let _ = write!(csv, ",{m:.4},{sd:.4}");
        }
        csv.push('\n');
        let _ = writeln!(
            md,
            "| {family} | {} | {n} | {:.2} ± {:.2} m | {:.2} ± {:.2} m | {:.2} ± {:.2} m | {:.2} ± {:.2} m | {:.1} ± {:.1} % | {:.1} ± {:.1} % | {:.1} ± {:.1} % | {} | {:.1} ± {:.1} % |",
            filter_name(*filter),
            st[0].0,
            st[0].1,
            st[1].0,
            st[1].1,
            st[2].0,
            st[2].1,
            st[5].0,
            st[5].1,
            100.0 * st[3].0,
            100.0 * st[3].1,
            100.0 * st[6].0,
            100.0 * st[6].1,
            100.0 * st[4].0,
            100.0 * st[4].1,
            if st[7].0.is_finite() {
                format!("{:.1} ± {:.1} µs", st[7].0, st[7].1)
            } else {
                "—".into()
            },
            100.0 * st[8].0,
            100.0 * st[8].1,
        );
    }
    md.push('\n');
    md.push_str(&class_table(suite, results));
    (csv, md)
}

/// Each family's zenith corrections from its survey (`suite.zenith_survey_seed`), by family
/// name: re-fitted from `FROM/zenith-survey/<family>/` when re-scoring a bench that stored one,
/// simulated otherwise (`threads` families at once), and stored under
/// `DIR/zenith-survey/<family>/`. Empty without a seed or with `--no-zenith-survey`.
fn zenith_surveys(
    suite: &Suite,
    families: &[&Family],
    args: &Args,
    threads: usize,
) -> anyhow::Result<std::collections::HashMap<String, Vec<(u16, ZenithCorrection)>>> {
    let mut out = std::collections::HashMap::new();
    let Some(seed) = suite.zenith_survey_seed.filter(|_| !args.no_zenith_survey) else {
        return Ok(out);
    };
    let progress = host_sim::progress_bar(&format!("zenith surveys (seed {seed})"));
    progress.set_length(families.len() as u64);
    let next = AtomicUsize::new(0);
    let done: Mutex<Vec<(String, anyhow::Result<host_sim::survey::Survey>)>> =
        Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..threads.clamp(1, families.len().max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(fam) = families.get(i) else { break };
                let stored = args
                    .rescore
                    .as_ref()
                    .map(|from| from.join("zenith-survey").join(&fam.name))
                    .filter(|d| d.join("truth.csv").is_file());
                let survey = match stored {
                    Some(dir) => host_sim::survey::Survey::load_seeded(&dir, seed).inspect(|sv| {
                        if sv.seed.is_none() {
                            eprintln!(
                                "warning: {} does not say its seed (stored before \
                                 survey.toml); re-fitted as it is",
                                dir.display()
                            )
                        }
                    }),
                    None => Scenario::load_with(&fam.scenario, seed, &fam.overrides)
                        .and_then(|sc| host_sim::survey::calibrate(&sc, seed, 1)),
                };
                let survey = survey.and_then(|sv| {
                    let dir = args.out.join("zenith-survey").join(&fam.name);
                    sv.store(&dir)?;
                    Ok(sv)
                });
                done.lock().expect("no panic holds it").push((fam.name.clone(), survey));
                progress.inc(1);
            });
        }
    });
    progress.finish_and_clear();
    for (name, survey) in done.into_inner().expect("no panic holds it") {
        let survey = survey.with_context(|| format!("the zenith survey of family `{name}`"))?;
        out.insert(name, survey.corrections());
    }
    Ok(out)
}

/// Where a run of `family` and `seed` keeps its recording and results, under `--out`.
fn run_dir(family: &Family, seed: u64) -> PathBuf {
    Path::new("runs").join(&family.name).join(format!("seed-{seed}"))
}

/// Runs `host-sim bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let suite = Suite::load(&args.suite)?;
    let seeds = match args.seeds.as_str() {
        "evaluation" => suite.evaluation_seeds.clone(),
        "tuning" => suite.tuning_seeds.clone(),
        other => bail!("--seeds `{other}`: use `evaluation` or `tuning`"),
    };
    for name in &args.families {
        if !suite.families.iter().any(|f| &f.name == name) {
            let known: Vec<&str> = suite.families.iter().map(|f| f.name.as_str()).collect();
            bail!(
                "--family `{name}` is not in {} (it has: {})",
                args.suite.display(),
                known.join(", ")
            );
        }
    }
    let families: Vec<&Family> = suite
        .families
        .iter()
        .filter(|f| args.families.is_empty() || args.families.contains(&f.name))
        .collect();
    let suite_profile = match &suite.profile {
        Some(p) => Profile::from_arg(p)?,
        None => Profile::dji_mini_2(),
    };
    // Each family's tracker profile, read once (not once per run).
    let profiles: Vec<Profile> = suite
        .families
        .iter()
        .map(|f| f.profile.as_deref().map_or_else(|| Ok(suite_profile.clone()), Profile::from_arg))
        .collect::<anyhow::Result<_>>()?;
    // Every run's recording must be there before any is re-tracked (not 160 errors later).
    if let Some(from) = &args.rescore {
        let missing: Vec<String> = families
            .iter()
            .flat_map(|f| seeds.iter().map(move |&s| run_dir(f, s)))
            .filter(|d| !from.join(d).is_dir())
            .map(|d| d.display().to_string())
            .collect();
        if !missing.is_empty() {
            bail!(
                "--rescore {}: no recorded run {} ({} of {} missing; was it a bench of {} with \
                 --seeds {}?)",
                from.display(),
                missing[0],
                missing.len(),
                families.len() * seeds.len(),
                args.suite.display(),
                args.seeds
            );
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let jobs: Vec<(&Family, u64)> =
        families.iter().flat_map(|f| seeds.iter().map(move |&s| (*f, s))).collect();
    let threads = match args.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .clamp(1, jobs.len().max(1));

    let surveys = zenith_surveys(&suite, &families, &args, threads)?;

    let progress = host_sim::progress_bar(&format!("bench {} runs", jobs.len()));
    progress.set_length(jobs.len() as u64);
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<RunResult>> = Mutex::new(Vec::new());
    let failures: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let run_one = |fam: &Family, seed: u64| -> anyhow::Result<Vec<RunResult>> {
        let run_dir = run_dir(fam, seed);
        let dir = args.out.join(&run_dir);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        let choose = suite.profile.is_none() && fam.profile.is_none();
        let index =
            suite.families.iter().position(|f| f.name == fam.name).expect("a listed family");
        let how = Tracking {
            profile: &profiles[index],
            kinds: &suite.filters,
            period: suite.period_s,
            choose_profile: choose,
            fuse_arrays: suite.fuse_arrays,
            zenith: surveys.get(&fam.name).map_or(&[], Vec::as_slice),
            strip_zenith: args.no_zenith_survey,
        };
        let runs = if let Some(from) = &args.rescore {
            let recorded = Recorded::load(&from.join(&run_dir))?;
            track_recorded(&recorded, &dir, &how)?
        } else {
            let scenario = Scenario::load_with(&fam.scenario, seed, &fam.overrides)?;
            let (sim, links) = host_sim::eval::link::simulate_links(
                &scenario,
                &host_sim::Options { threads: 1 },
                &indicatif::ProgressBar::hidden(),
                host_sim::DEFAULT_FULL_SCALE_PA,
            )?;
            track(&sim, &links, &dir, &how)?
        };
        Ok(runs
            .into_iter()
            .map(|r| RunResult {
                family: fam.name.clone(),
                seed,
                filter: r.kind,
                summary: r.summary,
                sync_max_us: r.sync.map_or(f64::NAN, |e| e.max_us),
            })
            .collect())
    };
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(fam, seed)) = jobs.get(i) else { break };
                progress.set_message(format!("{} seed {seed}", fam.name));
                match run_one(fam, seed) {
                    Ok(r) => results.lock().expect("no panic holding the lock").extend(r),
                    Err(e) => failures
                        .lock()
                        .expect("no panic holding the lock")
                        .push(format!("{} seed {seed}: {e:#}", fam.name)),
                }
                progress.inc(1);
            });
        }
    });
    progress.finish_and_clear();
    let mut results = results.into_inner().expect("workers done");
    results.sort_by(|a, b| {
        let fa = suite.families.iter().position(|f| f.name == a.family);
        let fb = suite.families.iter().position(|f| f.name == b.family);
        (fa, a.seed, filter_name(a.filter)).cmp(&(fb, b.seed, filter_name(b.filter)))
    });
    let label = format!(
        "{} {} ({})",
        seeds.len(),
        args.seeds,
        seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")
    );
    let (csv, md) = summary_tables(&suite, &results, &label);
    let write = |name: &str, text: &str| {
        let p = args.out.join(name);
        std::fs::write(&p, text).with_context(|| format!("writing {}", p.display()))
    };
    write("runs.csv", &runs_csv(&results))?;
    write("summary.csv", &csv)?;
    write("summary.md", &md)?;
    print!("{md}");
    let failures = failures.into_inner().expect("workers done");
    if !failures.is_empty() {
        bail!("{} of {} runs failed:\n{}", failures.len(), jobs.len(), failures.join("\n"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenarios() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
    }

    #[test]
    fn seeds_must_be_disjoint_and_the_error_names_them() {
        let text = r#"
tuning_seeds = [1, 2, 3]
evaluation_seeds = [3, 4, 2]
[[family]]
name = "a"
scenario = "square10-los.toml"
"#;
        let e = Suite::parse(text, &scenarios().join("x.toml")).unwrap_err().to_string();
        assert!(e.contains("must be disjoint; both list 3, 2"), "{e}");
        let dup = text.replace("[3, 4, 2]", "[4, 4]");
        let e = Suite::parse(&dup, &scenarios().join("x.toml")).unwrap_err().to_string();
        assert!(e.contains("evaluation_seeds lists a seed twice"), "{e}");
        // An output period that would fill memory with fixes, and a family name that leaves
        // `runs/`.
        let ok = text.replace("[3, 4, 2]", "[4]");
        let tiny = format!("period_s = 1e-9\n{ok}");
        let e = Suite::parse(&tiny, &scenarios().join("x.toml")).unwrap_err().to_string();
        assert!(e.contains("period_s 0.000000001 must be 0.001 to 10 s"), "{e}");
        let up = ok.replace("name = \"a\"", "name = \"..\"");
        let e = Suite::parse(&up, &scenarios().join("x.toml")).unwrap_err().to_string();
        assert!(e.contains("must be a plain word"), "{e}");
        // Names that would break a CSV row or a markdown cell, by their line (`name` is on
        // line 5 of `ok`).
        for bad in ["a,b", "a|b", "a\\nb", "a\\\"b"] {
            let odd = ok.replace("name = \"a\"", &format!("name = \"{bad}\""));
            let e = Suite::parse(&odd, &scenarios().join("x.toml")).unwrap_err().to_string();
            assert!(e.contains("x.toml:5: family[0].name") && e.contains("plain word"), "{e}");
        }
        // A filter listed twice would count each run as two seeds; a family twice.
        let twice = format!("filters = [\"aim\", \"paper\", \"aim\"]\n{ok}");
        let e = Suite::parse(&twice, &scenarios().join("x.toml")).unwrap_err().to_string();
        assert!(e.contains("x.toml:1: filters lists `aim` twice (entries 1 and 3)"), "{e}");
        let fam = ok.lines().skip(3).collect::<Vec<_>>().join("\n");
        let e = Suite::parse(&format!("{ok}{fam}\n"), &scenarios().join("x.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.toml:8: family[1].name `a` appears twice"), "{e}");
        // The survey's seed is its own: a flight's would repeat that flight's noise and drone.
        for z in [1, 4] {
            let survey = format!("zenith_survey_seed = {z}\n{ok}");
            let e = Suite::parse(&survey, &scenarios().join("x.toml")).unwrap_err().to_string();
            assert!(e.contains(&format!("zenith_survey_seed {z} is also a flight's seed")), "{e}");
        }
        let own = format!("zenith_survey_seed = 9\n{ok}");
        assert_eq!(
            Suite::parse(&own, &scenarios().join("x.toml")).unwrap().zenith_survey_seed,
            Some(9)
        );
    }

    #[test]
    fn a_bad_family_is_named_before_anything_runs() {
        let text = r#"
tuning_seeds = [1]
evaluation_seeds = [2]
[airframe]
wake_spread = 2.0
[[family]]
name = "fam"
scenario = "square10-los.toml"
"#;
        let e = format!("{:#}", Suite::parse(text, &scenarios().join("x.toml")).unwrap_err());
        assert!(e.contains("family `fam`") && e.contains("airframe.wake_spread"), "{e}");
        let missing = text.replace("wake_spread = 2.0", "").replace("square10-los", "nope");
        let e = format!("{:#}", Suite::parse(&missing, &scenarios().join("x.toml")).unwrap_err());
        assert!(e.contains("nope.toml"), "{e}");
        // A family's drone and profile: an unknown preset or profile is named.
        let ok = text.replace("wake_spread = 2.0", "");
        let bad = format!("{ok}drone = {{ preset = \"blimp\" }}\n");
        let e = format!("{:#}", Suite::parse(&bad, &scenarios().join("x.toml")).unwrap_err());
        assert!(e.contains("family `fam`") && e.contains("blimp"), "{e}");
        let bad = format!("{ok}profile = \"blimp\"\n");
        let e = format!("{:#}", Suite::parse(&bad, &scenarios().join("x.toml")).unwrap_err());
        assert!(e.contains("x.toml:9: family[0].profile (family `fam`)"), "{e}");
        assert!(e.contains("blimp"), "{e}");
        // The suite's own profile too, before any run.
        let bad = format!("profile = \"blimp\"\n{ok}");
        let e = format!("{:#}", Suite::parse(&bad, &scenarios().join("x.toml")).unwrap_err());
        assert!(e.contains("x.toml:1: profile: ") && e.contains("blimp"), "{e}");
    }

    #[test]
    fn mean_and_sample_sd() {
        let (m, sd) = mean_sd(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, 2.5);
        assert!((sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_sd(&[7.0]), (7.0, 0.0));
    }

    #[test]
    fn shipped_suites_load_with_disjoint_seeds_and_ten_evaluation_seeds() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("suites");
        let default = Suite::load(&dir.join("default.toml")).unwrap();
        assert!(default.evaluation_seeds.len() >= 10);
        assert!(default.families.len() >= 14, "{}", default.families.len());
        let ci = Suite::load(&dir.join("ci.toml")).unwrap();
        assert!(ci.families.len() <= 2 && ci.evaluation_seeds.len() <= 2);
        // The drone-type suites: the same families and seeds, one chooses the profile by
        // classifier, the other gives each family its type's bundled profile.
        let auto = Suite::load(&dir.join("types.toml")).unwrap();
        let given = Suite::load(&dir.join("types-profile.toml")).unwrap();
        assert_eq!(auto.families.len(), 6);
        assert_eq!(auto.evaluation_seeds, given.evaluation_seeds);
        for (a, g) in auto.families.iter().zip(&given.families) {
            assert_eq!((&a.name, &a.overrides, &a.profile), (&g.name, &g.overrides, &None));
            assert_eq!(g.profile.as_deref(), Some(Path::new(&g.name)));
            let drone = &a.overrides["drone"]["preset"];
            assert_eq!(drone.as_str(), Some(a.name.as_str()));
        }
    }
}
