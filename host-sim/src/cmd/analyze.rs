//! `host-sim analyze`.

/// Arguments of `host-sim analyze`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `host-sim analyze`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`host-sim analyze` is not built yet")
}
