//! `host-sim simulate`: run a scenario and write the recordings, the truth and the site file.
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
}

/// Runs `host-sim simulate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let scenario = Scenario::load(&args.scenario)?;
    let progress = host_sim::progress_bar("simulating");
    let sim =
        host_sim::simulate_with(&scenario, &host_sim::Options { threads: args.threads }, &progress)
            .with_context(|| format!("simulating {}", args.scenario.display()))?;
    sim.write(&args.out)?;
    eprintln!(
        "{}: {:.1} s, {} array(s) → {}",
        scenario.name,
        scenario.duration_s,
        sim.arrays.len(),
        args.out.display()
    );
    Ok(())
}
