//! `host-sim fly`.

/// Arguments of `host-sim fly`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `host-sim fly`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`host-sim fly` is not built yet")
}
