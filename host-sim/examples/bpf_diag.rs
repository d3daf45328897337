//! Diagnosis of the BPF bench (not part of the product): one drone case's files for offline
//! analysis. `cargo run --release -p host-sim --example bpf_diag -- AIRFRAME HALL BG DIST SEED
//! DURATION OUTDIR` writes `heard.f32` (mono pressure at the array, f32 LE), `rotor{r}.f32`
//! (each rotor's sound at 1 m), `rotors.csv` (t, rotor speeds Hz, 1 ms grid) and `frames.csv`
//! (frame time, groups Hz) as the intake delivers them.
use std::io::Write;

use host_sim::bpf_bench::{
    airframes, flight, frames_through_intake, in_hall, rotor_sounds, FS, HALLS,
};

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.first().map(String::as_str) == Some("negative") {
        return negative(&a[1..]);
    }
    anyhow::ensure!(a.len() == 7, "usage: AIRFRAME HALL BG DIST SEED DURATION OUTDIR");
    let profile = airframes()
        .into_iter()
        .find(|p| p.name == a[0])
        .ok_or_else(|| anyhow::anyhow!("no airframe {}", a[0]))?;
    let hall = HALLS[a[1].parse::<usize>()?];
    let (bg, dist, seed, dur): (f64, f64, u64, f64) =
        (a[2].parse()?, a[3].parse()?, a[4].parse()?, a[5].parse()?);
    let out = std::path::PathBuf::from(&a[6]);
    std::fs::create_dir_all(&out)?;
    let log = flight(&profile, dur, seed)?;
    let rotors = rotor_sounds(&profile, &log, dur, seed);
    let mut source = vec![0.0; rotors[0].len()];
    for r in &rotors {
        host_sim::tonal::add(&mut source, r, 1.0);
    }
    let heard = in_hall(&source, hall, dist, bg, seed);
    let write = |name: &str, x: &[f64]| -> anyhow::Result<()> {
        let bytes: Vec<u8> = x.iter().flat_map(|&v| (v as f32).to_le_bytes()).collect();
        std::fs::write(out.join(name), bytes)?;
        Ok(())
    };
    write("heard.f32", &heard)?;
    for (i, r) in rotors.iter().enumerate() {
        write(&format!("rotor{i}.f32"), r)?;
    }
    let mut f = std::fs::File::create(out.join("rotors.csv"))?;
    let n = (dur * 1000.0) as usize;
    for i in 0..n {
        let t = i as f64 / 1000.0;
        let speeds: Vec<String> =
            (0..profile.rotor_count()).map(|r| format!("{:.4}", log.rotor_hz(r, t))).collect();
        writeln!(f, "{t:.3},{}", speeds.join(","))?;
    }
    let mut f = std::fs::File::create(out.join("frames.csv"))?;
    for (t, groups) in frames_through_intake(&heard)? {
        let g: Vec<String> = groups.iter().map(|h| format!("{h:.3}")).collect();
        writeln!(f, "{t:.4},{}", g.join(","))?;
    }
    eprintln!("blades {} fs {FS}", profile.blades);
    Ok(())
}

/// `negative SEED DURATION`: every non-drone source in both halls; prints each frame's groups.
fn negative(a: &[String]) -> anyhow::Result<()> {
    let (seed, dur): (u64, f64) = (a[0].parse()?, a[1].parse()?);
    let fs = f64::from(FS);
    for kind in host_sim::tonal::Negative::ALL {
        for hall in HALLS {
            let len = (dur * fs) as usize;
            let mut source = kind.signal(fs, len, 65.0, seed);
            host_sim::tonal::scale_to_spl(&mut source, 65.0 + 20.0 * 3f64.log10());
            let heard = in_hall(&source, hall, 3.0, 55.0, seed);
            for (t, g) in frames_through_intake(&heard)? {
                if !g.is_empty() {
                    println!("{} rt60 {} t {t:.2} {g:.1?}", kind.name(), hall.rt60_s);
                }
            }
        }
    }
    Ok(())
}
