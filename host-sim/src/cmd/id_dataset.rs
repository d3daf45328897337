//! `host-sim id-dataset --out DIR`: writes a labelled dataset of simulated recordings for
//! `aim id train` / `aim id eval`, one folder per class (six drone types and `none`), one WAV
//! per clip ([`host_sim::iddata`] says what a clip holds). Use disjoint `--seed` ranges for
//! training and evaluation sets: clip i of every class has seed `--seed + i`.
use std::path::PathBuf;

use host_sim::iddata::{self, Options, SampleFormat};

/// Arguments of `host-sim id-dataset`.
#[derive(clap::Args)]
pub struct Args {
    /// Folder to write (created; one subfolder per class).
    #[arg(long)]
    out: PathBuf,
    /// Clips per class.
    #[arg(long, default_value_t = 100)]
    clips: usize,
    /// First clip seed (clips use seeds SEED ..< SEED + CLIPS).
    #[arg(long, default_value_t = 1000)]
    seed: u64,
    /// Clip length, s.
    #[arg(long, default_value_t = 1.0)]
    secs: f64,
    /// Sample rate, Hz (16000 as a phone or a recorder, 48000 as the array).
    #[arg(long, default_value_t = 16_000)]
    rate: u32,
    /// Channels per file (extra channels: the same sound plus microphone self-noise).
    #[arg(long, default_value_t = 1)]
    channels: u16,
    /// Sample format.
    #[arg(long, value_enum, default_value_t = SampleFormat::I16)]
    format: SampleFormat,
    /// Nearest drone distance, m.
    #[arg(long, default_value_t = 3.0)]
    min_distance: f64,
    /// Farthest drone distance, m.
    #[arg(long, default_value_t = 15.0)]
    max_distance: f64,
    /// Quietest background, dB SPL.
    #[arg(long, default_value_t = 55.0)]
    min_background: f64,
    /// Loudest background, dB SPL.
    #[arg(long, default_value_t = 70.0)]
    max_background: f64,
    /// Probability of a second tonal source in a drone clip.
    #[arg(long, default_value_t = 0.3)]
    second_source: f64,
    /// Write only this class (repeatable; default all); its clips are those of the full set.
    #[arg(long = "class")]
    class: Vec<String>,
}

/// Writes the dataset and prints one line per class.
pub fn run(args: Args) -> anyhow::Result<()> {
    let o = Options {
        clips_per_class: args.clips,
        seed_base: args.seed,
        secs: args.secs,
        rate_hz: args.rate,
        channels: args.channels,
        format: args.format,
        distance_m: (args.min_distance, args.max_distance),
        background_db: (args.min_background, args.max_background),
        second_source_probability: args.second_source,
        only: args.class,
    };
    for (class, files) in iddata::write_dataset(&args.out, &o)? {
        println!("{class}: {} clips in {}", files.len(), args.out.join(&class).display());
    }
    Ok(())
}
