//! The set of sinks a daemon runs, built from config in this order: stdout, `[zenoh]`,
//! `[recording]`; each event from the pipeline goes to every sink.

use super::config::DaemonConfig;
use super::sink::{Sink, SinkConfig, SinkContext, SinkReport, WindowEvent};
use super::stdout_sink::Output;
use crate::acquire::SampleBlock;
use crate::wire::status::StatusMessage;
use anyhow::Result;
use std::sync::Arc;

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
