//! `rigmon bench features` (placeholder until its owner fills it in).

use super::BenchOptions;

pub fn run(_opts: &BenchOptions) -> anyhow::Result<()> {
    anyhow::bail!("rigmon bench features is not implemented yet")
}
