//! `rigmon bench simulate` (placeholder until its owner fills it in).

use super::BenchOptions;

pub fn run(_opts: &BenchOptions) -> anyhow::Result<()> {
    anyhow::bail!("rigmon bench simulate is not implemented yet")
}
