//! `aim record`.

/// Arguments of `aim record`.
#[derive(clap::Args)]
pub struct Args {}

/// Runs `aim record`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`aim record` is not built yet")
}
