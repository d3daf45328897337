//! `aim replay`.

/// Arguments of `aim replay`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `aim replay`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`aim replay` is not built yet")
}
