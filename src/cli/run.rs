//! `rigmon run` (placeholder until its owner fills it in).

/// Arguments of `rigmon run`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon run is not implemented yet")
}
