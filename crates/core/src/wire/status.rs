//! The status message (`rigmon/<rig>/<asset>/<point>/status`, JSON, schema `rigmon.status`
//! version 1; the daemon fills it, `watch`, the historian and `history` read it): what the daemon is doing and everything it counted — source trouble (bad
//! frames, sequence gaps, reconnects), samples lost or dropped because processing fell
//! behind, sink drops, reloads, recording errors, and each window's latency budget (what it
//! waited for after its end, in parts: [`WindowBudget`]).

use crate::vocabulary::SpeedSourceKind;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

pub const SCHEMA: &str = "rigmon.status";
pub const SCHEMA_VERSION: u32 = 1;

/// Life-cycle phase of the daemon.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    Starting,
    Running,
    Reloading,
    Stopping,
    Finished,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StatusMessage {
    pub schema: String,
    pub schema_version: u32,
    pub rig: String,
    pub asset: String,
    pub point: String,
    pub time_ns: u64,
    pub uptime_s: f64,
    pub phase: Phase,
    pub software_version: String,
    pub source: SourceStatus,
    pub pipeline: PipelineStatus,
    pub model: ModelStatus,
    pub sinks: SinkStatus,
    pub publish: Option<PublishStats>,
    pub recording: Option<RecordStats>,
    /// Last health state, for a quick look.
    pub state: Option<String>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SourceStatus {
    pub describe: String,
    pub connected: bool,
    pub blocks: u64,
    pub samples: u64,
    pub bad_frames: u64,
    pub sequence_gaps: u64,
    /// Samples the source knows it lost (gaps, or dropped because the pipeline queue was full).
    pub samples_lost: u64,
    pub reconnects: u64,
    /// The source ended (end of file) or failed; `error` says why when it failed.
    pub finished: bool,
    pub error: Option<String>,
    /// What a replayed recording could not deliver (damaged chunks, gaps, a cut tail).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file_losses: Option<crate::recording::LossReport>,
}

impl StatusMessage {
    /// One status line for systemd (`systemctl status`).
    pub fn systemd_line(&self) -> String {
        format!(
            "{}: state {} | {} windows | source {} lost {} bad frames {} | model {}{}{}",
            match self.phase {
                Phase::Running => "running",
                Phase::Reloading => "reloading",
                Phase::Stopping => "stopping",
                Phase::Starting => "starting",
                Phase::Finished => "finished",
            },
            self.state.as_deref().unwrap_or("-"),
            self.pipeline.windows,
            if self.source.connected {
                "connected"
            } else {
                "disconnected"
            },
            self.source.samples_lost + self.pipeline.samples_lost,
            self.source.bad_frames,
            self.model.id,
            if self.pipeline.behind {
                " | BEHIND"
            } else {
                ""
            },
            match self.recording.as_ref().and_then(|r| r.failed.as_deref()) {
                Some(why) => format!(" | RECORDING FAILED: {why}"),
                None => String::new(),
            }
        )
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PipelineStatus {
    pub windows: u64,
    pub samples_in: u64,
    /// Samples missing on the sample clock as seen by the windower.
    pub samples_lost: u64,
    pub gaps: u64,
    pub restarts: u64,
    /// Captures started, when the source is a series of periodic captures (the time between
    /// them is neither lost nor a gap).
    #[serde(default)]
    pub captures: u64,
    /// Windows whose features or inference failed (counted, skipped).
    pub window_errors: u64,
    /// True while processing is behind real time (the source is dropping or the lag grows).
    pub behind: bool,
    /// Seconds of signal between the newest sample received and the last window computed.
    pub lag_s: f64,
    /// Block completing a window in -> health handed to the sinks, ms (last and max).
    pub latency_ms_last: f64,
    pub latency_ms_max: f64,
    /// The last window's latency budget.
    #[serde(default)]
    pub last_window: WindowBudget,
    /// The most signal past a window's end that had arrived when it was analysed, ms, over
    /// all windows so far (see [`WindowBudget::after_end_ms`]).
    #[serde(default)]
    pub after_end_ms_max: f64,
}

/// How long after its end a window's health left, in parts. The analysis waits for no signal
/// past a window's end, whatever its speed source: a fixed, stored or estimated speed needs
/// nothing more, and a tacho's speed is extrapolated past the last edge inside the window. So
/// a window's health leaves `after_end_ms + processing_ms` after its end (plus the source's
/// own delivery delay, which the daemon cannot see).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WindowBudget {
    /// Window end, s on the pipeline clock.
    pub end_s: f64,
    /// Where its speed came from.
    pub speed_source: SpeedSourceKind,
    /// Signal past the window's end that had arrived when it was analysed, ms: the rest of
    /// the block completing it (the source's block size sets it; 0 when blocks end on window
    /// ends), or more if the pipeline fell behind.
    pub after_end_ms: f64,
    /// The block completing the window arrived -> health handed to the sinks, ms.
    pub processing_ms: f64,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelStatus {
    pub id: String,
    pub sha256: String,
    pub reloads: u64,
    pub reloads_rejected: u64,
    pub last_reload_error: Option<String>,
}

/// Messages dropped because a sink's queue was full.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SinkStatus {
    pub zenoh_dropped: u64,
    pub record_dropped: u64,
}

/// Counters of the publisher (reported in the status topic).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PublishStats {
    pub health: u64,
    pub spectrum: u64,
    pub status: u64,
    pub errors: u64,
    pub queries_answered: u64,
    /// Other daemons that appeared publishing under this daemon's base key (the same machine
    /// id, asset and point) since it started.
    #[serde(default)]
    pub duplicates: u64,
}

/// Counters of the recorder (reported in the status topic).
#[derive(Debug, Default, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordStats {
    pub segments: u64,
    pub blocks: u64,
    pub messages: u64,
    pub write_errors: u64,
    /// The last write failed for lack of space (ENOSPC, EDQUOT or EFBIG).
    pub disk_full: bool,
    pub last_error: Option<String>,
    /// Set when a write failed and cleared once a new segment flushed: `<file>: <reason>`
    /// (reason `disk full` for ENOSPC/EDQUOT/EFBIG), for the status topic and systemd STATUS.
    #[serde(default)]
    pub failed: Option<String>,
    /// Current file.
    pub file: Option<PathBuf>,
    /// Events dropped because the recorder was behind or between segments after an error.
    pub dropped: u64,
    /// Segments removed after a failed write because they held no complete chunk.
    #[serde(default)]
    pub removed_empty: u64,
}
