//! `host-sim simulate`.

/// Arguments of `host-sim simulate`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `host-sim simulate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`host-sim simulate` is not built yet")
}
