//! `rigmon watch` (placeholder until its owner fills it in).

/// Arguments of `rigmon watch`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon watch is not implemented yet")
}
