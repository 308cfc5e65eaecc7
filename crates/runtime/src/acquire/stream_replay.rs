//! The daemon's file source ([`StreamReplay`]): a recording streamed block by block from disk
//! ([`BlockStream`]), so a file of any size replays with memory that does not grow with it.
//! Channels come out in rig order (a rig channel the file lacks is NaN and listed as absent);
//! a gap in the file (samples it does not hold: blocks its recorder dropped, a damaged chunk
//! skipped) is a jump of the sample clock, so the windower counts the samples as lost and
//! flags the windows over it `dropout`, never silence. What the file could not deliver is
//! logged as it is found and kept in [`SourceStats::losses`] for the status and the summary.
//! A recording too short for one window is refused before it starts (or, when its length is
//! only known at its end, fails then), naming the length it needs.

use super::{
    send_block, sleep_unless_stopped, BlockSender, ReplaySpeed, SampleBlock, Source, SourceStats,
    StopToken,
};
use crate::config::RigConfig;
use crate::recording::mcap::TachoInfo;
use crate::recording::stream::BlockStream;
use crate::recording::Losses;
use anyhow::{bail, Result};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A recording streamed through the daemon.
pub struct StreamReplay {
    stream: Box<dyn BlockStream>,
    /// For each rig acceleration channel, the index of the stream's channel, or `None`.
    order: Vec<Option<usize>>,
    absent: Vec<String>,
    speed: ReplaySpeed,
    looping: bool,
    /// Samples per block handed to the pipeline.
    block: usize,
    name: String,
    /// `features.window_s` and the samples one window needs.
    window_s: f64,
    window: u64,
}

impl StreamReplay {
    /// Check the stream against the rig: sample rate, the classifier channel, the recipe at the
    /// stream's rate, and a length of at least one window when the length is known up front.
    pub fn new(
        stream: Box<dyn BlockStream>,
        rig: &RigConfig,
        speed: ReplaySpeed,
        looping: bool,
        block_ms: f64,
        name: &str,
    ) -> Result<Self> {
        let info = stream.info();
        let fs = info.sample_rate;
        if !(fs.is_finite() && fs > 0.0) {
            bail!("{name}: the recording's sample rate is {fs} Hz; give the right one with `sample_rate_hz`");
        }
        let names: Vec<&str> = info.channels.iter().map(|c| c.name.as_str()).collect();
        let (order, absent) = super::channel_order::rig_channel_order(rig, &names, fs, name)?;
        // The recipe at this rate (window bounds, low-pass below Nyquist, the stored speed)
        // before the window's length is used.
        rig.check_recipe_at(fs, info.rpm, &format!("recording {name}"))?;
        let window_s = rig.features.window_s;
        let window = (window_s * fs).round().max(1.0) as u64;
        if let Some(n) = stream.exact_len() {
            if n < window {
                bail!(too_short(n, fs, window_s, window));
            }
        }
        let block = super::BlockAssembler::samples_for_ms(fs, block_ms);
        Ok(StreamReplay {
            stream,
            order,
            absent,
            speed,
            looping,
            block,
            name: name.to_string(),
            window_s,
            window,
        })
    }

    /// The block's channels in rig order, `pass_offset` added to its clock.
    fn to_rig_order(&self, b: SampleBlock, offset: u64) -> SampleBlock {
        let n = b.len();
        let mut cols: Vec<Option<Vec<f32>>> = b.channels.into_iter().map(Some).collect();
        let channels = self
            .order
            .iter()
            .map(|idx| match idx {
                Some(i) => cols[*i].take().unwrap_or_else(|| vec![f32::NAN; n]),
                None => vec![f32::NAN; n],
            })
            .collect();
        let shift = offset as f64 / b.sample_rate;
        SampleBlock {
            first_sample: b.first_sample + offset,
            sample_rate: b.sample_rate,
            channels,
            tacho_analog: b.tacho_analog,
            tacho_edges: b
                .tacho_edges
                .into_iter()
                .filter(|t| t.is_finite())
                .map(|t| t + shift)
                .collect(),
        }
    }

    /// Log what the stream lost since `seen`, and publish it in the stats.
    fn report_losses(&self, seen: &mut Losses, stats: &SourceStats) {
        let now = self.stream.losses();
        if now == *seen {
            return;
        }
        let fs = self.stream.info().sample_rate;
        for d in now.damaged.iter().skip(seen.damaged.len()) {
            tracing::warn!(
                "{}: damaged stretch at byte {} ({} bytes) skipped: {}",
                self.name,
                d.at_byte,
                d.bytes,
                d.what
            );
        }
        for g in now.gaps.iter().skip(seen.gaps.len()) {
            tracing::warn!(
                "{}: {:.3} s ({} samples) missing at {:.3} s ({}); the windows over it are flagged dropout",
                self.name,
                g.seconds,
                g.samples,
                g.at_s,
                g.cause.text()
            );
        }
        if let Ok(mut l) = stats.losses.lock() {
            *l = Some(now.report(fs));
        }
        *seen = now;
    }
}

/// The recording's `n` samples do not make one window.
fn too_short(n: u64, fs: f64, window_s: f64, window: u64) -> String {
    format!(
        "{n} sample(s) ({:.4} s) are too short for one window: features.window_s = {window_s} s \
         needs {window} samples at {fs} Hz; use a longer recording or a shorter \
         features.window_s in the rig file",
        n as f64 / fs
    )
}

impl Source for StreamReplay {
    fn describe(&self) -> String {
        let info = self.stream.info();
        let p = &info.provenance;
        format!(
            "file {} ({}, {} Hz, {}, speed {}{})",
            self.name,
            if p.format.is_empty() {
                "recording"
            } else {
                &p.format
            },
            info.sample_rate,
            self.stream
                .duration_hint_s()
                .map_or("length unknown".to_string(), |d| format!("{d:.1} s")),
            self.speed,
            if self.looping { ", loop" } else { "" }
        )
    }

    fn analog_tacho(&self) -> bool {
        matches!(self.stream.info().tacho, TachoInfo::Analog { .. })
    }

    fn sample_rate(&self) -> f64 {
        self.stream.info().sample_rate
    }

    fn nominal_rpm(&self) -> Option<f64> {
        self.stream.info().rpm
    }

    fn absent_channels(&self) -> Vec<String> {
        self.absent.clone()
    }

    fn capture_series(&self) -> bool {
        crate::recording::captures::is_capture_series(&self.stream.info().metadata)
    }

    fn run(
        mut self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        let fs = self.stream.info().sample_rate;
        let t0 = Instant::now();
        stats.connected.store(true, Ordering::Relaxed);
        let mut offset = 0u64;
        let mut seen = Losses::default();
        let mut pass = 0u64;
        'outer: loop {
            let mut end = 0u64;
            let mut delivered = 0u64;
            while let Some(b) = self.stream.next_block()? {
                self.report_losses(&mut seen, &stats);
                // Each pass starts the sample clock again: the seam is a clock going
                // backwards, which restarts the windows and their speed (analysis::windows).
                let b = self.to_rig_order(b, 0);
                for part in split(b, self.block) {
                    if stop.is_stopped() {
                        break 'outer;
                    }
                    let part_end = part.first_sample + part.len() as u64 + offset;
                    if let ReplaySpeed::Factor(x) = self.speed {
                        // A live DAQ delivers a block once its last sample has been taken.
                        let due = t0 + Duration::from_secs_f64(part_end as f64 / fs / x);
                        let now = Instant::now();
                        if due > now && !sleep_unless_stopped(due - now, &stop) {
                            break 'outer;
                        }
                    }
                    let len = part.len() as u64;
                    if !send_block(&tx, part, &stop) {
                        break 'outer;
                    }
                    SourceStats::add(&stats.blocks, 1);
                    SourceStats::add(&stats.samples, len);
                    delivered += len;
                    end = part_end - offset;
                }
            }
            self.report_losses(&mut seen, &stats);
            if pass == 0 {
                if !seen.is_empty() {
                    tracing::warn!("{}: {}", self.name, seen.line(fs));
                }
                if delivered < self.window {
                    bail!(too_short(delivered, fs, self.window_s, self.window));
                }
            }
            if !self.looping || stop.is_stopped() {
                break;
            }
            self.stream.rewind()?;
            offset += end;
            pass += 1;
        }
        stats.connected.store(false, Ordering::Relaxed);
        Ok(())
    }
}

/// A block cut into blocks of at most `n` samples.
fn split(b: SampleBlock, n: usize) -> Vec<SampleBlock> {
    if b.len() <= n {
        return vec![b];
    }
    let fs = b.sample_rate;
    let mut out = Vec::with_capacity(b.len().div_ceil(n));
    let mut start = 0;
    while start < b.len() {
        let end = (start + n).min(b.len());
        let first = b.first_sample + start as u64;
        let (t0, t1) = (first as f64 / fs, (b.first_sample + end as u64) as f64 / fs);
        let last = end == b.len();
        out.push(SampleBlock {
            first_sample: first,
            sample_rate: fs,
            channels: b.channels.iter().map(|c| c[start..end].to_vec()).collect(),
            tacho_analog: b.tacho_analog.as_ref().map(|t| t[start..end].to_vec()),
            tacho_edges: b
                .tacho_edges
                .iter()
                .copied()
                .filter(|&t| (t >= t0 || start == 0) && (t < t1 || last))
                .collect(),
        });
        start = end;
    }
    out
}
