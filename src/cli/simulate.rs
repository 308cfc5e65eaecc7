//! `rigmon simulate` (placeholder until its owner fills it in).

/// Arguments of `rigmon simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon simulate is not implemented yet")
}
