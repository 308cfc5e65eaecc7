//! `rigmon replay` (placeholder until its owner fills it in).

/// Arguments of `rigmon replay`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon replay is not implemented yet")
}
