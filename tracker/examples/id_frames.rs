//! The comb features of the `Mfcc` frames the chip would send for recordings (diagnostic, not
//! part of the product): `cargo run --release -p aim-tracker --example id_frames -- WAV...`.
//! Per recording: its frames, their mean salience (dB) and the share of frames whose comb
//! fundamental lies in `LO..HI` Hz (environment variables, default 450–1100, the 70 g toy's
//! BPF under manoeuvres); with `V=1` every frame's fundamental, salience, half- and
//! third-way levels and harmonic envelope.
use std::io::Write;

use aim_tracker::id::{audio, chip};

fn main() -> anyhow::Result<()> {
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let (lo, hi) = (env("LO", 450.0), env("HI", 1100.0));
    let verbose = std::env::var_os("V").is_some();
    let mut out = std::io::stdout().lock();
    for p in std::env::args().skip(1) {
        let (x, rate) = audio::read_mono(std::path::Path::new(&p))?;
        let frames = chip::frames_of_recording(&x, rate)?;
        let values: Vec<_> = frames.iter().map(|(_, f)| f.harmonic_values()).collect();
        let hz = |h: &[f32]| 250.0 * h[0].exp2();
        let n = values.len().max(1) as f32;
        let salience = values.iter().map(|h| h[1]).sum::<f32>() / n;
        let inside = values.iter().filter(|h| (lo..hi).contains(&hz(&h[..]))).count() as f32 / n;
        writeln!(
            out,
            "{p} frames {} mean_salience_db {salience:.2} f0_in_range {inside:.2}",
            values.len()
        )?;
        if verbose {
            for h in &values {
                writeln!(
                    out,
                    "  f0 {:7.1} Hz salience {:5.2} half {:5.2} third {:5.2} envelope {:?}",
                    hz(&h[..]),
                    h[1],
                    h[2],
                    h[3],
                    &h[4..]
                )?;
            }
        }
    }
    Ok(())
}
