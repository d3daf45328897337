//! `aim`: the host tracker's command line.
use clap::Parser;

/// AIM host tracker.
#[derive(Parser)]
#[command(version, about)]
struct Cli {}

fn main() -> anyhow::Result<()> {
    let _cli = Cli::parse();
    Ok(())
}
