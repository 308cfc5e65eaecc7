//! The sound-card source (feature `audio`, cpal -> ALSA): input channels mapped to rig
//! channels by name, the tacho on one of them; samples (full scale = 1.0) multiplied by the
//! rig's `sensitivity`. The device is reopened with backoff when it fails.

use super::layout::{RigLayout, Slot};
use super::{live_sample_rate, Source};
use crate::config::RigConfig;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

fn default_block_ms() -> f64 {
    100.0
}

/// `[source] type = "audio"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AudioSourceConfig {
    /// Input device as ALSA names it (`arecord -L`: `default`, `hw:CARD=...`, or a pcm
    /// defined in `.asoundrc`); the default input device if unset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// Sample rate to open the device at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Rig channel name -> input channel index (0-based), e.g.
    /// `map = { vertical = 0, horizontal = 1, axial = 2, tacho = 3 }`.
    pub map: BTreeMap<String, u16>,
    /// Channels to open on the device; defaults to the highest mapped index + 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_channels: Option<u16>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
}

/// The checked settings a sound-card source runs with.
#[derive(Debug, Clone)]
pub struct AudioPlan {
    pub device: Option<String>,
    pub sample_rate: u32,
    pub input_channels: u16,
    /// For each input channel: where it goes (or `Unused`) and its sensitivity.
    pub routes: Vec<(Slot, f32)>,
    pub n_accel: usize,
    pub analog_tacho: bool,
    pub block_ms: f64,
    pub describe: String,
}

impl AudioSourceConfig {
    /// Check the channel map against the rig, then find the device (an error names the
    /// devices that exist).
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        let plan = self.plan(rig)?;
        imp::build(plan)
    }

    /// The checks of [`AudioSourceConfig::build`] that need no device.
    pub fn plan(&self, rig: &RigConfig) -> Result<AudioPlan> {
        let fs = live_sample_rate(self.sample_rate_hz, &rig.acquisition, "audio")?;
        if fs.fract() != 0.0 || fs > 768_000.0 {
            bail!(
                "audio source: sample rate {fs} Hz: sound cards run at whole rates up to 768000 Hz"
            );
        }
        if !(self.block_ms.is_finite() && (1.0..=10_000.0).contains(&self.block_ms)) {
            bail!(
                "audio source: block_ms = {} must be between 1 and 10000",
                self.block_ms
            );
        }
        let layout = RigLayout::new(&rig.channels, &rig.speed);
        for name in self.map.keys() {
            if !layout.names.contains(name) {
                bail!("audio source: map names {name:?}, which is not a channel of rig {}; its channels are {}", rig.machine.id, layout.describe());
            }
        }
        let mut need: Vec<&str> = Vec::new();
        for (name, slot) in layout.names.iter().zip(&layout.slots) {
            if *slot != Slot::Unused && !self.map.contains_key(name) {
                need.push(name);
            }
        }
        if !need.is_empty() {
            bail!("audio source: map gives no input channel for {need:?}; add e.g. `{} = 0` to the map", need[0]);
        }
        let highest = self.map.values().copied().max().unwrap_or(0);
        let input_channels = self.input_channels.unwrap_or(highest + 1);
        if input_channels == 0 || highest >= input_channels {
            bail!("audio source: map uses input channel {highest} but input_channels = {input_channels}");
        }
        let mut routes = vec![(Slot::Unused, 1.0f32); input_channels as usize];
        for (name, &idx) in &self.map {
            let k = layout.names.iter().position(|n| n == name).unwrap();
            if routes[idx as usize].0 != Slot::Unused {
                bail!("audio source: input channel {idx} is mapped twice");
            }
            routes[idx as usize] = (layout.slots[k], layout.sensitivity[k]);
        }
        let describe = format!(
            "audio {} @ {fs} Hz, {}",
            self.device.as_deref().unwrap_or("default"),
            self.map
                .iter()
                .map(|(n, i)| format!("{n}<-in{i}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        Ok(AudioPlan {
            device: self.device.clone(),
            sample_rate: fs as u32,
            input_channels,
            routes,
            n_accel: layout.n_accel,
            analog_tacho: layout.analog_tacho,
            block_ms: self.block_ms,
            describe,
        })
    }
}

impl AudioPlan {
    /// Split interleaved frames (`input_channels` values each) into acceleration channels
    /// and the tacho, scaled by sensitivity.
    pub fn route(&self, interleaved: &[f32], accel: &mut [Vec<f32>], tacho: &mut Vec<f32>) {
        let c = self.input_channels as usize;
        for frame in interleaved.chunks_exact(c) {
            for (v, (slot, s)) in frame.iter().zip(&self.routes) {
                match *slot {
                    Slot::Accel(k) => accel[k].push(v * s),
                    Slot::Tacho => tacho.push(v * s),
                    Slot::Unused => {}
                }
            }
        }
    }
}

#[cfg(not(feature = "audio"))]
mod imp {
    use super::*;
    pub(super) fn build(_plan: AudioPlan) -> Result<Box<dyn Source>> {
        bail!("audio source: this rigmon was built without the `audio` feature; rebuild with `cargo build --features audio`")
    }
}

#[cfg(feature = "audio")]
mod imp {
    use super::super::serial::RECONNECT_FIRST;
    use super::super::{
        offer_block, sleep_unless_stopped, BlockAssembler, BlockSender, SourceStats, StopToken,
    };
    use super::*;
    use cpal::traits::{DeviceTrait, HostTrait, StreamTrait};
    use std::sync::atomic::AtomicU64;
    use std::sync::atomic::Ordering;
    use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    /// Frames the callback may queue ahead of the reader (2^20: 100 s at 10 kHz, 20 s at
    /// 51.2 kHz); beyond that it drops chunks and counts them lost.
    const QUEUE_FRAMES: u64 = 1 << 20;

    fn names(d: &cpal::Device) -> Vec<String> {
        let mut v = Vec::new();
        if let Ok(id) = d.id() {
            v.push(id.id().to_string());
            v.push(id.to_string());
        }
        if let Ok(desc) = d.description() {
            v.push(desc.name().to_string());
        }
        v
    }

    fn find(want: Option<&str>) -> Result<cpal::Device> {
        let host = cpal::default_host();
        match want {
            None => host.default_input_device().ok_or_else(|| {
                anyhow::anyhow!(
                    "audio source: there is no default input device; name one with `device`"
                )
            }),
            Some(w) => {
                let devices: Vec<cpal::Device> = host
                    .input_devices()
                    .map_err(|e| anyhow::anyhow!("audio source: cannot list input devices: {e}"))?
                    .collect();
                if let Some(d) = devices.iter().find(|d| names(d).iter().any(|n| n == w)) {
                    return Ok(d.clone());
                }
                let all: Vec<String> = devices
                    .iter()
                    .filter_map(|d| names(d).into_iter().next())
                    .collect();
                bail!("audio source: no input device named {w:?}; the input devices are {all:?} (`arecord -L` lists ALSA's names)")
            }
        }
    }

    pub(super) fn build(plan: AudioPlan) -> Result<Box<dyn Source>> {
        find(plan.device.as_deref())?;
        Ok(Box::new(AudioSource { plan }))
    }

    pub struct AudioSource {
        plan: AudioPlan,
    }

    /// Open the stream; samples go to `tx` as interleaved f32 chunks.
    fn open(
        plan: &AudioPlan,
        tx: Sender<Vec<f32>>,
        queued: Arc<AtomicU64>,
        lost: Arc<AtomicU64>,
        xruns: Arc<AtomicU64>,
        failed: Arc<std::sync::atomic::AtomicBool>,
    ) -> Result<cpal::Stream> {
        let dev = find(plan.device.as_deref())?;
        let cfg = cpal::StreamConfig {
            channels: plan.input_channels,
            sample_rate: plan.sample_rate,
            buffer_size: cpal::BufferSize::Default,
        };
        let c = plan.input_channels as u64;
        macro_rules! stream {
            ($t:ty, $conv:expr) => {{
                let (tx, lost, failed, xruns, queued) = (
                    tx.clone(),
                    lost.clone(),
                    failed.clone(),
                    xruns.clone(),
                    queued.clone(),
                );
                dev.build_input_stream::<$t, _, _>(
                    cfg.clone(),
                    move |data: &[$t], _: &cpal::InputCallbackInfo| {
                        let chunk: Vec<f32> = data.iter().map(|&x| $conv(x)).collect();
                        // Never wait here (the device would overrun): if the reader is
                        // behind, drop the chunk and count it; the clock moves on.
                        let n = chunk.len() as u64 / c;
                        if queued.load(Ordering::Relaxed) + n > QUEUE_FRAMES {
                            lost.fetch_add(n, Ordering::Relaxed);
                        } else {
                            queued.fetch_add(n, Ordering::Relaxed);
                            let _ = tx.send(chunk);
                        }
                    },
                    move |e: cpal::Error| match e.kind() {
                        // Overruns lose an unknown number of samples but the stream goes on.
                        cpal::ErrorKind::Xrun => {
                            xruns.fetch_add(1, Ordering::Relaxed);
                        }
                        cpal::ErrorKind::RealtimeDenied => tracing::debug!("audio stream: {e}"),
                        _ => {
                            tracing::warn!("audio stream: {e}; reopening");
                            failed.store(true, Ordering::Relaxed);
                        }
                    },
                    None,
                )
            }};
        }
        let stream = stream!(f32, |x: f32| x)
            .or_else(|_| stream!(i16, |x: i16| x as f32 / 32768.0))
            .or_else(|_| stream!(i32, |x: i32| x as f32 / 2_147_483_648.0))
            .map_err(|e| {
                anyhow::anyhow!(
                    "audio source: cannot open {} channels at {} Hz: {e}",
                    plan.input_channels,
                    plan.sample_rate
                )
            })?;
        stream
            .play()
            .map_err(|e| anyhow::anyhow!("audio source: cannot start the stream: {e}"))?;
        Ok(stream)
    }

    impl Source for AudioSource {
        fn describe(&self) -> String {
            self.plan.describe.clone()
        }

        fn analog_tacho(&self) -> bool {
            self.plan.analog_tacho
        }

        fn sample_rate(&self) -> f64 {
            self.plan.sample_rate as f64
        }

        fn run(
            self: Box<Self>,
            tx: BlockSender,
            stats: Arc<SourceStats>,
            stop: StopToken,
        ) -> Result<()> {
            let plan = &self.plan;
            let fs = plan.sample_rate as f64;
            let mut asm = BlockAssembler::new(
                fs,
                plan.n_accel,
                plan.analog_tacho,
                BlockAssembler::samples_for_ms(fs, plan.block_ms),
            );
            let mut clock = 0u64;
            let mut wait = RECONNECT_FIRST;
            let mut down_since: Option<Instant> = None;
            let mut accel: Vec<Vec<f32>> = vec![Vec::new(); plan.n_accel];
            let mut tacho = Vec::new();
            'outer: while !stop.is_stopped() {
                let (ctx, crx) = channel::<Vec<f32>>();
                let queued = Arc::new(AtomicU64::new(0));
                let lost = Arc::new(AtomicU64::new(0));
                let xruns = Arc::new(AtomicU64::new(0));
                let failed = Arc::new(std::sync::atomic::AtomicBool::new(false));
                let stream = match open(
                    plan,
                    ctx,
                    queued.clone(),
                    lost.clone(),
                    xruns.clone(),
                    failed.clone(),
                ) {
                    Ok(s) => s,
                    Err(e) => {
                        tracing::warn!("{e:#}; retrying");
                        if !sleep_unless_stopped(wait, &stop) {
                            break;
                        }
                        wait = (wait * 2).min(Duration::from_secs(2));
                        continue;
                    }
                };
                if let Some(t) = down_since.take() {
                    // A sound card has no sample counter of its own: what passed while it
                    // was away is estimated from the wall clock, skipped and counted lost.
                    let missed = (t.elapsed().as_secs_f64() * fs) as u64;
                    clock += missed;
                    SourceStats::add(&stats.samples_lost, missed);
                    SourceStats::add(&stats.reconnects, 1);
                }
                wait = RECONNECT_FIRST;
                stats.connected.store(true, Ordering::Relaxed);
                let (mut seen_lost, mut seen_xruns) = (0, 0);
                loop {
                    if stop.is_stopped() {
                        break 'outer;
                    }
                    if failed.load(Ordering::Relaxed) {
                        break;
                    }
                    match crx.recv_timeout(Duration::from_millis(100)) {
                        Ok(chunk) => {
                            queued.fetch_sub(
                                (chunk.len() / plan.input_channels as usize) as u64,
                                Ordering::Relaxed,
                            );
                            // Chunks the callback had to drop leave a gap on the clock.
                            let l = lost.load(Ordering::Relaxed);
                            clock += l - seen_lost;
                            SourceStats::add(&stats.samples_lost, l - seen_lost);
                            seen_lost = l;
                            let x = xruns.load(Ordering::Relaxed);
                            if x > seen_xruns {
                                tracing::warn!("audio: {} overrun(s): samples lost in the driver (count unknown)", x - seen_xruns);
                                SourceStats::add(&stats.sequence_gaps, x - seen_xruns);
                                seen_xruns = x;
                            }
                            accel.iter_mut().for_each(Vec::clear);
                            tacho.clear();
                            plan.route(&chunk, &mut accel, &mut tacho);
                            let n = chunk.len() / plan.input_channels as usize;
                            asm.push(
                                clock,
                                &accel,
                                plan.analog_tacho.then_some(tacho.as_slice()),
                                &[],
                            );
                            clock += n as u64;
                            for b in asm.take_ready() {
                                if !offer_block(&tx, b, &stats) {
                                    break 'outer;
                                }
                            }
                        }
                        Err(RecvTimeoutError::Timeout) => {}
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                }
                drop(stream);
                down_since = Some(Instant::now());
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
