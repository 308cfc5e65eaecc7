//! What a sink is, as vector has it: each sink is built from its own config section
//! ([`SinkConfig::build`]) and then handed, by the pipeline, the raw blocks, each window's
//! results, the status messages and the running config ([`Sink`]). The set a daemon runs is
//! [`super::sinks::Sinks`].

use super::config::DaemonConfig;
use super::intake::SourceInfo;
use super::queued_sink::Delivery;
use crate::acquire::SampleBlock;
use crate::config::RigConfig;
use crate::dsp::features::FeatureWindow;
use crate::wire::health::HealthMessage;
use crate::wire::status::PublishStats;
use crate::wire::status::RecordStats;
use crate::wire::status::{SinkStatus, StatusMessage};
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
