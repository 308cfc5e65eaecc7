//! `rigmon bench <what>`: run one of the built-in benchmarks (see `rigmon::bench`).

use crate::bench::{self, BenchOptions};
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum What {
    /// Envelope-order-spectrum features: channel-seconds per wall-second, one core.
    Features,
    /// Simulator: wall time for 10 s of signal vs the thesis' MSC Adams run.
    Simulate,
    /// Daemon footprint at the rig's rate: CPU share, RSS, publish latency.
    Footprint,
}

/// Arguments of `rigmon bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Which benchmark to run.
    #[arg(value_enum)]
    pub what: What,
    /// Rig file (default depends on the benchmark).
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Measuring time in seconds.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = BenchOptions {
        rig: args.rig,
        seconds: args.seconds,
        json: args.json,
    };
    match args.what {
        What::Features => bench::features::run(&opts),
        What::Simulate => bench::simulate::run(&opts),
        What::Footprint => bench::footprint::run(&opts),
    }
}
