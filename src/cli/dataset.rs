//! `rigmon dataset` (placeholder until its owner fills it in).

/// Arguments of `rigmon dataset`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon dataset is not implemented yet")
}
