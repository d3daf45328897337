//! `aim id train | eval | classify`: is a drone in a recording, and which type
//! ([`aim_tracker::id`]).
//!
//! - `aim id train DIR --out MODEL [--features clip|chip]`: DIR holds one folder per class of
//!   WAV recordings (mono or multichannel, 16 or 48 kHz, any length from 0.25 s — 0.8 s with
//!   `chip`; a class `none` for no drone); writes the model (JSON). `--features chip` trains
//!   on what the chip sends (`Mfcc` frames, windows of 6), the model `aim track --id-model`
//!   needs.
//! - `aim id eval DIR --model MODEL [--false-alarm 0.01] [--per-recording
//!   [--decision-windows 3] [--type-windows 6]] [--set-threshold] [--json]`: the confusion matrix, per-class
//!   precision and recall, the type accuracy among drone clips and the detection ROC (drone
//!   probability against `none`) with the threshold at the stated false-alarm rate; per window
//!   of `Mfcc` frames, or per recording by the live verdict at its end ([`chip::Live`]);
//!   `--set-threshold` writes that threshold into the model file.
//! - `aim id classify WAV... --model MODEL`: one JSON line per file, the verdict at its end
//!   as `aim track` would give it and `aim id eval --per-recording` scores it:
//!   `{"file":..,"class":..,"probability":..,"drone_probability":..,"probabilities":{..}}`.
use std::io::Write as _;
use std::path::{Path, PathBuf};

use aim_dsp::features::Extractor;
use aim_tracker::id::{audio, chip, clip, dataset, metrics, model, NONE_CLASS};
use anyhow::{bail, Context as _};

/// Arguments of `aim id`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: IdCommand,
}

#[derive(clap::Subcommand)]
enum IdCommand {
    /// Train a model on a folder of labelled recordings (`DIR/<class>/*.wav`).
    Train(TrainArgs),
    /// Evaluate a model on a folder of labelled recordings.
    Eval(EvalArgs),
    /// Classify recordings: one JSON line per file.
    Classify(ClassifyArgs),
}

#[derive(clap::Args)]
struct TrainArgs {
    /// Dataset folder: one subfolder of WAV files per class (`none`: no drone).
    dir: PathBuf,
    /// Model file to write (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Passes over the training set.
    #[arg(long, default_value_t = model::Training::default().epochs)]
    epochs: usize,
    /// Hidden units.
    #[arg(long, default_value_t = model::Training::default().hidden_units)]
    hidden: usize,
    /// Networks in the ensemble (their probabilities averaged).
    #[arg(long, default_value_t = model::Training::default().members)]
    members: usize,
    /// Seed of the initial weights and batch order.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Features: `clip` (the 16 kHz frame features of the whole clip, `aim_tracker::id::clip`)
    /// or `chip` (windows of the `Mfcc` frames the chip's pipeline makes of the recording,
    /// `aim_tracker::id::chip`: what `aim track` classifies live).
    #[arg(long, default_value = "clip", value_parser = ["clip", "chip"])]
    features: String,
    /// With `--features chip`: the share of recordings heard through an array (one of the
    /// shipped geometries, a plane wave from a random direction, zenith 30–90°, drawn from
    /// `--seed`) rather than the same samples on every microphone. The chip's features come
    /// from the mean of its microphones, which an array's aperture filters by direction; a
    /// model trained on single-microphone recordings only misreads drones heard by an array.
    #[arg(long, default_value_t = 0.5)]
    array_share: f64,
}

#[derive(clap::Args)]
struct EvalArgs {
    /// Dataset folder: one subfolder of WAV files per class, classes known to the model.
    dir: PathBuf,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
    /// False-alarm rate of the reported detection threshold.
    #[arg(long, default_value_t = 0.01)]
    false_alarm: f64,
    /// Print one JSON object instead of tables (`clips`: how many scores, each a recording or
    /// a window as `scored` says).
    #[arg(long)]
    json: bool,
    /// Score each recording once, by the verdict `aim track` would show at its end (a `chip`
    /// model: the drone probability from the last three disjoint windows of `Mfcc` frames,
    /// `aim_tracker::id::chip::DECISION_WINDOWS`, the type from up to six,
    /// `aim_tracker::id::chip::TYPE_WINDOWS`), rather than each window on its own.
    #[arg(long)]
    per_recording: bool,
    /// Write the detection threshold at `--false-alarm` on these recordings into the model
    /// file (`drone_threshold`): from then on the model's verdicts (`aim track`'s `drone`
    /// field, the confusion matrix here) name a drone only from that drone probability.
    /// Choose it on tuning recordings, with `--per-recording` for the live verdict.
    #[arg(long)]
    set_threshold: bool,
    /// With `--per-recording` and a `chip` model: disjoint windows whether a drone is there
    /// is decided on (also the fewest the type is).
    #[arg(long, default_value_t = chip::DECISION_WINDOWS as u16, requires = "per_recording",
          value_parser = clap::value_parser!(u16).range(1..=100))]
    decision_windows: u16,
    /// With `--per-recording` and a `chip` model: most disjoint windows the type of a
    /// detected drone averages (never fewer than `--decision-windows`).
    #[arg(long, default_value_t = chip::TYPE_WINDOWS as u16, requires = "per_recording",
          value_parser = clap::value_parser!(u16).range(1..=100))]
    type_windows: u16,
    /// With `--per-recording`: also write every recording's score to this CSV file (`path`,
    /// `class`, `drone_probability`, `verdict`), to see which recordings the errors are.
    #[arg(long, requires = "per_recording")]
    scores: Option<PathBuf>,
}

#[derive(clap::Args)]
struct ClassifyArgs {
    /// Recordings (WAV, mono or multichannel, 16 or 48 kHz).
    #[arg(required = true)]
    wav: Vec<PathBuf>,
    /// Model file.
    #[arg(long)]
    model: PathBuf,
}

/// Runs `aim id`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        IdCommand::Train(a) => train(a),
        IdCommand::Eval(a) => eval(a),
        IdCommand::Classify(a) => classify(a),
    }
}

/// The feature vectors of one recording: one (`clip`), or one per window of `Mfcc` frames
/// (`chip`: at least one; heard through `arrival`'s array if given).
fn features_of(
    path: &Path,
    ex: &Extractor,
    chip_frames: bool,
    arrival: Option<&chip::Arrival>,
) -> anyhow::Result<Vec<Vec<f32>>> {
    if chip_frames {
        return chip_windows(path, &mfcc_frames(path, arrival)?);
    }
    let x = audio::read_mono_16k(path)?;
    Ok(vec![clip::features(&x, ex)])
}

/// The `Mfcc` frames the chip's pipeline makes of the recording at `path` (heard through
/// `arrival`'s array if given).
fn mfcc_frames(
    path: &Path,
    arrival: Option<&chip::Arrival>,
) -> anyhow::Result<Vec<aim_wire::Mfcc>> {
    let (x, rate) = audio::read_mono(path)?;
    Ok(chip::frames_of_arrival(&x, rate, arrival)?.into_iter().map(|(_, m)| m).collect())
}

/// [`chip::windows`] of the recording at `path`'s `frames`: at least one, or an error naming
/// the file.
fn chip_windows(path: &Path, frames: &[aim_wire::Mfcc]) -> anyhow::Result<Vec<Vec<f32>>> {
    let w = chip::windows(frames);
    if w.is_empty() {
        bail!(
            "{}: {} Mfcc frames, at least {} needed (about 0.8 s of audio)",
            path.display(),
            frames.len(),
            chip::MIN_FRAMES
        );
    }
    Ok(w)
}

/// `f` of every job, in the jobs' order, computed on every core (each thread with its own
/// [`Extractor`]); the first error in job order is returned, and once a job has failed no
/// further job is handed out (those already taken finish). A progress bar on a terminal
/// counts the recordings.
fn on_every_core<J: Sync, T: Send>(
    jobs: &[J],
    f: impl Fn(&Extractor, &J) -> anyhow::Result<T> + Sync,
) -> anyhow::Result<Vec<T>> {
    on_threads(jobs, std::thread::available_parallelism().map_or(1, |n| n.get()), f)
}

/// [`on_every_core`] on `threads` threads.
fn on_threads<J: Sync, T: Send>(
    jobs: &[J],
    threads: usize,
    f: impl Fn(&Extractor, &J) -> anyhow::Result<T> + Sync,
) -> anyhow::Result<Vec<T>> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let progress = indicatif::ProgressBar::new(jobs.len() as u64).with_style(
        indicatif::ProgressStyle::with_template("reading recordings {bar:30} {pos}/{len} {eta}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let next = AtomicUsize::new(0);
    let threads = threads.min(jobs.len());
    let mut done: Vec<(usize, anyhow::Result<T>)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.max(1))
            .map(|_| {
                s.spawn(|| {
                    let ex = Extractor::new();
                    let mut out = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(job) = jobs.get(i) else { break };
                        let r = f(&ex, job);
                        let failed = r.is_err();
                        out.push((i, r));
                        progress.inc(1);
                        if failed {
                            next.store(jobs.len(), Ordering::Relaxed);
                        }
                    }
                    out
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    });
    progress.finish_and_clear();
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// Feature vectors and labels of every clip of `classes`, labels from `index`; with
/// `arrivals = Some((share, seed))`, that share of the clips heard through an array
/// ([`chip::Arrival::draw`], seeded by `seed` and the clip's place). The clips are read on
/// every core (the result is the same, in the same order, on any number); a progress bar on
/// a terminal counts them.
fn load(
    classes: &[dataset::Class],
    chip_frames: bool,
    arrivals: Option<(f64, u64)>,
    index: impl Fn(&str) -> anyhow::Result<usize>,
) -> anyhow::Result<(Vec<Vec<f32>>, Vec<usize>)> {
    let mut jobs = Vec::new();
    for (ci, c) in classes.iter().enumerate() {
        let label = index(&c.name)?;
        for (fi, f) in c.files.iter().enumerate() {
            let arrival = arrivals.and_then(|(share, seed)| {
                let clip = seed.wrapping_mul(1 << 20) ^ ((ci as u64) << 40) ^ fi as u64;
                (chip::unit_hash(clip) < share).then(|| chip::Arrival::draw(clip << 8))
            });
            jobs.push((f.as_path(), label, arrival));
        }
    }
    let done = on_every_core(&jobs, |ex, (path, _, arrival)| {
        features_of(path, ex, chip_frames, arrival.as_ref())
    })?;
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for (vectors, (_, label, _)) in done.into_iter().zip(&jobs) {
        for v in vectors {
            x.push(v);
            y.push(*label);
        }
    }
    Ok((x, y))
}

/// The model's verdict on one recording as `aim track` would give it at the recording's
/// end: for a `chip` model, the recording's `Mfcc` frames through [`chip::Live`] (the drone
/// probability over the last `decision_windows` disjoint windows, by default
/// [`chip::DECISION_WINDOWS`], the type over up to `type_windows`, by default
/// [`chip::TYPE_WINDOWS`]; a recording shorter than one window is one window of all its
/// frames, where `aim track` would still show no verdict); for a `clip` model, the clip's one
/// vector.
fn recording_probabilities(
    m: &model::Model,
    path: &Path,
    ex: &Extractor,
    decision_windows: usize,
    type_windows: usize,
) -> anyhow::Result<Vec<f32>> {
    if !m.reads_chip_frames() {
        let v = features_of(path, ex, false, None)?;
        return Ok(m.predict(&v[0]));
    }
    let frames = mfcc_frames(path, None)?;
    if frames.len() < chip::WINDOW_FRAMES {
        return Ok(m.predict(&chip_windows(path, &frames)?[0]));
    }
    let mut live = chip::Live::new(m.clone())?
        .with_decision_windows(decision_windows)
        .with_type_windows(type_windows);
    frames.iter().for_each(|f| live.push(f));
    let v = live.verdict().context("a full window gave no verdict")?;
    Ok(v.probabilities.clone())
}

/// Writes `aim id eval --scores`: one CSV row per recording, in the order scored.
fn write_scores(
    path: &Path,
    m: &model::Model,
    recordings: &[(&Path, usize)],
    scores: &[(Vec<f32>, usize)],
) -> anyhow::Result<()> {
    let mut csv = String::from("path,class,drone_probability,verdict\n");
    for ((file, label), (p, _)) in recordings.iter().zip(scores) {
        csv += &format!(
            "{},{},{:.6},{}\n",
            csv_field(&file.display().to_string()),
            csv_field(&m.classes[*label]),
            m.drone_probability(p),
            csv_field(&m.classes[m.decide(p)])
        );
    }
    std::fs::write(path, csv).with_context(|| format!("cannot write {}", path.display()))
}

/// `text` as one CSV field (RFC 4180): in double quotes, its quotes doubled, when it holds a
/// comma, a quote or a line break; as it is otherwise.
fn csv_field(text: &str) -> String {
    match text.contains([',', '"', '\n', '\r']) {
        true => format!("\"{}\"", text.replace('"', "\"\"")),
        false => text.to_string(),
    }
}

/// Most passes over the training set `aim id train` takes.
const MAX_EPOCHS: usize = 100_000;
/// Most hidden units of a network (4096: a 4096 × 89 layer and its output, about 1.5 MB).
const MAX_HIDDEN: usize = 4096;
/// Most networks in an ensemble.
const MAX_MEMBERS: usize = 32;

/// An error now, not after the training, if `path` cannot be written (its folder missing or
/// read-only): a probe file beside it is made and removed.
fn check_writable(flag: &str, path: &Path) -> anyhow::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let probe = dir.join(format!(".aim-id-{}.probe", std::process::id()));
    std::fs::write(&probe, b"")
        .with_context(|| format!("{flag} {}: cannot write in {}", path.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    if path.is_dir() {
        bail!("{flag} {} is a folder; give a file name", path.display());
    }
    if path.exists() {
        // Opened to append, not truncated: an existing model stays as it is until the new
        // one is written.
        std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .with_context(|| format!("{flag} {}: cannot be written", path.display()))?;
    }
    Ok(())
}

fn train(a: TrainArgs) -> anyhow::Result<()> {
    let classes = dataset::scan(&a.dir)?;
    if classes.len() < 2 {
        bail!("{}: one class ({}); training needs at least two", a.dir.display(), classes[0].name);
    }
    let names: Vec<String> = classes.iter().map(|c| c.name.clone()).collect();
    let chip_frames = a.features == "chip";
    if !(0.0..=1.0).contains(&a.array_share) {
        bail!("--array-share must be in 0..=1, got {}", a.array_share);
    }
    for (flag, value, range) in [
        ("--epochs", a.epochs, 1..=MAX_EPOCHS),
        ("--hidden", a.hidden, 1..=MAX_HIDDEN),
        ("--members", a.members, 1..=MAX_MEMBERS),
    ] {
        if !range.contains(&value) {
            bail!("{flag} must be {} to {}, not {value}", range.start(), range.end());
        }
    }
    check_writable("--out", &a.out)?;
    let arrivals = (chip_frames && a.array_share > 0.0).then_some((a.array_share, a.seed));
    let (x, y) = load(&classes, chip_frames, arrivals, |n| {
        Ok(names.iter().position(|c| c == n).unwrap_or(0))
    })?;
    let t = model::Training {
        epochs: a.epochs,
        hidden_units: a.hidden,
        members: a.members,
        seed: a.seed,
        ..model::Training::default()
    };
    let feature_names = if chip_frames { chip::names() } else { clip::names() };
    let m = model::Model::train(feature_names, names.clone(), &x, &y, t)?;
    m.save(&a.out)?;
    let right =
        x.iter().zip(&y).filter(|(v, &c)| m.most_probable(&m.predict(v), None) == c).count();
    let mut out = std::io::stdout().lock();
    for c in &classes {
        writeln!(out, "{:<20} {} clips", c.name, c.files.len())?;
    }
    writeln!(
        out,
        "trained on {} clips, {} classes; training accuracy {:.1} %; model written to {}",
        x.len(),
        names.len(),
        100.0 * right as f64 / x.len() as f64,
        a.out.display()
    )?;
    Ok(())
}

fn eval(a: EvalArgs) -> anyhow::Result<()> {
    if !(0.0..=1.0).contains(&a.false_alarm) {
        bail!("--false-alarm must be in 0..=1, got {}", a.false_alarm);
    }
    let m = model::Model::load(&a.model)?;
    let classes = dataset::scan(&a.dir)?;
    let index = |n: &str| {
        m.classes.iter().position(|c| c == n).with_context(|| {
            format!(
                "{}: class `{n}` is not one the model knows ({})",
                a.dir.join(n).display(),
                m.classes.join(", ")
            )
        })
    };
    if let Some(path) = &a.scores {
        check_writable("--scores", path)?;
    }
    let mut recordings: Vec<(&Path, usize)> = Vec::new();
    let scores: Vec<(Vec<f32>, usize)> = if a.per_recording {
        let jobs = &mut recordings;
        for c in &classes {
            let label = index(&c.name)?;
            jobs.extend(c.files.iter().map(|f| (f.as_path(), label)));
        }
        let (windows, types) = (usize::from(a.decision_windows), usize::from(a.type_windows));
        on_every_core(jobs, |ex, &(path, label)| {
            Ok((recording_probabilities(&m, path, ex, windows, types)?, label))
        })?
    } else {
        let (x, y) = load(&classes, m.reads_chip_frames(), None, index)?;
        x.iter().zip(y).map(|(v, y)| (m.predict(v), y)).collect()
    };
    if let Some(path) = &a.scores {
        write_scores(path, &m, &recordings, &scores)?;
    }
    let none = m.none_index();
    let mut confusion = metrics::Confusion::new(m.classes.clone());
    let (mut pos, mut neg) = (Vec::new(), Vec::new());
    let (mut type_right, mut type_n) = (0usize, 0usize);
    for (p, truth) in scores.iter().map(|(p, t)| (p, *t)) {
        confusion.add(truth, m.decide(p));
        let score = f64::from(m.drone_probability(p));
        if Some(truth) == none {
            neg.push(score);
        } else {
            pos.push(score);
            // Type among the drone classes only.
            type_n += 1;
            type_right += usize::from(m.most_probable(p, none) == truth);
        }
    }
    let roc = (!pos.is_empty() && !neg.is_empty()).then(|| metrics::roc(&pos, &neg));
    let op = roc.as_ref().and_then(|r| metrics::at_false_alarm(r, a.false_alarm));
    let type_accuracy = (type_n > 0).then(|| type_right as f64 / type_n as f64);
    if a.set_threshold {
        let Some(p) = op else {
            bail!(
                "--set-threshold needs both `{NONE_CLASS}` and drone recordings in {}",
                a.dir.display()
            );
        };
        if !p.threshold.is_finite() || !(0.0..=1.0).contains(&p.threshold) {
            bail!(
                "--set-threshold: no drone probability gives {} % false alarms or fewer on {} \
                 but every recording (threshold {}); choose a smaller --false-alarm",
                100.0 * a.false_alarm,
                a.dir.display(),
                p.threshold
            );
        }
        let mut with = m.clone();
        with.drone_threshold = Some(p.threshold as f32);
        // Written beside the model and renamed over it: a failed write leaves the old file.
        let tmp = a.model.with_extension("json.tmp");
        with.save(&tmp)?;
        std::fs::rename(&tmp, &a.model)
            .with_context(|| format!("cannot replace {}", a.model.display()))?;
        let scored = if a.per_recording {
            format!("live verdicts of {} windows per recording", a.decision_windows)
        } else {
            "single windows".to_string()
        };
        eprintln!(
            "drone threshold {:.4} (false alarms {:.2} %, detection {:.2} % on {}, {scored}) \
             written to {}; the confusion matrix below still uses the model as it was",
            p.threshold,
            100.0 * p.false_alarm,
            100.0 * p.detection,
            a.dir.display(),
            a.model.display()
        );
    }
    let mut out = std::io::stdout().lock();
    // What one score is: a recording, or one window of a recording's Mfcc frames.
    let unit = if a.per_recording || !m.reads_chip_frames() { "recordings" } else { "windows" };
    if a.json {
        let per_class: Vec<_> = (0..m.classes.len())
            .map(|c| {
                serde_json::json!({
                    "class": m.classes[c],
                    "clips": confusion.counts[c].iter().sum::<usize>(),
                    "precision": confusion.precision(c),
                    "recall": confusion.recall(c),
                })
            })
            .collect();
        let j = serde_json::json!({
            "clips": scores.len(),
            "scored": unit,
            "per_recording": a.per_recording,
            "accuracy": confusion.accuracy(),
            "type_accuracy": type_accuracy,
            "confusion": confusion,
            "per_class": per_class,
            "detection": op.map(|p| serde_json::json!({
                "false_alarm_target": a.false_alarm,
                "threshold": p.threshold,
                "detection": p.detection,
                "false_alarm": p.false_alarm,
                "auc": roc.as_deref().map(metrics::auc),
                "drone_clips": pos.len(),
                "none_clips": neg.len(),
            })),
        });
        writeln!(out, "{j}")?;
        return Ok(());
    }
    writeln!(
        out,
        "{} {unit} scored; accuracy (all classes) {:.2} %",
        scores.len(),
        100.0 * confusion.accuracy()
    )?;
    if let Some(t) = type_accuracy {
        writeln!(
            out,
            "type accuracy among {type_n} drone clips (drone classes only): {:.2} %",
            100.0 * t
        )?;
    }
    writeln!(out, "\nconfusion (rows: true class, columns: predicted, in class order)")?;
    for (c, row) in confusion.counts.iter().enumerate() {
        let cells: Vec<String> = row.iter().map(|n| format!("{n:>5}")).collect();
        writeln!(out, "{:<20}{}", m.classes[c], cells.join(""))?;
    }
    writeln!(out, "\n{:<20}{:>6}{:>11}{:>8}", "class", "clips", "precision", "recall")?;
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.1}%", 100.0 * v));
    for c in 0..m.classes.len() {
        let n: usize = confusion.counts[c].iter().sum();
        writeln!(
            out,
            "{:<20}{:>6}{:>11}{:>8}",
            m.classes[c],
            n,
            pct(confusion.precision(c)),
            pct(confusion.recall(c))
        )?;
    }
    match (&roc, op) {
        (Some(r), Some(p)) => {
            writeln!(
                out,
                "\ndetection ({} drone / {} {NONE_CLASS} clips): AUC {:.4}; at <= {:.2} % false alarms: \
                 threshold {:.4}, detection {:.2} %, false alarms {:.2} %",
                pos.len(),
                neg.len(),
                metrics::auc(r),
                100.0 * a.false_alarm,
                p.threshold,
                100.0 * p.detection,
                100.0 * p.false_alarm
            )?;
            writeln!(out, "ROC (false alarm, detection):")?;
            let step = (r.len() / 20).max(1);
            for p in r.iter().step_by(step) {
                writeln!(out, "  {:.4} {:.4}", p.false_alarm, p.detection)?;
            }
        }
        _ => writeln!(out, "\nno detection ROC: needs both `{NONE_CLASS}` and drone clips")?,
    }
    Ok(())
}

fn classify(a: ClassifyArgs) -> anyhow::Result<()> {
    let m = model::Model::load(&a.model)?;
    let ex = Extractor::new();
    let mut out = std::io::stdout().lock();
    for f in &a.wav {
        // The verdict `aim track` would give at the recording's end (a chip model: the live
        // pooling of the last windows), the same as `aim id eval --per-recording` scores.
        let p = recording_probabilities(&m, f, &ex, chip::DECISION_WINDOWS, chip::TYPE_WINDOWS)?;
        let best = m.decide(&p);
        let probabilities: serde_json::Map<String, serde_json::Value> =
            m.classes.iter().zip(&p).map(|(c, v)| (c.clone(), serde_json::json!(v))).collect();
        let j = serde_json::json!({
            "file": f.display().to_string(),
            "class": m.classes[best],
            "probability": p[best],
            "drone_probability": m.drone_probability(&p),
            "probabilities": probabilities,
        });
        writeln!(out, "{j}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RFC 4180 fields: plain text as it is; a comma, quote or line break quoted, quotes
    /// doubled.
    #[test]
    fn csv_fields_are_quoted_when_they_must_be() {
        assert_eq!(csv_field("a/b c.wav"), "a/b c.wav");
        assert_eq!(csv_field("x,y.wav"), "\"x,y.wav\"");
        assert_eq!(csv_field("say \"hi\""), r#""say ""hi""""#);
        assert_eq!(csv_field("a\r\nb"), "\"a\r\nb\"");
    }

    /// Results come back in the jobs' order on any number of threads, and the first error
    /// in job order is the one returned.
    #[test]
    fn work_on_every_core_keeps_the_order_and_the_first_error() {
        let jobs: Vec<u64> = (0..200).collect();
        let square = |_: &Extractor, j: &u64| -> anyhow::Result<u64> { Ok(j * j) };
        let want: Vec<u64> = jobs.iter().map(|j| j * j).collect();
        for threads in [1, 2, 7] {
            assert_eq!(on_threads(&jobs, threads, square).unwrap(), want);
        }
        let fail = |_: &Extractor, j: &u64| -> anyhow::Result<u64> {
            if *j == 60 || *j == 61 {
                bail!("job {j} failed")
            }
            Ok(*j)
        };
        for threads in [1, 2, 7] {
            let e = on_threads(&jobs, threads, fail).unwrap_err();
            assert_eq!(e.to_string(), "job 60 failed");
        }
        assert!(on_threads(&[] as &[u64], 2, square).unwrap().is_empty());
    }
}
