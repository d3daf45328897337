//! `host-sim simulate`: run a scenario and write the recordings, the truth and the site file.
use std::io::IsTerminal as _;
use std::path::PathBuf;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

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
    let progress = if std::io::stderr().is_terminal() {
        ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    progress.set_style(
        ProgressStyle::with_template("{spinner} simulating [{bar:40}] {percent:>3}% eta {eta}")
            .context("progress template")?
            .progress_chars("=> "),
    );
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
