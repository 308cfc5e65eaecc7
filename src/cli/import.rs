//! `rigmon import` (placeholder until its owner fills it in).

/// Arguments of `rigmon import`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon import is not implemented yet")
}
