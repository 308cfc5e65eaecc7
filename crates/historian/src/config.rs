//! The historian's configuration file (`config/historian.toml`): which database (named the
//! way psql names it), the Zenoh session (the daemon's `[zenoh]` section, access control
//! included), the buffer and its spill folder, batching, retention, recovery and history
//! answers. Unknown keys are refused with their name and line; relative paths are relative
//! to the file's folder (the spill folder: to `$STATE_DIRECTORY` under systemd).

use super::database::DatabaseSettings;
use anyhow::{bail, Context, Result};
use rigmon_core::config::resolve_relative;
use rigmon_core::vocabulary::ZenohMode;
use rigmon_runtime::publish::zenoh::ZenohSettings;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole `historian.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistorianConfig {
    /// This historian's name (its status key `<prefix>/@historian/<name>/status`).
    #[serde(default = "default_name")]
    pub name: String,
    /// Site for machines whose rig file names none (`[machine] site`).
    #[serde(default = "default_site")]
    pub default_site: String,
    #[serde(default)]
    pub database: DatabaseSettings,
    #[serde(default = "client_zenoh")]
    pub zenoh: ZenohSettings,
    #[serde(default)]
    pub intake: IntakeSettings,
    #[serde(default)]
    pub buffer: BufferSettings,
    #[serde(default)]
    pub batch: BatchSettings,
    #[serde(default)]
    pub retention: RetentionSettings,
    #[serde(default)]
    pub recovery: RecoverySettings,
    #[serde(default)]
    pub history: HistorySettings,
    /// Seconds between status messages.
    #[serde(default = "default_status_every")]
    pub status_every_s: f64,
}

/// `[intake]`: what a message must be to be taken at all (see `historian::admit`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntakeSettings {
    /// A window may end (and be published) at most this long after the historian's clock;
    /// later ones are refused and counted (a daemon's clock ahead, a forged date).
    #[serde(default = "default_max_future_s")]
    pub max_future_s: f64,
    /// Larger messages are refused and counted before they are buffered (a health message
    /// is 1-4 KB).
    #[serde(default = "default_max_message_kb")]
    pub max_message_kb: f64,
}

/// `[buffer]`: what is held while the database is down or slow.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BufferSettings {
    /// Messages held in memory before new ones go to the spill folder.
    #[serde(default = "default_memory_messages")]
    pub memory_messages: usize,
    /// ...and at most this many MB of them (whichever is reached first).
    #[serde(default = "default_memory_mb")]
    pub memory_mb: f64,
    /// The spill folder (segment files; what is in it survives a historian restart).
    #[serde(default = "default_spill_dir")]
    pub spill_dir: PathBuf,
    /// Bytes the spill may hold; beyond it new messages are dropped and counted.
    #[serde(default = "default_spill_max_mb")]
    pub spill_max_mb: f64,
}

/// `[batch]`: how rows are grouped into one COPY transaction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BatchSettings {
    /// Rows per transaction at most.
    #[serde(default = "default_max_rows")]
    pub max_rows: usize,
    /// Longest a message waits for its batch to fill, ms.
    #[serde(default = "default_max_delay_ms")]
    pub max_delay_ms: u64,
    /// Message bytes per transaction at most (batching by bytes as well as rows), MB.
    #[serde(default = "default_max_batch_mb")]
    pub max_mb: f64,
    /// Wait for each commit's WAL flush (`true`), or not (`false`, the default: PostgreSQL's
    /// `synchronous_commit = off` for this session only; a database crash may forget the
    /// last ~0.6 s of commits, which the gap tracker asks again of the daemons).
    #[serde(default)]
    pub synchronous_commit: bool,
    /// COPY streams (connections) written at once, each point always on the same one
    /// ([`crate::streams`]): PostgreSQL then works on a batch in several backends.
    #[serde(default = "default_streams")]
    pub streams: usize,
}

/// `[retention]`: partitions older than these are dropped (hourly and at start).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetentionSettings {
    /// Per-window rows (daily partitions).
    #[serde(default = "default_windows_days")]
    pub windows_days: u32,
    /// 1-minute aggregates (monthly partitions).
    #[serde(default = "default_minutes_days")]
    pub minutes_days: u32,
}

/// `[recovery]`: catching up with what was missed from the daemons' recent history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecoverySettings {
    /// Ask the daemons for gaps at all.
    #[serde(default = "yes")]
    pub enabled: bool,
    /// How long to wait for a daemon's answer, s.
    #[serde(default = "default_query_timeout")]
    pub query_timeout_s: f64,
    /// Requests to the daemons' recent history out at once.
    #[serde(default = "default_in_flight")]
    pub in_flight: usize,
    /// Windows one request asks for at most (a point's further gaps wait for its next turn).
    #[serde(default = "default_request_windows")]
    pub max_request_windows: u64,
    /// How long a gap waits for a late (out of order) window before it is asked for, ms.
    #[serde(default = "default_grace_ms")]
    pub grace_ms: u64,
    /// At start, look this far back (s) from each point's newest stored window for holes in
    /// its run and ask the daemons for them (a historian stopped while it was recovering
    /// forgets what it was asking for). 0: no scan. The default spans the daemons' default
    /// recent history (1,200 windows at a 0.5 s hop).
    #[serde(default = "default_hole_scan_s")]
    pub hole_scan_s: f64,
    /// Search the database for holes again after this long (s), when the historian has
    /// caught up (nothing spilled, nothing to ask): a window missing that no gap named is
    /// asked for and counted like any other ([`super::audit`]). 0: only at start.
    #[serde(default = "default_audit_every_s")]
    pub audit_every_s: f64,
}

impl RecoverySettings {
    /// How the recovery plan paces its requests.
    pub fn pacing(&self) -> super::recovery_plan::Pacing {
        super::recovery_plan::Pacing {
            in_flight: self.in_flight,
            max_windows: self.max_request_windows,
            max_ranges: 32,
            grace: std::time::Duration::from_millis(self.grace_ms),
        }
    }
}

/// `[history]`: answering `get` with `_time=[..]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HistorySettings {
    /// Windows one query may return; more is refused with an error reply naming the count.
    #[serde(default = "default_max_replies")]
    pub max_replies: u64,
}

fn default_name() -> String {
    "historian".into()
}
fn default_site() -> String {
    "default".into()
}
fn client_zenoh() -> ZenohSettings {
    ZenohSettings {
        mode: ZenohMode::Client,
        connect: vec!["tcp/127.0.0.1:7447".into()],
        history_windows: 0,
        ..Default::default()
    }
}
fn default_status_every() -> f64 {
    2.0
}
fn default_memory_messages() -> usize {
    20_000
}
fn default_memory_mb() -> f64 {
    256.0
}
fn default_max_future_s() -> f64 {
    300.0
}
fn default_max_message_kb() -> f64 {
    1024.0
}
fn default_spill_dir() -> PathBuf {
    "spill".into()
}
fn default_spill_max_mb() -> f64 {
    1024.0
}
fn default_max_rows() -> usize {
    20000
}
fn default_max_batch_mb() -> f64 {
    32.0
}
fn default_streams() -> usize {
    2
}
fn default_max_delay_ms() -> u64 {
    250
}
fn default_windows_days() -> u32 {
    30
}
fn default_minutes_days() -> u32 {
    3650
}
fn yes() -> bool {
    true
}
fn default_query_timeout() -> f64 {
    10.0
}
fn default_in_flight() -> usize {
    8
}
fn default_request_windows() -> u64 {
    240
}
fn default_grace_ms() -> u64 {
    1000
}
fn default_hole_scan_s() -> f64 {
    600.0
}
fn default_audit_every_s() -> f64 {
    300.0
}
fn default_max_replies() -> u64 {
    200_000
}

impl Default for BufferSettings {
    fn default() -> Self {
        BufferSettings {
            memory_messages: default_memory_messages(),
            memory_mb: default_memory_mb(),
            spill_dir: default_spill_dir(),
            spill_max_mb: default_spill_max_mb(),
        }
    }
}
impl Default for IntakeSettings {
    fn default() -> Self {
        IntakeSettings {
            max_future_s: default_max_future_s(),
            max_message_kb: default_max_message_kb(),
        }
    }
}
impl Default for BatchSettings {
    fn default() -> Self {
        BatchSettings {
            max_rows: default_max_rows(),
            max_delay_ms: default_max_delay_ms(),
            max_mb: default_max_batch_mb(),
            synchronous_commit: false,
            streams: default_streams(),
        }
    }
}
impl Default for RetentionSettings {
    fn default() -> Self {
        RetentionSettings {
            windows_days: default_windows_days(),
            minutes_days: default_minutes_days(),
        }
    }
}
impl Default for RecoverySettings {
    fn default() -> Self {
        RecoverySettings {
            enabled: true,
            query_timeout_s: default_query_timeout(),
            in_flight: default_in_flight(),
            max_request_windows: default_request_windows(),
            grace_ms: default_grace_ms(),
            hole_scan_s: default_hole_scan_s(),
            audit_every_s: default_audit_every_s(),
        }
    }
}
impl Default for HistorySettings {
    fn default() -> Self {
        HistorySettings {
            max_replies: default_max_replies(),
        }
    }
}

impl Default for HistorianConfig {
    fn default() -> Self {
        HistorianConfig {
            name: default_name(),
            default_site: default_site(),
            database: DatabaseSettings::default(),
            zenoh: client_zenoh(),
            intake: IntakeSettings::default(),
            buffer: BufferSettings::default(),
            batch: BatchSettings::default(),
            retention: RetentionSettings::default(),
            recovery: RecoverySettings::default(),
            history: HistorySettings::default(),
            status_every_s: default_status_every(),
        }
    }
}

impl HistorianConfig {
    /// Read, parse, resolve relative paths and validate; errors name the file and the key.
    pub fn load(path: &Path) -> Result<HistorianConfig> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read historian config {}", path.display()))?;
        Self::parse(&text, path).with_context(|| format!("in historian config {}", path.display()))
    }

    /// Parse text read from `path` (relative paths are relative to its folder).
    pub fn parse(text: &str, path: &Path) -> Result<HistorianConfig> {
        let mut c: HistorianConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        c.resolve_paths(path);
        c.validate()?;
        Ok(c)
    }

    fn resolve_paths(&mut self, base_file: &Path) {
        if let Some(p) = &self.database.password_file {
            self.database.password_file = Some(resolve_relative(base_file, p));
        }
        if let Some(p) = &self.zenoh.config_file {
            self.zenoh.config_file = Some(resolve_relative(base_file, p));
        }
        let z = &mut self.zenoh;
        for p in [
            &mut z.auth.users_file,
            &mut z.auth.password_file,
            &mut z.tls.root_ca,
            &mut z.tls.cert,
            &mut z.tls.key,
        ]
        .into_iter()
        .flatten()
        {
            *p = resolve_relative(base_file, p);
        }
        if self.buffer.spill_dir.is_relative() {
            self.buffer.spill_dir = match std::env::var_os("STATE_DIRECTORY") {
                Some(s) => Path::new(s.to_string_lossy().split(':').next().unwrap_or("."))
                    .join(&self.buffer.spill_dir),
                None => resolve_relative(base_file, &self.buffer.spill_dir),
            };
        }
    }

    /// Check the numbers and names; errors name the key.
    pub fn validate(&self) -> Result<()> {
        if self.name.is_empty() || self.name.contains(['/', '*', '$', '#', '?', ' ']) {
            bail!(
                "name = {:?}: a plain word (no / * $ # ? or spaces)",
                self.name
            );
        }
        self.database.validate()?;
        self.zenoh.validate()?;
        if self.buffer.memory_messages == 0 {
            bail!("buffer.memory_messages must be at least 1");
        }
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if !positive(self.buffer.memory_mb) {
            bail!(
                "buffer.memory_mb = {}: must be a positive number of MB",
                self.buffer.memory_mb
            );
        }
        if !(self.intake.max_future_s >= 0.0 && self.intake.max_future_s <= 86_400.0) {
            bail!(
                "intake.max_future_s = {}: seconds a window may be ahead of this clock, 0 to 86400",
                self.intake.max_future_s
            );
        }
        if !(self.intake.max_message_kb >= 1.0 && self.intake.max_message_kb <= 65_536.0) {
            bail!(
                "intake.max_message_kb = {}: 1 to 65536 (a health message is 1-4 KB)",
                self.intake.max_message_kb
            );
        }
        if !(self.buffer.spill_max_mb >= 0.0 && self.buffer.spill_max_mb.is_finite()) {
            bail!(
                "buffer.spill_max_mb = {}: must be >= 0 (0 = no spill)",
                self.buffer.spill_max_mb
            );
        }
        if self.batch.max_rows == 0 || self.batch.max_delay_ms == 0 {
            bail!("batch.max_rows and batch.max_delay_ms must be at least 1");
        }
        if !(1..=16).contains(&self.batch.streams) {
            bail!(
                "batch.streams = {}: between 1 and 16 COPY streams (connections)",
                self.batch.streams
            );
        }
        if !positive(self.batch.max_mb) {
            bail!(
                "batch.max_mb = {}: must be a positive number of MB",
                self.batch.max_mb
            );
        }
        if self.retention.windows_days == 0 || self.retention.minutes_days == 0 {
            bail!("retention.windows_days and retention.minutes_days must be at least 1 (days)");
        }
        if !positive(self.recovery.query_timeout_s) || !positive(self.status_every_s) {
            bail!(
                "recovery.query_timeout_s and status_every_s must be positive numbers of seconds"
            );
        }
        if self.recovery.in_flight == 0 || self.recovery.max_request_windows == 0 {
            bail!("recovery.in_flight and recovery.max_request_windows must be at least 1");
        }
        let scan = self.recovery.hole_scan_s;
        if !(scan.is_finite() && scan >= 0.0) {
            bail!("recovery.hole_scan_s = {scan}: must be 0 (no scan) or a positive number of seconds");
        }
        let every = self.recovery.audit_every_s;
        if !(every.is_finite() && every >= 0.0) {
            bail!("recovery.audit_every_s = {every}: must be 0 (only at start) or a positive number of seconds");
        }
        if self.history.max_replies == 0 {
            bail!("history.max_replies must be at least 1");
        }
        Ok(())
    }

    /// The zenoh config this historian opens its session with, refused when it could receive
    /// nothing (its own access-control list denies every incoming put).
    pub fn zenoh_config(&self) -> Result<zenoh::Config> {
        let c = self.zenoh.zenoh_config()?;
        if let Some(why) =
            rigmon_runtime::publish::access::receives_nothing(&c, &self.zenoh.key_prefix)
        {
            bail!("[zenoh]: this historian would store nothing: {why}");
        }
        Ok(c)
    }

    /// The key this historian publishes its status on.
    pub fn status_key(&self) -> String {
        format!("{}/@historian/{}/status", self.zenoh.key_prefix, self.name)
    }

    /// Memory bytes the buffer may hold.
    pub fn memory_max_bytes(&self) -> u64 {
        (self.buffer.memory_mb * 1024.0 * 1024.0) as u64
    }

    /// Largest message taken, bytes.
    pub fn max_message_bytes(&self) -> usize {
        (self.intake.max_message_kb * 1024.0) as usize
    }

    /// The admission rules.
    pub fn admission(&self) -> super::admit::Rules {
        super::admit::Rules {
            prefix: self.zenoh.key_prefix.clone(),
            max_future_ns: (self.intake.max_future_s * 1e9) as u64,
        }
    }

    /// Message bytes one batch may hold.
    pub fn batch_max_bytes(&self) -> u64 {
        (self.batch.max_mb * 1024.0 * 1024.0) as u64
    }

    /// Spill bytes allowed.
    pub fn spill_max_bytes(&self) -> u64 {
        (self.buffer.spill_max_mb * 1024.0 * 1024.0) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_example_parses_and_unknown_keys_are_named() {
        let p =
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/historian.toml");
        let text = std::fs::read_to_string(&p).unwrap();
        let c = HistorianConfig::parse(&text, &p).unwrap();
        assert_eq!(c.zenoh.mode, ZenohMode::Client);
        assert!(!c.zenoh.multicast_scouting);
        assert!(c
            .zenoh
            .connect
            .iter()
            .all(|e| e.starts_with("tcp/127.0.0.1:")));
        let bad = text.replacen("[batch]", "[batch]\nmax_rowz = 3", 1);
        let e = format!("{:#}", HistorianConfig::parse(&bad, &p).unwrap_err());
        assert!(e.contains("max_rowz") && e.contains("line"), "{e}");
    }
}
