//! Multi-channel WAV (float32, int8/16/24/32 PCM) via `hound`, read as a stream of blocks
//! ([`WavStream`]: `replay` and `import` hold one block in memory, whatever the file's size) or
//! whole ([`load`]).
//!
//! WAV channels map onto the rig's `channels` in order (acceleration and tacho alike); the
//! counts must match. Integer samples are read as full-scale fractions (-1 .. 1), float samples
//! as they are; both are then multiplied by the channel's `sensitivity` to give `unit`. A tacho
//! channel becomes the analog tacho ([`Tacho::Analog`]).

use super::{check_classifier_names, resolve_sample_rate, ImportOptions};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
use crate::recording::stream::BlockStream;
use crate::recording::{Channel, Provenance, Recording, SampleBlock, Tacho};
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

/// Where a WAV channel goes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    /// Acceleration channel `k` (in the stream's channel order).
    Accel(usize),
    Tacho,
}

/// A WAV file read block by block.
pub struct WavStream {
    reader: hound::WavReader<BufReader<File>>,
    path: String,
    spec: hound::WavSpec,
    info: RecordingInfo,
    targets: Vec<Target>,
    /// Full scale of an integer sample (1 for float), and each WAV channel's `sensitivity`.
    full_scale: f64,
    sensitivities: Vec<f32>,
    frames: u64,
    next_frame: u64,
    block: usize,
    scratch: Vec<f64>,
}

/// Open a WAV file: check its header against the rig and settle the sample rate.
pub fn open(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<WavStream> {
    let p = path.display();
    let reader = hound::WavReader::open(path)
        .map_err(|e| anyhow::anyhow!("{p}: not a readable WAV file: {e}"))?;
    let spec = reader.spec();
    let n_ch = spec.channels as usize;
    if n_ch != rig.channels.len() {
        bail!(
            "{p}: the WAV has {n_ch} channel(s) but the rig file lists {} ({:?}); the rig's `channels` give the WAV channel order",
            rig.channels.len(),
            rig.channel_names()
        );
    }
    let frames = reader.duration() as u64;
    // The header's length is bounded by the file size (hound checks the data chunk).
    let file_len = std::fs::metadata(path)?.len();
    let bytes_per_sample = (spec.bits_per_sample as u64).div_ceil(8).max(1);
    if frames
        .saturating_mul(n_ch as u64)
        .saturating_mul(bytes_per_sample)
        > file_len
    {
        bail!("{p}: truncated: the WAV header announces {frames} frames but the file holds only {file_len} bytes");
    }
    let full_scale = match spec.sample_format {
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                bail!(
                    "{p}: {}-bit float WAV is not supported (use 32-bit float)",
                    spec.bits_per_sample
                );
            }
            1.0
        }
        hound::SampleFormat::Int => {
            let bits = spec.bits_per_sample;
            if !(1..=32).contains(&bits) {
                bail!("{p}: {bits}-bit integer WAV is not supported");
            }
            (1u64 << (bits - 1)) as f64
        }
    };
    if frames == 0 {
        bail!("{p}: the WAV holds no samples");
    }
    let (sample_rate, note) = resolve_sample_rate(
        path,
        Some((spec.sample_rate as f64, "WAV header".to_string())),
        &rig.acquisition,
        opts,
    )?;
    let mut channels = Vec::new();
    let mut targets = Vec::new();
    let mut tacho = TachoInfo::None;
    for cfg in &rig.channels {
        match cfg.kind {
            ChannelKind::Acceleration => {
                targets.push(Target::Accel(channels.len()));
                channels.push(ChannelInfo {
                    name: cfg.name.clone(),
                    axis: cfg.axis.clone(),
                    unit: cfg.unit.to_string(),
                });
            }
            ChannelKind::Tacho => {
                if tacho != TachoInfo::None {
                    bail!("{p}: the rig file lists more than one tacho channel; rigmon uses one");
                }
                targets.push(Target::Tacho);
                tacho = TachoInfo::Analog {
                    unit: cfg.unit.to_string(),
                };
            }
        }
    }
    let names: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
    check_classifier_names(path, rig, &names, "WAV channel")?;
    let format = match spec.sample_format {
        hound::SampleFormat::Float => "float32".to_string(),
        hound::SampleFormat::Int => format!("int{}", spec.bits_per_sample),
    };
    let info = RecordingInfo {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: opts.rpm,
        provenance: Provenance {
            source_path: p.to_string(),
            format: "wav".into(),
            notes: vec![format!("{n_ch}-channel {format} WAV"), note],
        },
        metadata: BTreeMap::new(),
    };
    let block = crate::recording::mcap::file_writer::default_block_len(sample_rate);
    Ok(WavStream {
        reader,
        path: p.to_string(),
        full_scale,
        sensitivities: rig.channels.iter().map(|c| c.sensitivity as f32).collect(),
        spec,
        info,
        targets,
        frames,
        next_frame: 0,
        block,
        scratch: Vec::new(),
    })
}

impl WavStream {
    /// The information, writable (the rig stamp is added by the caller).
    pub fn info_mut(&mut self) -> &mut RecordingInfo {
        &mut self.info
    }

    /// Frames in the file (from its header).
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Read up to `frames` frames, interleaved, as f64 (before scaling) into `scratch`.
    fn read_frames(&mut self, frames: usize) -> Result<usize> {
        let n_ch = self.targets.len();
        let want = frames * n_ch;
        self.scratch.clear();
        let first = self.next_frame;
        let path = &self.path;
        let sample_err = |k: usize, e: hound::Error| {
            anyhow::anyhow!(
                "{path}: truncated or damaged WAV at frame {} (channel {}): {e}",
                first + (k / n_ch) as u64,
                k % n_ch
            )
        };
        match self.spec.sample_format {
            hound::SampleFormat::Float => {
                for (k, s) in self.reader.samples::<f32>().take(want).enumerate() {
                    self.scratch.push(s.map_err(|e| sample_err(k, e))? as f64);
                }
            }
            hound::SampleFormat::Int => {
                for (k, s) in self.reader.samples::<i32>().take(want).enumerate() {
                    self.scratch.push(s.map_err(|e| sample_err(k, e))? as f64);
                }
            }
        }
        let got = self.scratch.len();
        if got % n_ch != 0 {
            bail!(
                "{path}: truncated: the data ends in the middle of a frame ({} samples for {n_ch} channels)",
                self.next_frame * n_ch as u64 + got as u64
            );
        }
        Ok(got / n_ch)
    }
}

impl BlockStream for WavStream {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }

    fn duration_hint_s(&self) -> Option<f64> {
        Some(self.frames as f64 / self.info.sample_rate)
    }

    fn exact_len(&self) -> Option<u64> {
        Some(self.frames)
    }

    fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        let frames = self.read_frames(self.block)?;
        if frames == 0 {
            return Ok(None);
        }
        let n_acc = self.info.channels.len();
        let mut channels = vec![Vec::with_capacity(frames); n_acc];
        let mut tacho = match self.info.tacho {
            TachoInfo::Analog { .. } => Some(Vec::with_capacity(frames)),
            _ => None,
        };
        for frame in self.scratch.chunks_exact(self.targets.len()) {
            for ((x, target), &sens) in frame.iter().zip(&self.targets).zip(&self.sensitivities) {
                // As fractions of full scale, then times the sensitivity (in f32).
                let mut v = (x / self.full_scale) as f32;
                if sens != 1.0 {
                    v *= sens;
                }
                match target {
                    Target::Accel(k) => channels[*k].push(v),
                    Target::Tacho => tacho.get_or_insert_with(Vec::new).push(v),
                }
            }
        }
        let first = self.next_frame;
        self.next_frame += frames as u64;
        // Float WAVs can hold NaN/Inf: refused, naming the channel and the sample.
        for (c, samples) in channels.iter().enumerate() {
            if let Some(i) = samples.iter().position(|x| !x.is_finite()) {
                let k = first + i as u64;
                bail!(
                    "{}: channel {:?}: sample {k} (t = {:.6} s) is {}; recordings must hold finite numbers only",
                    self.path,
                    self.info.channels[c].name,
                    k as f64 / self.info.sample_rate,
                    samples[i]
                );
            }
        }
        if let Some(i) = tacho
            .as_ref()
            .and_then(|t| t.iter().position(|x| !x.is_finite()))
        {
            let k = first + i as u64;
            bail!(
                "{}: tacho channel: sample {k} (t = {:.6} s) is {}; recordings must hold finite numbers only",
                self.path,
                k as f64 / self.info.sample_rate,
                tacho.as_ref().map_or(0.0, |t| t[i])
            );
        }
        Ok(Some(SampleBlock {
            first_sample: first,
            sample_rate: self.info.sample_rate,
            channels,
            tacho_analog: tacho,
            tacho_edges: Vec::new(),
        }))
    }

    fn rewind(&mut self) -> Result<()> {
        self.reader
            .seek(0)
            .map_err(|e| anyhow::anyhow!("{}: cannot go back to the start: {e}", self.path))?;
        self.next_frame = 0;
        Ok(())
    }
}

/// Read a WAV file whole into a [`Recording`].
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let mut s = open(path, rig, opts)?;
    let n = s.frames() as usize;
    let mut cols: Vec<Vec<f32>> = (0..s.info.channels.len())
        .map(|_| Vec::with_capacity(n))
        .collect();
    let mut tacho: Option<Vec<f32>> = None;
    while let Some(b) = s.next_block()? {
        for (col, part) in cols.iter_mut().zip(b.channels) {
            col.extend_from_slice(&part);
        }
        if let Some(t) = b.tacho_analog {
            tacho
                .get_or_insert_with(|| Vec::with_capacity(n))
                .extend_from_slice(&t);
        }
    }
    if cols.first().is_none_or(Vec::is_empty) && tacho.as_ref().is_none_or(Vec::is_empty) {
        bail!("{}: the WAV holds no samples", path.display());
    }
    let info = s.info;
    Ok(Recording {
        sample_rate: info.sample_rate,
        start_time_ns: 0,
        channels: info
            .channels
            .iter()
            .zip(cols)
            .map(|(c, samples)| Channel {
                name: c.name.clone(),
                axis: c.axis.clone(),
                unit: c.unit.clone(),
                samples,
            })
            .collect(),
        tacho: match &info.tacho {
            TachoInfo::Analog { unit } => Some(Tacho::Analog {
                samples: tacho.unwrap_or_default(),
                unit: unit.clone(),
            }),
            _ => None,
        },
        rpm: info.rpm,
        nominal_rpm: None,
        provenance: info.provenance,
        metadata: info.metadata,
    })
}
