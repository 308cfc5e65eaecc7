//! `rigmon features` (placeholder until its owner fills it in).

/// Arguments of `rigmon features`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon features is not implemented yet")
}
