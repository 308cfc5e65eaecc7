//! The historian's status (`<prefix>/@historian/<name>/status`, JSON, schema
//! `rigmon.historian.status` version 1; the `@` chunk keeps it out of `rigmon/**`): the
//! database connection, what was received, refused (by reason), committed, buffered, spilled,
//! dropped, damaged, rejected, recovered and lost (every lost window by point and seq range),
//! and publish-to-committed latency. Also the
//! systemd STATUS= line.

use super::latency::LatencySummary;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::Mutex;

pub const SCHEMA: &str = "rigmon.historian.status";
pub const SCHEMA_VERSION: u32 = 1;

/// Counters shared by the historian's tasks.
#[derive(Debug, Default)]
pub struct Counters {
    pub received_health: AtomicU64,
    pub received_status: AtomicU64,
    /// Messages that are not health/status JSON (counted, skipped).
    pub rejected: AtomicU64,
    /// Messages refused by admission ([`super::admit`]), by reason.
    pub refused_key: AtomicU64,
    pub refused_name: AtomicU64,
    pub refused_future: AtomicU64,
    pub refused_seq: AtomicU64,
    pub refused_too_large: AtomicU64,
    /// Rows older than the windows retention (never written).
    pub expired: AtomicU64,
    pub committed_rows: AtomicU64,
    /// Rows already in the database (replays, retries, overlaps).
    pub duplicate_rows: AtomicU64,
    pub events: AtomicU64,
    pub batches: AtomicU64,
    pub db_connected: AtomicBool,
    pub db_reconnects: AtomicU64,
    pub schema_version: AtomicI64,
    pub last_commit_ns: AtomicU64,
    pub gaps: AtomicU64,
    /// Missing windows asked of the daemons.
    pub requested: AtomicU64,
    pub recovered: AtomicU64,
    /// Windows missed after the historian knew the point, not recoverable (exact count).
    pub lost: AtomicU64,
    /// Windows from before the historian first saw a point, fetched from the daemon's cache,
    /// and windows after a silent point's newest one fetched when its tail was asked.
    pub backfilled: AtomicU64,
    /// ...and those the daemon did not have (not counted as lost: never seen, or, for a
    /// silent point's tail, never made).
    pub not_backfilled: AtomicU64,
    /// Asked for, then arrived live while the request was out.
    pub late: AtomicU64,
    /// Windows asked again: the daemon still held them (or the query timed out) and their
    /// replies were dropped on the way.
    pub asked_again: AtomicU64,
    /// Searches of the database for holes ([`super::audit`]) ...
    pub audits: AtomicU64,
    /// ... the windows they found missing that no gap had named (asked of the daemons),
    pub audit_found: AtomicU64,
    /// ... and one is running now.
    pub auditing: AtomicBool,
    /// Nanoseconds spent in each step ([`Profile`]).
    pub intake_ns: AtomicU64,
    pub take_ns: AtomicU64,
    pub decode_ns: AtomicU64,
    pub write_ns: AtomicU64,
    pub queries_answered: AtomicU64,
    pub history_rows_sent: AtomicU64,
    pub last_error: Mutex<Option<String>>,
    /// Every window lost, by point and seq range (the buffer enters its drops here too).
    pub losses: std::sync::Arc<super::losses::LossLedger>,
}

impl Counters {
    pub fn add(c: &AtomicU64, n: u64) {
        c.fetch_add(n, Ordering::Relaxed);
    }

    pub fn get(c: &AtomicU64) -> u64 {
        c.load(Ordering::Relaxed)
    }

    /// Add the time since `t0` to a nanosecond counter.
    pub fn time(c: &AtomicU64, t0: std::time::Instant) {
        Counters::add(c, t0.elapsed().as_nanos() as u64);
    }

    /// The profile so far.
    pub fn profile(&self) -> Profile {
        let s = |c: &AtomicU64| Counters::get(c) as f64 / 1e9;
        Profile {
            intake_s: s(&self.intake_ns),
            take_s: s(&self.take_ns),
            decode_s: s(&self.decode_ns),
            write_s: s(&self.write_ns),
        }
    }

    /// The counter of one refusal reason.
    pub fn refused(&self, r: super::admit::Refusal) -> &AtomicU64 {
        use super::admit::Refusal as R;
        match r {
            R::Key => &self.refused_key,
            R::Name => &self.refused_name,
            R::Future => &self.refused_future,
            R::Seq => &self.refused_seq,
            R::TooLarge => &self.refused_too_large,
        }
    }

    pub fn set_error(&self, e: Option<String>) {
        if let Ok(mut g) = self.last_error.lock() {
            *g = e;
        }
    }
}

/// Life-cycle phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    Running,
    Stopping,
    Finished,
}

/// The status message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HistorianStatus {
    pub schema: String,
    pub schema_version: u32,
    pub name: String,
    pub time_ns: u64,
    pub uptime_s: f64,
    pub phase: Phase,
    pub database: DatabaseStatus,
    pub received: Received,
    pub rows: Rows,
    pub buffer: BufferStatus,
    pub recovery: Recovery,
    pub latency: LatencySummary,
    pub history: HistoryAnswers,
    pub software_version: String,
    /// Every window the historian could not keep, by point and seq range
    /// ([`super::losses`]): dropped when memory and spill were full, or missed and no longer
    /// in the daemon's recent history.
    #[serde(default)]
    pub lost: super::losses::LostSummary,
    #[serde(default)]
    pub profile: Profile,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DatabaseStatus {
    /// `user@host:port/db` (never a password).
    pub target: String,
    pub connected: bool,
    pub reconnects: u64,
    pub schema_version: i64,
    pub last_error: Option<String>,
    pub last_commit_ns: u64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Received {
    pub health: u64,
    pub status: u64,
    /// Not health/status JSON, or refused by the database row by row.
    pub rejected: u64,
    /// Refused by admission, by reason (see `historian::admit`).
    #[serde(default)]
    pub refused: Refused,
}

/// Messages refused by admission, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Refused {
    /// Machine, asset or point not those of the key it arrived on.
    pub key: u64,
    /// A name that is no plain Zenoh key chunk.
    pub name: u64,
    /// Dated beyond now + `[intake] max_future_s`.
    pub future: u64,
    /// A `seq` no daemon can have reached (or beyond `int8`).
    pub seq: u64,
    /// Larger than `[intake] max_message_kb`.
    pub too_large: u64,
}

impl Refused {
    pub fn total(&self) -> u64 {
        self.key + self.name + self.future + self.seq + self.too_large
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Rows {
    pub committed: u64,
    pub duplicates: u64,
    pub expired: u64,
    pub events: u64,
    pub batches: u64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct BufferStatus {
    pub memory: u64,
    pub spilled: u64,
    pub spill_bytes: u64,
    pub spilled_total: u64,
    /// Messages dropped because memory and spill were full.
    pub dropped: u64,
    /// Bytes held in memory (bounded by `[buffer] memory_mb`).
    #[serde(default)]
    pub memory_bytes: u64,
    /// Damaged stretches of spill segments skipped on reading (each lost at least one
    /// message), and their bytes.
    #[serde(default)]
    pub spill_damaged: u64,
    #[serde(default)]
    pub spill_damaged_bytes: u64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Recovery {
    pub gaps: u64,
    pub requested: u64,
    pub recovered: u64,
    pub lost: u64,
    pub backfilled: u64,
    pub not_backfilled: u64,
    /// Asked for, then arrived live after all (out of order) while the request was out.
    #[serde(default)]
    pub late: u64,
    /// Windows asked again (the daemon still held them, or the query timed out).
    #[serde(default)]
    pub asked_again: u64,
    /// Windows in the recovery plan not yet asked for, and requests out now.
    #[serde(default)]
    pub waiting: u64,
    #[serde(default)]
    pub in_flight: u64,
    /// Searches of the database for holes ([`super::audit`]), the windows they found missing
    /// that no gap had named (the start-up search's are those a stopped historian left), and
    /// whether one is running now.
    #[serde(default)]
    pub audits: u64,
    #[serde(default)]
    pub audit_found: u64,
    #[serde(default)]
    pub auditing: bool,
}

/// Where the historian's time went (seconds, cumulative; wall time of each step, which on a
/// busy machine includes waiting for a core): the Zenoh callbacks (push into the buffer,
/// memory or spill append), taking batches from the buffer (spill reads), decoding the JSON
/// into rows (with admission and gap tracking), and writing them (COPY, insert, commit: the
/// database's time included).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    pub intake_s: f64,
    pub take_s: f64,
    pub decode_s: f64,
    pub write_s: f64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct HistoryAnswers {
    pub queries: u64,
    pub rows_sent: u64,
}

impl HistorianStatus {
    /// One line for `systemctl status`.
    pub fn systemd_line(&self) -> String {
        format!(
            "{}: db {} | {} rows, {} dup | buffer {} mem {} spilled | {} dropped | {} refused, {} rejected, {} spill damaged | recovered {} lost {} | p99 {:.2} s",
            match self.phase {
                Phase::Running => "running",
                Phase::Stopping => "stopping",
                Phase::Finished => "finished",
            },
            if self.database.connected { "connected" } else { "DOWN" },
            self.rows.committed,
            self.rows.duplicates,
            self.buffer.memory,
            self.buffer.spilled,
            self.buffer.dropped,
            self.received.refused.total(),
            self.received.rejected,
            self.buffer.spill_damaged,
            self.recovery.recovered,
            self.lost.windows,
            self.latency.p99_s
        )
    }
}
