//! Multi-channel WAV (float32/64, int8/16/24/32 PCM, WAVE_FORMAT_EXTENSIBLE; the header read
//! by [`wav_header`](super::wav_header), which says what a lying header did), read as a stream of blocks
//! ([`WavStream`]: `replay` and `import` hold one block in memory, whatever the file's size) or
//! whole ([`load`]).
//!
//! WAV channels map onto the rig's `channels` in order (acceleration and tacho alike); the
//! counts must match. Integer samples are read as full-scale fractions (-1 .. 1), float samples
//! as they are; both are then multiplied by the channel's `sensitivity` to give `unit`. A tacho
//! channel becomes the analog tacho ([`Tacho::Analog`]).

use super::wav_header::{self, WavHeader};
use super::{check_classifier_names, resolve_sample_rate, ImportOptions};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
use crate::recording::stream::BlockStream;
use crate::recording::{Channel, Provenance, Recording, SampleBlock, Tacho};
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
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
    reader: BufReader<File>,
    path: String,
    header: WavHeader,
    info: RecordingInfo,
    targets: Vec<Target>,
    /// Each WAV channel's `sensitivity`.
    sensitivities: Vec<f32>,
    frames: u64,
    next_frame: u64,
    block: usize,
    scratch: Vec<f64>,
    bytes: Vec<u8>,
}

/// Open a WAV file: check its header against the rig and settle the sample rate.
pub fn open(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<WavStream> {
    let p = path.display();
    let file = File::open(path).map_err(|e| anyhow::anyhow!("{p}: cannot open: {e}"))?;
    let file_len = file.metadata()?.len();
    let mut reader = BufReader::new(file);
    let header = wav_header::read(&mut reader, file_len, &p.to_string())?;
    let n_ch = header.channels;
    if n_ch != rig.channels.len() {
        bail!(
            "{p}: the WAV has {n_ch} channel(s) but the rig file lists {} ({:?}); the rig's `channels` give the WAV channel order",
            rig.channels.len(),
            rig.channel_names()
        );
    }
    let frames = header.frames;
    if frames == 0 {
        bail!("{p}: the WAV holds no samples (its data chunk is empty)");
    }
    let (sample_rate, note) = resolve_sample_rate(
        path,
        Some((f64::from(header.sample_rate), "WAV header".to_string())),
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
    let mut notes = vec![format!("{n_ch}-channel {} WAV", header.format_text), note];
    notes.extend(header.notes.iter().cloned());
    let info = RecordingInfo {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: opts.rpm,
        provenance: Provenance {
            source_path: p.to_string(),
            format: "wav".into(),
            notes,
        },
        metadata: BTreeMap::new(),
    };
    let block = crate::recording::mcap::file_writer::default_block_len(sample_rate);
    reader.seek(SeekFrom::Start(header.data_offset))?;
    Ok(WavStream {
        reader,
        path: p.to_string(),
        sensitivities: rig.channels.iter().map(|c| c.sensitivity as f32).collect(),
        header,
        info,
        targets,
        frames,
        next_frame: 0,
        block,
        scratch: Vec::new(),
        bytes: Vec::new(),
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

    /// Read up to `frames` frames, interleaved, as fractions of full scale (float samples as
    /// they are, before the sensitivity) into `scratch`.
    fn read_frames(&mut self, frames: usize) -> Result<usize> {
        let frames = (frames as u64).min(self.frames - self.next_frame) as usize;
        let fb = self.header.frame_bytes();
        self.bytes.resize(frames * fb, 0);
        if let Err(e) = self.reader.read_exact(&mut self.bytes) {
            bail!(
                "{}: truncated or damaged WAV at frame {}: {e} (the file changed while it was read?)",
                self.path,
                self.next_frame
            );
        }
        self.scratch.clear();
        wav_header::decode(&self.header, &self.bytes, &mut self.scratch);
        Ok(frames)
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
                let mut v = *x as f32;
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
            .seek(SeekFrom::Start(self.header.data_offset))
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
