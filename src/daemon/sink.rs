//! What a sink is, as vector has it: each sink is built from its own config section
//! ([`SinkConfig::build`]) and then handed, by the pipeline, the raw blocks, each window's
//! results, the status messages and the running config ([`Sink`]). [`Sinks`] is the set a
//! daemon runs, in this order: stdout, Zenoh, recording.

use super::config::DaemonConfig;
use super::intake::SourceInfo;
use super::queued_sink::Delivery;
use super::status::{SinkStatus, StatusMessage};
use super::stdout_sink::Output;
use crate::acquire::SampleBlock;
use crate::config::RigConfig;
use crate::dsp::features::FeatureWindow;
use crate::health::message::HealthMessage;
use crate::publish::zenoh::PublishStats;
use crate::recorder::RecordStats;
use anyhow::Result;
use std::sync::Arc;
use std::time::Duration;

/// What every sink may look at while it is built.
pub struct SinkContext<'a> {
    pub rig: &'a RigConfig,
    /// The whole daemon config as started (sinks read their own section and `[pipeline]`).
    pub config: &'a DaemonConfig,
    pub source: &'a SourceInfo,
    /// Time of the run's start, ns since the Unix epoch.
    pub start_ns: u64,
    /// What queued sinks do when full.
    pub delivery: Delivery,
    /// Before the pipeline starts, wait up to this long for a health subscriber.
    pub wait_for_subscriber: Option<Duration>,
}

/// A sink's own config section: builds the sink, or nothing when the section turns it off.
pub trait SinkConfig {
    fn build(&self, cx: &SinkContext) -> Result<Option<Box<dyn Sink>>>;
}

/// One window's results, as every sink sees them.
pub struct WindowEvent<'a> {
    pub health: &'a HealthMessage,
    /// `health` as JSON, serialised once for all sinks.
    pub health_json: &'a [u8],
    /// The features (None when the window could not be computed).
    pub features: Option<&'a FeatureWindow>,
}

/// Counters the sinks report for the status message and the summary.
#[derive(Debug, Clone, Default)]
pub struct SinkReport {
    pub dropped: SinkStatus,
    pub publish: Option<PublishStats>,
    pub recording: Option<RecordStats>,
}

/// Where the pipeline's output goes.
pub trait Sink {
    /// Raw samples as they arrive (shared, not copied).
    fn on_block(&mut self, _block: &Arc<SampleBlock>) {}
    /// One window's health message and features.
    fn on_window(&mut self, window: &WindowEvent);
    /// A status message (every `pipeline.status_every_s`, and a last one at the end).
    fn on_status(&mut self, _status: &StatusMessage) {}
    /// The running config after a SIGHUP reload brought a new one.
    fn on_config(&mut self, _config: &DaemonConfig) {}
    /// Add this sink's counters.
    fn report(&self, _into: &mut SinkReport) {}
    /// Drain and close (the files, the session).
    fn close(self: Box<Self>);
}

/// The sinks a daemon runs.
pub struct Sinks(Vec<Box<dyn Sink>>);

impl Sinks {
    /// Build every sink its config turns on: stdout (`output`), `[zenoh]`, `[recording]`.
    pub fn build(cx: &SinkContext, output: Output) -> Result<Sinks> {
        let configs: [&dyn SinkConfig; 3] = [&output, &cx.config.zenoh, &cx.config.recording];
        let mut sinks = Vec::new();
        for c in configs {
            sinks.extend(c.build(cx)?);
        }
        Ok(Sinks(sinks))
    }

    pub fn on_block(&mut self, block: &Arc<SampleBlock>) {
        self.0.iter_mut().for_each(|s| s.on_block(block));
    }

    pub fn on_window(&mut self, window: &WindowEvent) {
        self.0.iter_mut().for_each(|s| s.on_window(window));
    }

    pub fn on_status(&mut self, status: &StatusMessage) {
        self.0.iter_mut().for_each(|s| s.on_status(status));
    }

    pub fn on_config(&mut self, config: &DaemonConfig) {
        self.0.iter_mut().for_each(|s| s.on_config(config));
    }

    pub fn report(&self) -> SinkReport {
        let mut r = SinkReport::default();
        self.0.iter().for_each(|s| s.report(&mut r));
        r
    }

    /// Close every sink, in order.
    pub fn close(self) {
        self.0.into_iter().for_each(|s| s.close());
    }
}
