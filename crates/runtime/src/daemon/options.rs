//! How to run the daemon: the config plus what the caller decides (`rigmon run`, `rigmon
//! replay`, benchmarks and tests): stdout output, waiting for a subscriber, lossless sinks,
//! signals, and a stop flag for library callers.

use super::config::DaemonConfig;
use super::signals;
use super::stdout_sink::Output;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// How to run the daemon.
pub struct DaemonOptions {
    pub config: DaemonConfig,
    /// The file `config` came from (re-read on SIGHUP); None for `rigmon replay`.
    pub config_path: Option<PathBuf>,
    pub output: Output,
    /// Before starting the pipeline, wait up to this long for a health subscriber.
    pub wait_for_subscriber: Option<Duration>,
    /// Sinks wait instead of dropping when their queue is full (replays).
    pub lossless: bool,
    /// React to SIGTERM/SIGINT/SIGHUP (the CLI); tests driving the library use `stop`.
    pub use_signals: bool,
    /// Stop flag for library callers.
    pub stop: Arc<AtomicBool>,
}

impl DaemonOptions {
    pub fn new(config: DaemonConfig) -> Self {
        DaemonOptions {
            config,
            config_path: None,
            output: Output::None,
            wait_for_subscriber: None,
            lossless: false,
            use_signals: false,
            stop: Arc::default(),
        }
    }

    /// A stop was asked for (the stop flag, or SIGTERM/SIGINT when signals are on).
    pub fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst) || (self.use_signals && signals::stop_requested())
    }

    /// SIGHUP came since the last call (signals on).
    pub fn reload_requested(&self) -> bool {
        self.use_signals && signals::take_reload()
    }
}
