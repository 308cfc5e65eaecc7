//! The serial DAQ adapter: reads frames of the rigmon serial protocol
//! ([`super::serial_protocol`]) from a serial port, reconnects with backoff when the device
//! goes away, and counts bad frames, sequence gaps and lost samples instead of failing.

use super::layout::RigLayout;
use super::serial_protocol::{Decoder, DecoderCounters, Frame};
use super::{
    live_sample_rate, offer_block, sleep_unless_stopped, BlockAssembler, BlockSender, Source,
    SourceStats, StopToken,
};
use crate::config::RigConfig;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::io::Read;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn default_baud() -> u32 {
    921_600
}
fn default_block_ms() -> f64 {
    100.0
}
fn default_reconnect_max_ms() -> u64 {
    2000
}

/// First wait before reopening a lost device; doubles up to `reconnect_max_ms`.
pub const RECONNECT_FIRST: Duration = Duration::from_millis(50);

/// `[source] type = "serial"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSourceConfig {
    /// The serial device (`/dev/ttyUSB0`, `/dev/serial/by-id/...`, or the path
    /// `rigmon emulate serial --pty` prints).
    pub port: String,
    /// Baud rate (ignored by pseudo-terminals and USB CDC devices).
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Sample rate the DAQ runs at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// Longest wait between reconnection attempts, ms (the wait doubles from 50 ms).
    #[serde(default = "default_reconnect_max_ms")]
    pub reconnect_max_ms: u64,
}

impl SerialSourceConfig {
    /// A port with the defaults.
    pub fn new(port: impl Into<String>) -> Self {
        SerialSourceConfig {
            port: port.into(),
            baud: default_baud(),
            sample_rate_hz: None,
            block_ms: default_block_ms(),
            reconnect_max_ms: default_reconnect_max_ms(),
        }
    }

    /// Check the settings against the rig. The port is not opened here: a device that is
    /// not plugged in yet is waited for (and reported as disconnected), not an error.
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        Ok(Box::new(self.source(rig)?))
    }

    /// Like [`SerialSourceConfig::build`], with the concrete type.
    pub fn source(&self, rig: &RigConfig) -> Result<SerialSource> {
        let fs = live_sample_rate(self.sample_rate_hz, &rig.acquisition, "serial")?;
        if self.port.trim().is_empty() {
            bail!("serial source: `port` is empty; give the device path, e.g. /dev/ttyUSB0");
        }
        if !(self.block_ms.is_finite() && (1.0..=10_000.0).contains(&self.block_ms)) {
            bail!(
                "serial source: block_ms = {} must be between 1 and 10000",
                self.block_ms
            );
        }
        if self.reconnect_max_ms < 50 {
            bail!(
                "serial source: reconnect_max_ms = {} must be at least 50",
                self.reconnect_max_ms
            );
        }
        if self.baud == 0 {
            bail!("serial source: baud must be positive");
        }
        let layout = RigLayout::new(&rig.channels, &rig.speed);
        Ok(SerialSource {
            cfg: self.clone(),
            fs,
            block: BlockAssembler::samples_for_ms(fs, self.block_ms),
            layout,
        })
    }
}

/// A serial DAQ adapter ready to run.
#[derive(Debug)]
pub struct SerialSource {
    cfg: SerialSourceConfig,
    fs: f64,
    block: usize,
    layout: RigLayout,
}

/// Logs a kind of trouble at most once every 10 s (with how often it happened meanwhile).
#[derive(Debug, Default)]
pub(crate) struct Throttle {
    last: Option<Instant>,
    suppressed: u64,
}

impl Throttle {
    pub(crate) fn warn(&mut self, msg: impl FnOnce() -> String) {
        let now = Instant::now();
        if self
            .last
            .is_none_or(|t| now.duration_since(t) >= Duration::from_secs(10))
        {
            let more = std::mem::take(&mut self.suppressed);
            if more > 0 {
                tracing::warn!("{} ({more} more like it since the last message)", msg());
            } else {
                tracing::warn!("{}", msg());
            }
            self.last = Some(now);
        } else {
            self.suppressed += 1;
        }
    }
}

struct Session<'a> {
    src: &'a SerialSource,
    stats: &'a SourceStats,
    decoder: Decoder,
    seen: DecoderCounters,
    asm: BlockAssembler,
    mismatch: Throttle,
}

impl Session<'_> {
    /// Decode what is buffered; returns `false` when the receiver is gone.
    fn drain(&mut self, tx: &BlockSender) -> bool {
        while let Some(frame) = self.decoder.next_frame() {
            self.frame(frame);
        }
        let c = self.decoder.counters().clone();
        SourceStats::add(
            &self.stats.bad_frames,
            c.bad_frames() - self.seen.bad_frames(),
        );
        SourceStats::add(
            &self.stats.sequence_gaps,
            c.sequence_gaps - self.seen.sequence_gaps,
        );
        SourceStats::add(
            &self.stats.samples_lost,
            c.samples_lost - self.seen.samples_lost,
        );
        self.seen = c;
        self.flush(tx)
    }

    fn flush(&mut self, tx: &BlockSender) -> bool {
        for b in self.asm.take_ready() {
            if !offer_block(tx, b, self.stats) {
                return false;
            }
        }
        true
    }

    fn frame(&mut self, f: Frame) {
        let layout = &self.src.layout;
        if f.channels.len() != layout.device_channels() {
            SourceStats::add(&self.stats.bad_frames, 1);
            self.mismatch.warn(|| {
                format!(
                    "serial {}: frame {} has {} channels but the rig has {} ({}); frame skipped — make the DAQ send the rig's channels in order",
                    self.src.cfg.port,
                    f.sequence,
                    f.channels.len(),
                    layout.device_channels(),
                    layout.describe()
                )
            });
            return;
        }
        if (f.sample_rate as f64 - self.src.fs).abs() > 1e-3 * self.src.fs {
            SourceStats::add(&self.stats.bad_frames, 1);
            self.mismatch.warn(|| {
                format!(
                    "serial {}: frame {} says {} Hz but the source runs at {} Hz; frame skipped — fix `sample_rate_hz` or the DAQ",
                    self.src.cfg.port, f.sequence, f.sample_rate, self.src.fs
                )
            });
            return;
        }
        let first = f.first_sample;
        let edges: Vec<f64> = f.edges.iter().map(|e| e / self.src.fs).collect();
        let (accel, tacho) = layout.split(f.channels);
        self.asm.push(first, &accel, tacho.as_deref(), &edges);
    }
}

impl Source for SerialSource {
    fn describe(&self) -> String {
        format!(
            "serial {} @ {} baud, {} Hz, channels {}",
            self.cfg.port,
            self.cfg.baud,
            self.fs,
            self.layout.describe()
        )
    }

    fn analog_tacho(&self) -> bool {
        self.layout.analog_tacho
    }

    fn sample_rate(&self) -> f64 {
        self.fs
    }

    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        let mut s = Session {
            src: &self,
            stats: &stats,
            decoder: Decoder::new(),
            seen: DecoderCounters::default(),
            asm: BlockAssembler::new(
                self.fs,
                self.layout.n_accel,
                self.layout.analog_tacho,
                self.block,
            ),
            mismatch: Throttle::default(),
        };
        let max_wait = Duration::from_millis(self.cfg.reconnect_max_ms);
        let mut wait = RECONNECT_FIRST;
        let mut opened_before = false;
        let mut open_trouble = Throttle::default();
        let mut buf = vec![0u8; 64 * 1024];
        'outer: while !stop.is_stopped() {
            let mut port = match serialport::new(&self.cfg.port, self.cfg.baud)
                .timeout(Duration::from_millis(100))
                .open()
            {
                Ok(p) => p,
                Err(e) => {
                    open_trouble.warn(|| {
                        format!(
                            "serial {}: cannot open ({e}); retrying every {} ms at most",
                            self.cfg.port,
                            max_wait.as_millis()
                        )
                    });
                    if !sleep_unless_stopped(wait, &stop) {
                        break;
                    }
                    wait = (wait * 2).min(max_wait);
                    continue;
                }
            };
            if opened_before {
                SourceStats::add(&stats.reconnects, 1);
                tracing::info!("serial {}: reconnected", self.cfg.port);
            } else {
                tracing::info!("serial {}: open", self.cfg.port);
            }
            opened_before = true;
            wait = RECONNECT_FIRST;
            stats.connected.store(true, Ordering::Relaxed);
            s.decoder.discard_buffered();
            loop {
                if stop.is_stopped() {
                    break 'outer;
                }
                match port.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        s.decoder.feed(&buf[..n]);
                        if !s.drain(&tx) {
                            break 'outer;
                        }
                    }
                    Err(e)
                        if e.kind() == std::io::ErrorKind::TimedOut
                            || e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        tracing::warn!(
                            "serial {}: lost the device ({e}); reconnecting",
                            self.cfg.port
                        );
                        break;
                    }
                }
            }
            stats.connected.store(false, Ordering::Relaxed);
            drop(port);
            // What was assembled before the loss is good data: hand it on.
            s.asm.close();
            if !s.flush(&tx) {
                break;
            }
            if !sleep_unless_stopped(wait, &stop) {
                break;
            }
        }
        stats.connected.store(false, Ordering::Relaxed);
        s.asm.close();
        s.flush(&tx);
        Ok(())
    }
}
