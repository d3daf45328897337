//! `aim frames`.

/// Arguments of `aim frames`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `aim frames`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`aim frames` is not built yet")
}
