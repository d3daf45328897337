//! Diagnosis of the BPF bench (not part of the product): writes the bench's clips for a seed
//! set so that the detector alone can be replayed on them quickly (`bpf_replay`).
//! `cargo run --release -p host-sim --example bpf_cache -- tune|eval|SEED,SEED,… DURATION OUTDIR`:
//! per clip `NAME.f32` (mono pressure at the array, f32 LE) and, for drone clips, `NAME.truth`
//! (per analysis index: the rotors' true BPFs at the window's centre). `CLEAN=1`: the drone
//! clips only, with no hall and no background (`d_AIRFRAME_c_0_SEED`, the source at 3 m).
use std::fmt::Write as _;

use host_sim::bpf_bench::{
    airframes, drone_sound, flight, in_hall, true_bpf, BACKGROUNDS_DB, FS, HALLS,
};
use host_sim::tonal::{scale_to_spl, Negative};

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(a.len() == 3, "usage: tune|eval|SEED,SEED,… DURATION OUTDIR");
    let seeds: Vec<u64> = match a[0].as_str() {
        "tune" => host_sim::bpf_bench::TUNING_SEEDS.to_vec(),
        "eval" => host_sim::bpf_bench::EVALUATION_SEEDS.to_vec(),
        list => list.split(',').map(str::parse).collect::<Result<_, _>>()?,
    };
    let dur: f64 = a[1].parse()?;
    let out = std::path::PathBuf::from(&a[2]);
    std::fs::create_dir_all(&out)?;
    let clean = std::env::var_os("CLEAN").is_some();
    let write = |name: &str, x: &[f64]| -> anyhow::Result<()> {
        let bytes: Vec<u8> = x.iter().flat_map(|&v| (v as f32).to_le_bytes()).collect();
        std::fs::write(out.join(name), bytes)?;
        Ok(())
    };
    for p in airframes() {
        for &seed in &seeds {
            let distance = if seed % 2 == 1 { 3.0 } else { 5.0 };
            let log = flight(&p, dur, seed)?;
            let source = drone_sound(&p, &log, dur, seed);
            // The truth file, the same for every hall and background of this flight.
            let mut truth = String::new();
            let n = ((dur * 8000.0) as usize - 4096) / 2048 + 1;
            for j in 0..n {
                let t = j as f64 * 0.256 + 0.256;
                let tr: Vec<String> = (0..p.rotor_count())
                    .map(|r| format!("{:.4}", true_bpf(&log, r, f64::from(p.blades), t)))
                    .collect();
                writeln!(truth, "{}", tr.join(","))?;
            }
            let clip = |name: &str, heard: &[f64]| -> anyhow::Result<()> {
                write(&format!("{name}.f32"), heard)?;
                std::fs::write(out.join(format!("{name}.truth")), &truth)?;
                Ok(())
            };
            if clean {
                let direct: Vec<f64> = source.iter().map(|v| v / 3.0).collect();
                clip(&format!("d_{}_c_0_{seed}", p.name), &direct)?;
                continue;
            }
            for (h, hall) in HALLS.iter().enumerate() {
                for bg in BACKGROUNDS_DB {
                    let heard = in_hall(&source, *hall, distance, bg, seed);
                    clip(&format!("d_{}_{h}_{bg}_{seed}", p.name), &heard)?;
                }
            }
        }
    }
    if clean {
        return Ok(());
    }
    let fs = f64::from(FS);
    for kind in Negative::ALL {
        for &seed in &seeds {
            for (h, hall) in HALLS.iter().enumerate() {
                let len = (dur * fs) as usize;
                let mut source = kind.signal(fs, len, 65.0, seed);
                scale_to_spl(&mut source, 65.0 + 20.0 * 3f64.log10());
                let heard = in_hall(&source, *hall, 3.0, 55.0, seed);
                write(&format!("n_{}_{h}_{seed}.f32", kind.name()), &heard)?;
            }
        }
    }
    Ok(())
}
