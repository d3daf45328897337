//! `host-sim`: the acoustic world simulator's command line.
use clap::Parser;

/// AIM acoustic world simulator.
#[derive(Parser)]
#[command(version, about)]
struct Cli {}

fn main() -> anyhow::Result<()> {
    let _cli = Cli::parse();
    Ok(())
}
