//! `rigmon train` (placeholder until its owner fills it in).

/// Arguments of `rigmon train`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon train is not implemented yet")
}
