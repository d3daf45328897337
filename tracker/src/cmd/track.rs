//! `aim track`.

/// Arguments of `aim track`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `aim track`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`aim track` is not built yet")
}
