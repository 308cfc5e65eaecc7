//! `rigmon evaluate` (placeholder until its owner fills it in).

/// Arguments of `rigmon evaluate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon evaluate is not implemented yet")
}
