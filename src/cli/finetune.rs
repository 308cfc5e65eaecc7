//! `rigmon finetune` (placeholder until its owner fills it in).

/// Arguments of `rigmon finetune`.
#[derive(clap::Args, Debug)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("rigmon finetune is not implemented yet")
}
