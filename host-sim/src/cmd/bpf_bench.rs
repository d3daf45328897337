//! `host-sim bpf-bench [--seeds tune|eval] [--duration S]`: the BPF detector on realistic
//! simulated drones and on non-drone sources (`host_sim::bpf_bench`), scored from the `Peaks`
//! frames read through the tracker's intake. Prints one line per airframe and per non-drone
//! source, the totals, then the per-seed mean ± sd of the three figures.
//!
//! Seeds: `tune` = `host_sim::bpf_bench::TUNING_SEEDS` (used while choosing the detector's
//! constants), `eval` = `EVALUATION_SEEDS` (reported). Every airframe flies in both halls at every background level (55, 62, 70 dB),
//! 3 m from the array for odd seeds and 5 m for even ones; every non-drone source plays at
//! 65 dB (direct, at the array) in both halls over the 55 dB background.
use anyhow::bail;

use super::bench::mean_sd;

use host_sim::bpf_bench::{
    airframes, drone_case, negative_case, Score, BACKGROUNDS_DB, EVALUATION_SEEDS, HALLS,
    SETTLING_FRAMES, TUNING_SEEDS,
};
use host_sim::tonal::Negative;

/// Arguments of `host-sim bpf-bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Seed set: `tune` or `eval`.
    #[arg(long, default_value = "eval")]
    seeds: String,
    /// Seconds per clip.
    #[arg(long, default_value_t = 10.0)]
    duration: f64,
}

fn pct(n: usize, d: usize) -> f64 {
    100.0 * n as f64 / d.max(1) as f64
}

/// Runs `host-sim bpf-bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let seeds: &[u64] = match args.seeds.as_str() {
        "tune" => &TUNING_SEEDS,
        "eval" => &EVALUATION_SEEDS,
        other => bail!("--seeds must be `tune` or `eval`, not `{other}`"),
    };
    if !(args.duration.is_finite() && (2.0..=120.0).contains(&args.duration)) {
        bail!("--duration must be 2–120 s, not {}", args.duration);
    }
    println!(
        "drones (seeds {seeds:?}, {} s clips, frames after the first {SETTLING_FRAMES} of each clip)",
        args.duration
    );
    println!(
        "{:<20} {:>6} {:>9} {:>10} {:>8}",
        "airframe", "frames", "with BPF", "within 2Hz", "octave"
    );
    let mut total = Score::default();
    // Per seed (same order as `seeds`): drones, non-drone sources.
    let mut per_seed = vec![(Score::default(), Score::default()); seeds.len()];
    for p in airframes() {
        let mut s = Score::default();
        for (i, &seed) in seeds.iter().enumerate() {
            let distance = if seed % 2 == 1 { 3.0 } else { 5.0 };
            for hall in HALLS {
                for bg in BACKGROUNDS_DB {
                    let c = drone_case(&p, hall, distance, bg, args.duration, seed)?;
                    per_seed[i].0 += c;
                    s += c;
                }
            }
        }
        println!(
            "{:<20} {:>6} {:>8.1}% {:>9.1}% {:>7.2}%",
            p.name,
            s.frames,
            pct(s.with_bpf, s.frames),
            pct(s.correct, s.frames),
            pct(s.octave, s.frames)
        );
        total += s;
    }
    println!(
        "{:<20} {:>6} {:>8.1}% {:>9.1}% {:>7.2}%   (of frames with a BPF: {:.1}% within 2 Hz)",
        "all drones",
        total.frames,
        pct(total.with_bpf, total.frames),
        pct(total.correct, total.frames),
        pct(total.octave, total.frames),
        pct(total.correct, total.with_bpf)
    );
    println!();
    println!("non-drone sources (65 dB direct at 3 m, 55 dB background)");
    println!("{:<20} {:>6} {:>9}", "source", "frames", "with BPF");
    let mut neg = Score::default();
    for kind in Negative::ALL {
        let mut s = Score::default();
        for (i, &seed) in seeds.iter().enumerate() {
            for hall in HALLS {
                let c = negative_case(kind, hall, 65.0, 55.0, args.duration, seed)?;
                per_seed[i].1 += c;
                s += c;
            }
        }
        println!("{:<20} {:>6} {:>8.1}%", kind.name(), s.frames, pct(s.with_bpf, s.frames));
        neg += s;
    }
    println!("{:<20} {:>6} {:>8.1}%", "all non-drone", neg.frames, pct(neg.with_bpf, neg.frames));
    println!();
    let stat =
        |f: &dyn Fn(&(Score, Score)) -> f64| mean_sd(&per_seed.iter().map(f).collect::<Vec<_>>());
    let (w, ws) = stat(&|(d, _)| pct(d.correct, d.frames));
    let (o, os) = stat(&|(d, _)| pct(d.octave, d.frames));
    let (n, ns) = stat(&|(_, n)| pct(n.with_bpf, n.frames));
    println!(
        "per seed, mean ± sd over {} seeds: drone frames within 2 Hz {w:.1} ± {ws:.1}%, octave \
         {o:.2} ± {os:.2}%, non-drone frames with a BPF {n:.2} ± {ns:.2}%",
        seeds.len()
    );
    Ok(())
}
