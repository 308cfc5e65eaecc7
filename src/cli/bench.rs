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
    /// Sustained load: 16 ch x 51.2 kHz through the whole pipeline as fast as it goes.
    Load,
    /// Calibration of six recordings analysed whole, against the same calibration before.
    Calibrate,
    /// Speed from the vibration: the tracker's cost per hop at 3 ch x 10 kHz and
    /// 1 ch x 51.2 kHz against the same analysis with the true speed (--seconds of signal,
    /// default 30).
    Speed,
    /// Fleet historian: --points simulated points at 2 windows/s through a router into the
    /// PostgreSQL named by the PG* variables.
    Historian,
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
    /// Measuring time in seconds (default 60 for `load` and `historian`, 10 for the others).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// `calibrate` only: measured recordings (a labels.csv); default: the independent
    /// generator's speed_fluctuation case, six recordings of 20 s.
    #[arg(long)]
    pub measured: Option<PathBuf>,
    /// `historian` only: simulated points.
    #[arg(long, default_value_t = 1000)]
    pub points: usize,
    /// `historian` only: the historian's COPY streams (`[batch] streams`).
    #[arg(long, default_value_t = 2)]
    pub streams: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = BenchOptions {
        rig: args.rig,
        seconds: args.seconds.unwrap_or(match args.what {
            What::Load | What::Historian => 60.0,
            What::Speed => 30.0,
            _ => 10.0,
        }),
        json: args.json,
    };
    match args.what {
        What::Features => bench::features::run(&opts),
        What::Simulate => bench::simulate::run(&opts),
        What::Footprint => bench::footprint::run(&opts),
        What::Load => bench::load::run(&opts),
        What::Calibrate => bench::calibrate::run(&opts, args.measured, args.seconds),
        What::Speed => bench::speed::run(&opts),
        What::Historian => {
            bench::historian::run(args.points, args.streams, opts.seconds, opts.json)
        }
    }
}
