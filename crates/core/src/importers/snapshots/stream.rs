//! A series of captures as a [`BlockStream`]: one block per capture, read from its file when
//! asked for, its `first_sample` at the capture's time on the sample clock (time since the
//! first capture x sample rate). Memory holds one capture. The stream's metadata marks it a
//! capture series ([`META_CAPTURE_INTERVAL`]), so the windower restarts at every capture and
//! counts the time between captures as neither lost nor a gap. [`collect`] gathers any such
//! stream into one [`Recording`] with where each capture starts.

use super::{ImportOptions, Series};
use crate::config::RigConfig;
use crate::recording::captures::{
    is_capture_series, write_starts, CaptureStart, META_CAPTURE_INTERVAL,
};
use crate::recording::losses::GapCause;
use crate::recording::mcap::{RecordingInfo, RecordingReader, TachoInfo};
use crate::recording::stream::{BlockStream, McapStream};
use crate::recording::{Channel, Losses, Provenance, Recording, SampleBlock};
use anyhow::{bail, Result};
use std::path::Path;

/// Metadata key: one line describing the series (captures, length, interval).
pub const META_CAPTURE_SERIES: &str = "capture_series";

/// A folder of captures read one file at a time.
pub struct SnapshotStream {
    series: Series,
    info: RecordingInfo,
    rig: RigConfig,
    opts: ImportOptions,
    next: usize,
    /// Sample-clock index where the previous capture ended.
    prev_end: u64,
}

impl SnapshotStream {
    pub fn new(series: Series, rig: &RigConfig, opts: &ImportOptions) -> Result<Self> {
        let mut metadata = std::collections::BTreeMap::new();
        metadata.insert(
            META_CAPTURE_INTERVAL.into(),
            series.times.interval_s.to_string(),
        );
        metadata.insert(
            META_CAPTURE_SERIES.into(),
            format!(
                "{} captures of {} samples every {} s",
                series.files.len(),
                series.capture_len,
                series.times.interval_s
            ),
        );
        crate::importers::stamp_rig(&mut metadata, rig);
        let info = RecordingInfo {
            sample_rate: series.sample_rate,
            start_time_ns: 0,
            channels: series.channels.clone(),
            tacho: TachoInfo::None,
            rpm: opts.rpm,
            provenance: Provenance {
                source_path: series.dir.display().to_string(),
                format: series.format.clone(),
                notes: series.notes.clone(),
            },
            metadata,
        };
        Ok(SnapshotStream {
            series,
            info,
            rig: rig.clone(),
            opts: opts.clone(),
            next: 0,
            prev_end: 0,
        })
    }

    /// The folder's captures.
    pub fn series(&self) -> &Series {
        &self.series
    }

    /// Bytes the whole series takes in memory as f32 samples (every capture as long as the
    /// first).
    pub fn whole_bytes(&self) -> u64 {
        let s = &self.series;
        (s.files.len() * s.capture_len * s.channels.len() * 4) as u64
    }

    /// Where capture `k` starts on the sample clock.
    fn clock_of(&self, k: usize) -> u64 {
        (self.series.times.times_s[k] * self.series.sample_rate).round() as u64
    }
}

impl BlockStream for SnapshotStream {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
    fn duration_hint_s(&self) -> Option<f64> {
        let s = &self.series;
        let last = s.times.times_s.last().copied().unwrap_or(0.0);
        Some(last + s.capture_len as f64 / s.sample_rate)
    }
    fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        let k = self.next;
        if k >= self.series.files.len() {
            return Ok(None);
        }
        let channels = self.series.read(k, &self.rig, &self.opts)?;
        let first = self.clock_of(k);
        if k > 0 && first < self.prev_end {
            bail!(
                "{}: capture {} starts {:.3} s after capture {} ({}) but that one lasts {:.3} s: \
                 captures overlap; check acquisition.capture_interval_s (now {} s)",
                self.series.dir.display(),
                self.series.name(k),
                self.series.times.times_s[k] - self.series.times.times_s[k - 1],
                k - 1,
                self.series.name(k - 1),
                (self.prev_end - self.clock_of(k - 1)) as f64 / self.series.sample_rate,
                self.series.times.interval_s
            );
        }
        self.prev_end = first + channels[0].len() as u64;
        self.next += 1;
        Ok(Some(SampleBlock {
            first_sample: first,
            sample_rate: self.series.sample_rate,
            channels,
            tacho_analog: None,
            tacho_edges: Vec::new(),
        }))
    }
    fn rewind(&mut self) -> Result<()> {
        self.next = 0;
        self.prev_end = 0;
        Ok(())
    }
}

/// Gather a stream of captures into one recording: the samples one capture after the other,
/// and where each starts (a jump of the sample clock starts a new capture) in the metadata.
pub fn collect(stream: &mut dyn BlockStream) -> Result<Recording> {
    let info = stream.info().clone();
    if info.tacho != TachoInfo::None {
        bail!(
            "{}: a series of captures with a tacho is not supported; replay it instead",
            info.provenance.source_path
        );
    }
    let mut channels: Vec<Channel> = info
        .channels
        .iter()
        .map(|c| Channel {
            name: c.name.clone(),
            axis: c.axis.clone(),
            unit: c.unit.clone(),
            samples: Vec::new(),
        })
        .collect();
    let (mut starts, mut origin, mut expect, mut index) = (Vec::new(), None, None, 0u64);
    while let Some(b) = stream.next_block()? {
        let o = *origin.get_or_insert(b.first_sample);
        if expect != Some(b.first_sample) {
            starts.push(CaptureStart {
                index,
                clock: b.first_sample - o,
            });
        }
        for (c, s) in channels.iter_mut().zip(&b.channels) {
            c.samples.extend_from_slice(s);
        }
        index += b.len() as u64;
        expect = Some(b.first_sample + b.len() as u64);
    }
    let mut metadata = info.metadata.clone();
    write_starts(&mut metadata, &starts);
    let mut provenance = info.provenance.clone();
    provenance.notes.extend(stream.notes());
    Ok(Recording {
        sample_rate: info.sample_rate,
        start_time_ns: info.start_time_ns,
        channels,
        tacho: None,
        rpm: info.rpm,
        nominal_rpm: None,
        provenance,
        metadata,
    })
}

/// A rigmon MCAP file written from a series of captures (`rigmon import <folder>`): the
/// stretches of the clock its writer never wrote are the time between captures, not losses.
pub struct RecordedSeries(pub Box<dyn BlockStream>);

impl BlockStream for RecordedSeries {
    fn info(&self) -> &RecordingInfo {
        self.0.info()
    }
    fn duration_hint_s(&self) -> Option<f64> {
        self.0.duration_hint_s()
    }
    fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        self.0.next_block()
    }
    fn rewind(&mut self) -> Result<()> {
        self.0.rewind()
    }
    fn losses(&self) -> Losses {
        let mut l = self.0.losses();
        l.gaps.retain(|g| g.cause != GapCause::NotRecorded);
        l
    }
    fn notes(&self) -> Vec<String> {
        self.0.notes()
    }
}

/// A rigmon MCAP file of a series of captures read whole (capture by capture: the time
/// between them is never filled in), with what could not be read; `None` for any other MCAP
/// file.
pub fn recorded_series(path: &Path, opts: &ImportOptions) -> Result<Option<(Recording, Losses)>> {
    let reader = RecordingReader::open(path)?;
    if !is_capture_series(&reader.info().metadata) {
        return Ok(None);
    }
    let mut inner = McapStream::new(reader)?;
    let mut notes = Vec::new();
    let info = inner.info_mut();
    crate::importers::apply_overrides(&mut info.sample_rate, &mut info.rpm, opts, &mut notes);
    info.provenance.notes.extend(notes);
    let mut s = RecordedSeries(Box::new(inner));
    let mut rec = collect(&mut s)?;
    crate::importers::carry_nominal_rpm(&mut rec, opts);
    let losses = s.losses();
    if !losses.is_empty() {
        tracing::warn!("{}: {}", path.display(), losses.line(rec.sample_rate));
    }
    Ok(Some((rec, losses)))
}
