//! `host-sim simulate`: run a scenario and write the recordings, the truth and the site file.
//!
//! The audio is written to disk block by block as it is rendered
//! ([`host_sim::write_streamed`]), so memory does not grow with the duration but for the flight
//! log and the truth; a scenario whose simulation would still need more memory than
//! `--max-memory-mb` is refused before anything is computed, with the estimate
//! ([`Scenario::memory_estimate_bytes`]). A recording with a sample that is not finite is never
//! written. Ctrl-C or SIGTERM stops the run within a block, removes the unfinished
//! `array-<id>.wav.part` files and exits with status 130.
use std::path::PathBuf;

use anyhow::Context as _;

use host_sim::scenario::Scenario;

/// Arguments of `host-sim simulate`.
#[derive(clap::Args)]
pub struct Args {
    /// Scenario file (TOML), e.g. `host-sim/scenarios/square10-los.toml`.
    scenario: PathBuf,
    /// Output directory: `array-<id>.wav`, `truth.csv`, `site.toml`.
    #[arg(long)]
    out: PathBuf,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Refuse scenarios whose simulation needs more memory than this, MB (1 MB = 10⁶ bytes).
    #[arg(long, default_value_t = 4000)]
    max_memory_mb: u64,
}

/// Refuses `scenario` when its estimated memory exceeds `max_mb`.
pub fn check_memory(scenario: &Scenario, max_mb: u64) -> anyhow::Result<()> {
    let need_mb = scenario.memory_estimate_bytes().div_ceil(1_000_000);
    if need_mb > max_mb {
        anyhow::bail!(
            "{}: simulating {:.0} s needs about {need_mb} MB of memory, more than \
             --max-memory-mb {max_mb}; shorten duration_s, use fewer arrays or noise \
             directions, or raise the limit",
            scenario.name,
            scenario.duration_s
        );
    }
    Ok(())
}

/// Runs `host-sim simulate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let scenario = Scenario::load(&args.scenario)?;
    check_memory(&scenario, args.max_memory_mb)?;
    let progress = host_sim::progress_bar("simulating");
    let stop = aim_tracker::link::serial::interrupt_flag()?;
    let sim = host_sim::write_streamed(
        &scenario,
        &host_sim::Options { threads: args.threads },
        &progress,
        &args.out,
        Some(&stop),
    )
    .with_context(|| format!("simulating {}", args.scenario.display()))?;
    eprintln!(
        "{}: {:.1} s, {} array(s) → {}",
        scenario.name,
        scenario.duration_s,
        sim.arrays.len(),
        args.out.display()
    );
    Ok(())
}
