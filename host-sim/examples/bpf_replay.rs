//! Diagnosis of the BPF bench (not part of the product): the detector alone (`SpectralPath`
//! on the mono pressure, no pipeline, no wire) on the clips `bpf_cache` wrote, scored as
//! `host-sim bpf-bench` scores. `cargo run --release -p host-sim --example bpf_replay -- DIR`.
//! Environment: `Q`, `P` override `Config::bpf_min_quality` and `Config::peak_floor_ratio`;
//! `V=1` prints each clip, `F=NAME` each frame of the clips whose name holds NAME; `SKIP=N`
//! [the bench's `SETTLING_FRAMES`, 3] scores frames from analysis N on (to compare detectors
//! whose combs start at different ages).
use std::collections::BTreeMap;

use aim_dsp::bpf::{SpectralPath, ANALYSIS_LEN};
use aim_dsp::{Config, Geometry};
use host_sim::bpf_bench::{classify, Verdict};

/// Per clip or class: frames, frames with a BPF, within 2 Hz, octave errors, octave errors
/// below every rotor (a shaft comb reported).
const COUNTS: usize = 5;
type Counts = [usize; COUNTS];

fn frames(x: &[f32], config: &Config) -> Vec<Vec<f32>> {
    let mut path = SpectralPath::empty();
    path.configure(16_000, 1);
    let tw = aim_dsp::gcc_phat::Twiddles::new();
    let mut scratch = [0.0f32; ANALYSIS_LEN];
    let mut out = Vec::new();
    for &v in x {
        if path.push(v * 0.05) {
            let p = path.analyze(config, &mut scratch, &tw);
            out.push(p.peaks[..p.count as usize].iter().map(|q| q.hz).collect());
        }
    }
    out
}

fn main() -> anyhow::Result<()> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("DIR"));
    let verbose = std::env::var_os("V").is_some();
    let skip: usize = match std::env::var("SKIP") {
        Ok(v) => v.parse()?,
        Err(_) => host_sim::bpf_bench::SETTLING_FRAMES,
    };
    let mut config = Config::new(Geometry::respeaker_6mic(), 16_000);
    if let Ok(v) = std::env::var("Q") {
        config.bpf_min_quality = v.parse()?;
    }
    if let Ok(v) = std::env::var("P") {
        config.peak_floor_ratio = v.parse()?;
    }
    let mut names: Vec<_> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".f32"))
        .collect();
    names.sort();
    let mut by: BTreeMap<String, Counts> = BTreeMap::new();
    for n in names {
        let bytes = std::fs::read(dir.join(&n))?;
        let x: Vec<f32> =
            bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let fr = frames(&x, &config);
        let stem = n.trim_end_matches(".f32");
        let parts: Vec<&str> = stem.split('_').collect();
        let key = format!("{}_{}", parts[0], parts[1]);
        let e = by.entry(key).or_default();
        let mut case: Counts = [0; COUNTS];
        if parts[0] == "d" {
            let truth = std::fs::read_to_string(dir.join(format!("{stem}.truth")))?;
            let truth: Vec<Vec<f64>> =
                truth.lines().map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
            for (j, g) in fr.iter().enumerate().skip(skip) {
                case[0] += 1;
                let Some(&f) = g.first() else { continue };
                let f = f as f64;
                case[1] += 1;
                let tr = &truth[j.min(truth.len() - 1)];
                if std::env::var("F").is_ok_and(|f| stem.contains(&f)) {
                    println!("{stem} {j} {g:.1?} truth {tr:.1?}");
                }
                match classify(f, tr) {
                    Verdict::Correct => case[2] += 1,
                    Verdict::Octave => {
                        case[3] += 1;
                        if tr.iter().all(|&b| f < b) {
                            case[4] += 1;
                        }
                    }
                    Verdict::Wrong => {}
                }
            }
        } else {
            for (j, g) in fr.iter().enumerate().skip(skip) {
                if !g.is_empty() && std::env::var("F").is_ok_and(|f| stem.contains(&f)) {
                    println!("{stem} {j} {g:.1?}");
                }
                case[0] += 1;
                case[1] += usize::from(!g.is_empty());
            }
        }
        if verbose {
            println!("{stem:40} {:3} {:3} {:3} {:3}", case[0], case[1], case[2], case[3]);
        }
        for i in 0..COUNTS {
            e[i] += case[i];
        }
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    let (mut d, mut nd): (Counts, Counts) = ([0; COUNTS], [0; COUNTS]);
    for (k, v) in &by {
        println!(
            "{k:28} {:5} with {:5.1}% within {:5.1}% octave {:5.2}% (below {:5.2}%)",
            v[0],
            pct(v[1], v[0]),
            pct(v[2], v[0]),
            pct(v[3], v[0]),
            pct(v[4], v[0])
        );
        let t = if k.starts_with("d_") { &mut d } else { &mut nd };
        for i in 0..COUNTS {
            t[i] += v[i];
        }
    }
    println!(
        "ALL DRONES {:5} with {:5.1}% within {:5.1}% octave {:5.2}% | NONDRONE {:5} with {:5.2}%",
        d[0],
        pct(d[1], d[0]),
        pct(d[2], d[0]),
        pct(d[3], d[0]),
        nd[0],
        pct(nd[1], nd[0])
    );
    Ok(())
}
