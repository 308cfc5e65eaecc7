//! Sources: where samples come from (MCAP replay, serial DAQ adapter, CAN adapter, sound
//! card). Every source runs on its own thread, pushes [`SampleBlock`]s on the sample clock
//! into a bounded channel, and counts what went wrong in [`SourceStats`] instead of failing.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// A block of consecutive samples from a source, on the source's sample clock.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleBlock {
    /// Index of the first sample on the sample clock. A jump from the previous block's end
    /// means samples were lost (and the pipeline counts them).
    pub first_sample: u64,
    /// Sample rate, Hz.
    pub sample_rate: f64,
    /// One vector per acceleration channel, in rig channel order, all the same length.
    pub channels: Vec<Vec<f32>>,
    /// Analog tacho samples (same length as the channels) when the tacho is a voltage.
    pub tacho_analog: Option<Vec<f32>>,
    /// Tacho edge times in seconds on the sample clock (sample index / sample rate).
    pub tacho_edges: Vec<f64>,
}

impl SampleBlock {
    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

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
    /// Run until done or stopped.
    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> anyhow::Result<()>;
}
