//! Sources: where samples come from (MCAP replay, serial DAQ adapter, CAN adapter, sound
//! card, openDAQ streaming server). Every source runs on its own thread, pushes [`SampleBlock`]s on the sample clock
//! into a bounded channel, and counts what went wrong in [`SourceStats`] instead of failing.
//!
//! [`SourceConfig`] is the `[source]` section of the daemon's configuration: a table tagged
//! by `type` (`file`, `serial`, `can`, `audio`, `opendaq`); [`SourceConfig::build`] checks it against
//! the rig and returns a ready [`Source`], or an error that says what to fix.

pub(crate) mod assembler;
pub mod audio;
pub mod can;
pub mod can_protocol;
pub(crate) mod channel_order;
pub mod emulator;
pub(crate) mod file_replay;
pub mod layout;
pub mod opendaq;
pub mod serial;
pub mod serial_protocol;
pub(crate) mod stream_replay;

use crate::config::{Acquisition, RigConfig};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::TrySendError;
use std::sync::Arc;
use std::time::Duration;

pub use crate::recording::SampleBlock;
pub use assembler::BlockAssembler;
pub use file_replay::{FileReplay, FileSourceConfig, ReplaySpeed};

/// Counters a source keeps while it runs (shared with the status publisher).
#[derive(Debug, Default)]
pub struct SourceStats {
    pub blocks: AtomicU64,
    pub samples: AtomicU64,
    /// Frames rejected (bad CRC, bad length, bad sync).
    pub bad_frames: AtomicU64,
    /// Sequence-number gaps seen.
    pub sequence_gaps: AtomicU64,
    /// Samples known to be lost (gaps on the sample clock).
    pub samples_lost: AtomicU64,
    /// Times the device was lost and reopened.
    pub reconnects: AtomicU64,
    /// Set while the device is connected and delivering.
    pub connected: AtomicBool,
    /// What a recording being replayed could not deliver (damage, gaps, a cut tail).
    pub losses: std::sync::Mutex<Option<crate::recording::LossReport>>,
}

impl SourceStats {
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }
}

/// Cooperative stop flag for source threads.
#[derive(Debug, Clone, Default)]
pub struct StopToken(Arc<AtomicBool>);

impl StopToken {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn stop(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    pub fn is_stopped(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// What a running source sends downstream.
pub type BlockSender = std::sync::mpsc::SyncSender<SampleBlock>;

/// A source of samples. `run` blocks the calling thread until the source ends (end of file)
/// or `stop` is set; recoverable trouble (bad frames, unplugged device) is counted in `stats`
/// and retried, never returned as an error. An `Err` means the source cannot work at all,
/// and says what the user should fix.
pub trait Source: Send {
    /// One line for logs and the status topic ("serial /dev/ttyUSB0 @ 921600").
    fn describe(&self) -> String;
    /// Sample rate the source delivers, Hz.
    fn sample_rate(&self) -> f64;
    /// Whether its blocks carry an analog tacho (`SampleBlock::tacho_analog`), known before
    /// the first block so that what records them is made right once.
    fn analog_tacho(&self) -> bool;
    /// Run until done or stopped.
    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> anyhow::Result<()>;
    /// A nominal shaft speed the source knows before any sample arrives (a recording's stored
    /// rpm, e.g. CWRU's `X<nnn>RPM`), for `speed.source = "recording"`.
    fn nominal_rpm(&self) -> Option<f64> {
        None
    }
    /// Rig acceleration channels this source cannot deliver: their vectors in every block
    /// are NaN (e.g. a CWRU file without the `BA` channel). Consumers should skip them
    /// rather than flag them.
    fn absent_channels(&self) -> Vec<String> {
        Vec::new()
    }
    /// Its blocks are a series of periodic captures (snapshots): a jump of the sample clock
    /// is the time between two captures, not lost samples ([`crate::recording::captures`]).
    fn capture_series(&self) -> bool {
        false
    }
}

/// The `[source]` section of the daemon configuration, tagged by `type`.
///
/// ```toml
/// [source]
/// type = "file"            # or "serial", "can", "audio"
/// path = "replay/outer_race_19.8hz.mcap"
/// speed = 1.0              # real-time factor, or "max"
/// loop = true
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum SourceConfig {
    /// Replay of a recording (MCAP, any-layout .mat, WAV, CSV).
    File(FileSourceConfig),
    /// The serial DAQ adapter ([`serial_protocol`]).
    Serial(serial::SerialSourceConfig),
    /// The CAN adapter ([`can_protocol`]; needs the `can` feature).
    Can(can::CanSourceConfig),
    /// A sound card (needs the `audio` feature).
    Audio(audio::AudioSourceConfig),
    /// An openDAQ LT streaming server (DewesoftX, SIRIUS with openDAQ; [`opendaq`]).
    Opendaq(opendaq::OpendaqSourceConfig),
}

impl SourceConfig {
    /// Check the configuration against the rig and open the source. The error says which
    /// source could not start, why, and what to do about it.
    pub fn build(&self, rig: &RigConfig) -> anyhow::Result<Box<dyn Source>> {
        match self {
            SourceConfig::File(c) => Ok(Box::new(c.open(rig)?)),
            SourceConfig::Serial(c) => c.build(rig),
            SourceConfig::Can(c) => c.build(rig),
            SourceConfig::Audio(c) => c.build(rig),
            SourceConfig::Opendaq(c) => c.build(rig),
        }
    }

    /// Make relative paths in the section relative to the folder of the file it was read
    /// from (`base_file`), as every path in a rigmon config is.
    pub fn resolve_paths(&mut self, base_file: &Path) {
        if let SourceConfig::File(c) = self {
            c.path = crate::config::resolve_relative(base_file, &c.path);
        }
    }

    /// The `type` tag (`file`, `serial`, `can`, `audio`, `opendaq`).
    pub fn kind(&self) -> &'static str {
        match self {
            SourceConfig::File(_) => "file",
            SourceConfig::Serial(_) => "serial",
            SourceConfig::Can(_) => "can",
            SourceConfig::Audio(_) => "audio",
            SourceConfig::Opendaq(_) => "opendaq",
        }
    }
}

/// Sample rate a live source runs at: the source's own setting, else the rig's
/// `acquisition.sample_rate_hz`; an error naming both places when neither is set.
pub fn live_sample_rate(
    own: Option<f64>,
    acquisition: &Acquisition,
    kind: &str,
) -> anyhow::Result<f64> {
    let fs = own.or(acquisition.sample_rate_hz).ok_or_else(|| {
        anyhow::anyhow!(
            "{kind} source: no sample rate; set `sample_rate_hz` in the [source] section or `acquisition.sample_rate_hz` in the rig file"
        )
    })?;
    if !(fs.is_finite() && fs > 0.0) {
        anyhow::bail!("{kind} source: sample_rate_hz = {fs} must be a positive number");
    }
    Ok(fs)
}

/// Send a block, waiting while the channel is full (for sources that must not lose data,
/// like file replay). Returns `false` when the receiver is gone or `stop` was set.
pub fn send_block(tx: &BlockSender, mut block: SampleBlock, stop: &StopToken) -> bool {
    loop {
        match tx.try_send(block) {
            Ok(()) => return true,
            Err(TrySendError::Disconnected(_)) => return false,
            Err(TrySendError::Full(b)) => {
                if stop.is_stopped() {
                    return false;
                }
                block = b;
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}

/// Offer a block from a live source: if the consumer has fallen behind and the channel is
/// full, the block is dropped and its samples counted as lost (the next block's
/// `first_sample` jumps, so the pipeline sees the gap too). Returns `false` when the
/// receiver is gone.
pub fn offer_block(tx: &BlockSender, block: SampleBlock, stats: &SourceStats) -> bool {
    let n = block.len() as u64;
    match tx.try_send(block) {
        Ok(()) => {
            SourceStats::add(&stats.blocks, 1);
            SourceStats::add(&stats.samples, n);
            true
        }
        Err(TrySendError::Full(_)) => {
            SourceStats::add(&stats.samples_lost, n);
            true
        }
        Err(TrySendError::Disconnected(_)) => false,
    }
}

/// Sleep up to `d`, waking early when `stop` is set. Returns `false` if stopped.
pub fn sleep_unless_stopped(d: Duration, stop: &StopToken) -> bool {
    let end = std::time::Instant::now() + d;
    loop {
        if stop.is_stopped() {
            return false;
        }
        let now = std::time::Instant::now();
        if now >= end {
            return true;
        }
        std::thread::sleep((end - now).min(Duration::from_millis(20)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        source: SourceConfig,
    }

    fn parse(t: &str) -> Result<SourceConfig, String> {
        toml::from_str::<Doc>(t)
            .map(|d| d.source)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn every_source_type_parses_with_defaults() {
        let f = parse("[source]\ntype = \"file\"\npath = \"replay/healthy.mcap\"\nspeed = \"max\"\nloop = true").unwrap();
        let SourceConfig::File(f) = f else { panic!() };
        assert_eq!(
            (f.speed, f.looping, f.block_ms),
            (ReplaySpeed::Max, true, 100.0)
        );
        let s = parse("[source]\ntype = \"serial\"\nport = \"/dev/ttyUSB0\"").unwrap();
        assert_eq!(s.kind(), "serial");
        let SourceConfig::Serial(s) = s else { panic!() };
        assert_eq!(s.baud, 921_600);
        let c = parse("[source]\ntype = \"can\"\ninterface = \"can0\"\nbase_id = 0x200").unwrap();
        let SourceConfig::Can(c) = c else { panic!() };
        assert_eq!((c.base_id, c.max_lag_ms), (0x200, 500.0));
        let a = parse(
            "[source]\ntype = \"audio\"\ndevice = \"rigcap\"\nmap = { vertical = 0, tacho = 1 }",
        )
        .unwrap();
        let SourceConfig::Audio(a) = a else { panic!() };
        assert_eq!(a.map["tacho"], 1);
    }

    #[test]
    fn unknown_keys_and_types_are_rejected_by_name() {
        let e = parse("[source]\ntype = \"file\"\npath = \"x.mcap\"\nspeeed = 2").unwrap_err();
        assert!(e.contains("speeed"), "{e}");
        let e = parse("[source]\ntype = \"serial\"\nport = \"/dev/ttyUSB0\"\nbaudrate = 9600")
            .unwrap_err();
        assert!(e.contains("baudrate"), "{e}");
        let e = parse("[source]\ntype = \"dewesoft\"").unwrap_err();
        assert!(e.contains("dewesoft"), "{e}");
    }

    #[test]
    fn relative_paths_resolve_against_the_config_file() {
        let mut s = parse("[source]\ntype = \"file\"\npath = \"replay/a.mcap\"").unwrap();
        s.resolve_paths(Path::new("/etc/rigmon/rigmon.toml"));
        let SourceConfig::File(f) = s else { panic!() };
        assert_eq!(f.path, Path::new("/etc/rigmon/replay/a.mcap"));
    }

    #[test]
    fn a_file_that_cannot_be_read_says_which() {
        let rig = RigConfig::load(
            &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let s = parse("[source]\ntype = \"file\"\npath = \"/nonexistent/run.mcap\"").unwrap();
        let e = format!("{:#}", s.build(&rig).err().unwrap());
        assert!(e.contains("/nonexistent/run.mcap"), "{e}");
    }
}
