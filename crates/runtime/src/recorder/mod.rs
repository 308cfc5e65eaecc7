//! Recording sink: what the daemon saw, to MCAP with zstd chunks, rotated by size and time.
//! One file per segment, `<stem>-<UTC stamp>.mcap`, holding
//! - the raw samples in the rigmon layout ([`crate::recording::mcap`], layout_version 1,
//!   written with the importers' streaming writer), so `rigmon replay` and every importer read
//!   it as before;
//! - features (`/features`) and health (`/health`) as JSON messages (schema encoding
//!   `jsonschema`, message encoding `json`) in the same chunks; readers of the raw layout skip
//!   these channels.
//!
//! The file is created at the segment's first block (its start time is that sample's time);
//! with `raw = false` it is a plain MCAP of the two JSON channels. Chunks are closed every
//! `flush_s` seconds (and at `chunk_kb`), and after each the file is a complete MCAP, so after
//! a kill -9 everything up to the last flush reads back, with any MCAP reader; SIGTERM
//! finishes the file cleanly (summary, footer). A segment is closed before it would pass
//! `max_file_mb`. Write errors (disk full: ENOSPC, EDQUOT, EFBIG; a folder that cannot be
//! created) are counted, reported as `failed` in the status, and retried with a new segment
//! after `retry_s`; the failed segment is cut back to its last complete chunk, or removed when
//! it has none. They never stop monitoring.

pub mod mcap;

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

pub use self::mcap::{RecordEvent, Recorder};

/// `[recording]` section of the daemon config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordConfig {
    #[serde(default)]
    pub enabled: bool,
    /// Folder for the segments (relative: under `$STATE_DIRECTORY`, else the config's folder).
    #[serde(default = "default_dir")]
    pub dir: PathBuf,
    /// Start a new segment when the raw file reaches this size, MB.
    #[serde(default = "default_max_mb")]
    pub max_file_mb: f64,
    /// Start a new segment after this many seconds.
    #[serde(default = "default_max_s")]
    pub max_file_s: f64,
    /// Close the current chunk at least this often (bounds the loss on a crash), s.
    #[serde(default = "default_flush_s")]
    pub flush_s: f64,
    /// Uncompressed bytes per MCAP chunk.
    #[serde(default = "default_chunk_kb")]
    pub chunk_kb: u64,
    /// After a write error, wait this long before trying a new segment, s.
    #[serde(default = "default_retry_s")]
    pub retry_s: f64,
    /// What to record.
    #[serde(default = "yes")]
    pub raw: bool,
    #[serde(default = "yes")]
    pub features: bool,
    #[serde(default = "yes")]
    pub health: bool,
}

fn default_dir() -> PathBuf {
    PathBuf::from("recordings")
}
fn default_max_mb() -> f64 {
    256.0
}
fn default_max_s() -> f64 {
    3600.0
}
fn default_flush_s() -> f64 {
    2.0
}
fn default_chunk_kb() -> u64 {
    1024
}
fn default_retry_s() -> f64 {
    5.0
}
fn yes() -> bool {
    true
}

impl Default for RecordConfig {
    fn default() -> Self {
        RecordConfig {
            enabled: false,
            dir: default_dir(),
            max_file_mb: default_max_mb(),
            max_file_s: default_max_s(),
            flush_s: default_flush_s(),
            chunk_kb: default_chunk_kb(),
            retry_s: default_retry_s(),
            raw: true,
            features: true,
            health: true,
        }
    }
}

impl RecordConfig {
    pub fn validate(&self) -> Result<()> {
        for (k, v) in [
            ("max_file_mb", self.max_file_mb),
            ("max_file_s", self.max_file_s),
            ("flush_s", self.flush_s),
            ("retry_s", self.retry_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                bail!("recording.{k} = {v}: must be a positive number");
            }
        }
        if self.chunk_kb == 0 || self.chunk_kb > 1 << 20 {
            bail!(
                "recording.chunk_kb = {}: must be between 1 and 1048576",
                self.chunk_kb
            );
        }
        if self.enabled && !(self.raw || self.features || self.health) {
            bail!("recording.enabled = true but raw, features and health are all false; record something or disable recording");
        }
        Ok(())
    }
}
