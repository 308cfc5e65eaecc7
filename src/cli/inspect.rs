//! `rigmon inspect` (placeholder until its owner fills it in).

/// Arguments of `rigmon inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon inspect is not implemented yet")
}
