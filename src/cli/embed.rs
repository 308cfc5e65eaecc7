//! `rigmon embed` (placeholder until its owner fills it in).

/// Arguments of `rigmon embed`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon embed is not implemented yet")
}
