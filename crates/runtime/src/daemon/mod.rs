//! The daemon as a topology, built from config: source thread -> bounded block queue
//! ([`intake`]) -> [`pipeline`] (rolling windows -> features -> model -> health state
//! machine) -> sinks ([`sink`]: stdout, the Zenoh publisher, the MCAP recorder; the last two
//! each on its own thread behind a bounded queue, [`queued_sink`]). Live sources drop (and
//! count) when the pipeline falls behind; file replays wait. Before anything starts, the
//! checks of [`preflight`] run (the same ones `rigmon run --check` runs). The loop here feeds
//! the pipeline its events: blocks, SIGHUP reloads, ticks and the end.

pub mod analyze;
pub(crate) mod backlog;
pub(crate) mod code_pages;
pub mod config;
pub mod intake;
pub mod latency;
pub mod notify;
pub mod options;
pub mod pipeline;
pub(crate) mod preflight;
pub(crate) mod queued_sink;
pub(crate) mod record_sink;
pub mod reload;
pub mod signals;
pub mod sink;
pub mod sinks;
pub mod source_status;
pub(crate) mod stdout_sink;
pub mod summary;
pub(crate) mod zenoh_sink;

pub use options::DaemonOptions;
pub use stdout_sink::Output;
pub use summary::Summary;

use crate::acquire::{Source, SourceStats};
use anyhow::Result;
use intake::{Intake, Received};
use pipeline::Pipeline;
use std::sync::Arc;
use std::time::Instant;

/// Check everything ([`preflight::preflight`]), build it from the options and run until the
/// source ends or a stop is requested. Problems monitoring survives (a recording folder that
/// cannot be created) are logged and the run goes on.
pub fn run(opts: DaemonOptions) -> Result<Summary> {
    let checked = preflight::preflight(&opts.config)?;
    for p in &checked.problems {
        tracing::error!("{p}");
    }
    run_with_source(opts, checked.source)
}

/// [`run`] with a source built by the caller (benchmarks, tests); `opts.config.source` is
/// then only reported.
pub fn run_with_source(opts: DaemonOptions, source: Box<dyn Source>) -> Result<Summary> {
    let started = Instant::now();
    if opts.use_signals {
        signals::install();
    }
    let stats = Arc::new(SourceStats::default());
    let mut pipeline = Pipeline::build(&opts, source.as_ref(), stats.clone(), started)?;
    let mut intake = Intake::spawn(source, opts.config.pipeline.queue_blocks, stats)?;
    pipeline.ready();
    let mut stopping = false;
    let source_result = loop {
        if !stopping && opts.stop_requested() {
            stopping = true;
            pipeline.on_stop();
            intake.stop();
        }
        if opts.reload_requested() {
            pipeline.request_reload();
        }
        pipeline.poll_reload();
        match intake.receive() {
            Received::Block(block) => pipeline.on_block(block),
            Received::Nothing => {}
            Received::Ended => break intake.join(),
        }
        pipeline.on_tick(intake.backlog(), stopping);
    };
    pipeline.finish(source_result, stopping)
}
