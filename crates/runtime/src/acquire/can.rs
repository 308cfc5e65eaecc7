//! The CAN adapter: reads frames of the rigmon CAN layout ([`super::can_protocol`]) from a
//! SocketCAN interface (feature `can`; classic and FD frames alike), reopens the interface
//! when it goes away, and counts bad frames, sequence gaps and lost samples instead of
//! failing.

use super::can_protocol::{MAX_BASE_ID, MAX_CAN_CHANNELS};
use super::layout::RigLayout;
use super::{live_sample_rate, Source};
use crate::config::RigConfig;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};

fn default_base_id() -> u32 {
    0x100
}
fn default_block_ms() -> f64 {
    100.0
}
fn default_reconnect_max_ms() -> u64 {
    2000
}
fn default_max_lag_ms() -> f64 {
    500.0
}

/// `[source] type = "can"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanSourceConfig {
    /// SocketCAN interface (`can0`, `vcan0`).
    pub interface: String,
    /// First CAN ID of the adapter's block of IDs (see the CAN layout in the README).
    #[serde(default = "default_base_id")]
    pub base_id: u32,
    /// Sample rate the adapter runs at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// A channel this far behind the others is filled with NaN so the rest keeps flowing, ms.
    #[serde(default = "default_max_lag_ms")]
    pub max_lag_ms: f64,
    /// Longest wait between reconnection attempts, ms.
    #[serde(default = "default_reconnect_max_ms")]
    pub reconnect_max_ms: u64,
}

impl CanSourceConfig {
    pub fn new(interface: impl Into<String>) -> Self {
        CanSourceConfig {
            interface: interface.into(),
            base_id: default_base_id(),
            sample_rate_hz: None,
            block_ms: default_block_ms(),
            max_lag_ms: default_max_lag_ms(),
            reconnect_max_ms: default_reconnect_max_ms(),
        }
    }

    /// Check the settings against the rig and open the interface once, so a machine without
    /// SocketCAN or a misspelt interface is reported at start.
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        let fs = live_sample_rate(self.sample_rate_hz, &rig.acquisition, "can")?;
        let name = &self.interface;
        if fs > 65_535.0 || fs.fract() != 0.0 {
            bail!("can source {name}: the CAN layout carries whole sample rates up to 65535 Hz; {fs} Hz does not fit");
        }
        if self.base_id > MAX_BASE_ID {
            bail!("can source {name}: base_id = {:#x} leaves no room for the layout's IDs in 11 bits (at most {MAX_BASE_ID:#x})", self.base_id);
        }
        let layout = RigLayout::new(&rig.channels, &rig.speed);
        if layout.device_channels() > MAX_CAN_CHANNELS {
            bail!("can source {name}: the rig has {} channels; the CAN layout carries at most {MAX_CAN_CHANNELS}", layout.device_channels());
        }
        for (what, v) in [("block_ms", self.block_ms), ("max_lag_ms", self.max_lag_ms)] {
            if !(v.is_finite() && (1.0..=10_000.0).contains(&v)) {
                bail!("can source {name}: {what} = {v} must be between 1 and 10000");
            }
        }
        if self.reconnect_max_ms < 50 {
            bail!(
                "can source {name}: reconnect_max_ms = {} must be at least 50",
                self.reconnect_max_ms
            );
        }
        imp::build(self, fs, layout)
    }
}

#[cfg(not(feature = "can"))]
mod imp {
    use super::*;
    pub(super) fn build(
        cfg: &CanSourceConfig,
        _fs: f64,
        _layout: RigLayout,
    ) -> Result<Box<dyn Source>> {
        bail!("can source {}: this rigmon was built without the `can` feature; rebuild with `cargo build --features can`", cfg.interface)
    }
}

#[cfg(feature = "can")]
mod imp {
    use super::super::can_protocol::{CanCounters, CanDecoder};
    use super::super::serial::{Throttle, RECONNECT_FIRST};
    use super::super::{
        offer_block, sleep_unless_stopped, BlockAssembler, BlockSender, SourceStats, StopToken,
    };
    use super::*;
    use socketcan::{CanAnyFrame, CanFdSocket, EmbeddedFrame, Id, Socket};
    use std::sync::atomic::Ordering;
    use std::sync::Arc;
    use std::time::Duration;

    pub(super) fn build(
        cfg: &CanSourceConfig,
        fs: f64,
        layout: RigLayout,
    ) -> Result<Box<dyn Source>> {
        if let Err(e) = CanFdSocket::open(&cfg.interface) {
            let hint = match e.raw_os_error() {
                Some(libc::EAFNOSUPPORT) => "this kernel has no SocketCAN support; load the `can` and `can_raw` modules (modprobe can_raw)".to_string(),
                Some(libc::ENODEV) => format!("there is no interface named {:?}; `ip link show` lists them (a USB adapter: plug it in, then `ip link set {} up type can bitrate 1000000`)", cfg.interface, cfg.interface),
                _ => "check the interface name and that it is up (`ip link show`)".to_string(),
            };
            bail!("can source {}: cannot open ({e}); {hint}", cfg.interface);
        }
        Ok(Box::new(CanSource {
            cfg: cfg.clone(),
            fs,
            layout,
        }))
    }

    /// A SocketCAN adapter ready to run.
    pub struct CanSource {
        cfg: CanSourceConfig,
        fs: f64,
        layout: RigLayout,
    }

    fn standard_frame(f: &CanAnyFrame) -> Option<(u32, &[u8])> {
        let (id, data) = match f {
            CanAnyFrame::Normal(d) => (d.id(), d.data()),
            CanAnyFrame::Fd(d) => (d.id(), d.data()),
            CanAnyFrame::Remote(_) | CanAnyFrame::Error(_) => return None,
        };
        match id {
            Id::Standard(s) => Some((s.as_raw() as u32, data)),
            Id::Extended(_) => None,
        }
    }

    impl Source for CanSource {
        fn describe(&self) -> String {
            format!(
                "can {} (base id {:#x}), {} Hz, channels {}",
                self.cfg.interface,
                self.cfg.base_id,
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
            let max_lag = BlockAssembler::samples_for_ms(self.fs, self.cfg.max_lag_ms);
            let mut dec = CanDecoder::new(
                self.cfg.base_id,
                self.layout.device_channels(),
                self.fs,
                max_lag,
            );
            let mut seen = CanCounters::default();
            let block = BlockAssembler::samples_for_ms(self.fs, self.cfg.block_ms);
            let mut asm = BlockAssembler::new(
                self.fs,
                self.layout.n_accel,
                self.layout.analog_tacho,
                block,
            );
            let max_wait = Duration::from_millis(self.cfg.reconnect_max_ms);
            let mut wait = RECONNECT_FIRST;
            let mut opened_before = false;
            let mut trouble = Throttle::default();
            'outer: while !stop.is_stopped() {
                let sock = match CanFdSocket::open(&self.cfg.interface)
                    .and_then(|s| s.set_read_timeout(Duration::from_millis(100)).map(|_| s))
                {
                    Ok(s) => s,
                    Err(e) => {
                        trouble.warn(|| {
                            format!("can {}: cannot open ({e}); retrying", self.cfg.interface)
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
                }
                opened_before = true;
                wait = RECONNECT_FIRST;
                stats.connected.store(true, Ordering::Relaxed);
                loop {
                    if stop.is_stopped() {
                        break 'outer;
                    }
                    match sock.read_frame() {
                        Ok(f) => {
                            if let Some((id, data)) = standard_frame(&f) {
                                dec.push(id, data);
                            }
                        }
                        Err(e)
                            if matches!(
                                e.kind(),
                                std::io::ErrorKind::WouldBlock
                                    | std::io::ErrorKind::TimedOut
                                    | std::io::ErrorKind::Interrupted
                            ) => {}
                        Err(e) => {
                            tracing::warn!(
                                "can {}: lost the interface ({e}); reconnecting",
                                self.cfg.interface
                            );
                            break;
                        }
                    }
                    while let Some(a) = dec.take_aligned() {
                        let first = a.first_sample;
                        let edges: Vec<f64> = a.edges.iter().map(|e| e / self.fs).collect();
                        let (accel, tacho) = self.layout.split(a.channels);
                        asm.push(first, &accel, tacho.as_deref(), &edges);
                    }
                    let c = dec.counters().clone();
                    SourceStats::add(&stats.bad_frames, c.bad_frames - seen.bad_frames);
                    SourceStats::add(&stats.sequence_gaps, c.sequence_gaps - seen.sequence_gaps);
                    SourceStats::add(&stats.samples_lost, c.samples_lost - seen.samples_lost);
                    seen = c;
                    for b in asm.take_ready() {
                        if !offer_block(&tx, b, &stats) {
                            break 'outer;
                        }
                    }
                }
                stats.connected.store(false, Ordering::Relaxed);
                if !sleep_unless_stopped(wait, &stop) {
                    break;
                }
            }
            stats.connected.store(false, Ordering::Relaxed);
            asm.close();
            for b in asm.take_ready() {
                offer_block(&tx, b, &stats);
            }
            Ok(())
        }
    }
}
