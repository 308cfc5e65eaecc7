//! `rigmon emulate` (placeholder until its owner fills it in).

/// Arguments of `rigmon emulate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon emulate is not implemented yet")
}
