//! The streaming writer of the rigmon MCAP layout ([`RecordingWriter`]): create with a
//! [`RecordingInfo`], write blocks as they come, flush chunks, finish. Used by the
//! whole-recording writer, the simulator and the daemon's recorder. It writes through an
//! [`McapFile`], so the file on disk is a complete MCAP after every chunk; the definitions
//! (metadata, schemas, channels) sit in their own small first chunk, so damage to a data
//! chunk never takes the channel definitions with it.

use super::codec::{encode_block, encode_edges};
use super::durable_file::{McapFile, McapFileOptions};
use super::layout::*;
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Settings of the streaming writer.
#[derive(Debug, Clone)]
pub struct WriterSettings {
    /// Uncompressed bytes per chunk; a chunk is also closed by [`RecordingWriter::flush`].
    /// Smaller chunks lose less data when the writer is killed.
    pub chunk_size: u64,
    /// zstd level (1..19).
    pub zstd_level: u32,
}

impl Default for WriterSettings {
    fn default() -> Self {
        WriterSettings {
            chunk_size: 512 * 1024,
            zstd_level: 3,
        }
    }
}

/// Streaming writer of the rigmon layout: create, write blocks, finish. Used by
/// [`write_recording`](super::write_recording), the simulator and the daemon's recording sink.
pub struct RecordingWriter {
    file: McapFile,
    sample_rate: f64,
    start_time_ns: u64,
    units: Vec<String>,
    accel_ids: Vec<u16>,
    tacho_unit: Option<String>,
    tacho_analog_id: Option<u16>,
    edges_id: Option<u16>,
    edges_schema: Option<u16>,
    sequence: u32,
    buf: Vec<u8>,
    blocks: u64,
}

impl RecordingWriter {
    /// Create `path` (truncating it) and write the header, schemas and metadata records.
    pub fn create(path: &Path, info: &RecordingInfo) -> Result<Self> {
        Self::create_with(path, info, &WriterSettings::default())
    }

    /// [`create`](Self::create) with explicit settings.
    pub fn create_with(
        path: &Path,
        info: &RecordingInfo,
        settings: &WriterSettings,
    ) -> Result<Self> {
        if !(info.sample_rate.is_finite() && info.sample_rate > 0.0) {
            bail!(
                "{}: sample rate {} Hz is not a positive number",
                path.display(),
                info.sample_rate
            );
        }
        if info.channels.is_empty() {
            bail!(
                "{}: a recording needs at least one acceleration channel",
                path.display()
            );
        }
        let file = McapFile::create(
            path,
            &McapFileOptions {
                chunk_size: settings.chunk_size,
                zstd_level: settings.zstd_level,
                profile: PROFILE.into(),
            },
        )?;
        Self::start(file, info).with_context(|| format!("{}: cannot write MCAP", path.display()))
    }

    fn start(mut file: McapFile, info: &RecordingInfo) -> Result<Self> {
        file.write_metadata(&mcap::records::Metadata {
            name: RECORDING_METADATA.into(),
            metadata: recording_record(info)?,
        })?;
        file.write_metadata(&mcap::records::Metadata {
            name: LABELS_METADATA.into(),
            metadata: info.metadata.clone(),
        })?;
        let block_schema = file.add_schema(
            SAMPLE_BLOCK_SCHEMA,
            ENCODING,
            SAMPLE_BLOCK_LAYOUT.as_bytes(),
        )?;
        let rate = info.sample_rate.to_string();
        let mut accel_ids = Vec::new();
        for c in &info.channels {
            let meta = BTreeMap::from([
                ("name".to_string(), c.name.clone()),
                ("axis".to_string(), c.axis.clone()),
                ("unit".to_string(), c.unit.clone()),
                ("sample_rate_hz".to_string(), rate.clone()),
            ]);
            accel_ids.push(file.add_channel(
                block_schema,
                &format!("{ACCEL_TOPIC_PREFIX}{}", c.name),
                ENCODING,
                &meta,
            )?);
        }
        let (tacho_unit, tacho_analog_id) = match &info.tacho {
            TachoInfo::Analog { unit } => {
                let meta = BTreeMap::from([
                    ("unit".to_string(), unit.clone()),
                    ("sample_rate_hz".to_string(), rate.clone()),
                ]);
                (
                    Some(unit.clone()),
                    Some(file.add_channel(block_schema, TACHO_ANALOG_TOPIC, ENCODING, &meta)?),
                )
            }
            _ => (None, None),
        };
        let mut w = RecordingWriter {
            file,
            sample_rate: info.sample_rate,
            start_time_ns: info.start_time_ns,
            units: info.channels.iter().map(|c| c.unit.clone()).collect(),
            accel_ids,
            tacho_unit,
            tacho_analog_id,
            edges_id: None,
            edges_schema: None,
            sequence: 0,
            buf: Vec::new(),
            blocks: 0,
        };
        if info.tacho == TachoInfo::Edges {
            w.edges_channel()?;
        }
        // The definitions in a chunk of their own, closed by a provisional end.
        w.file.flush()?;
        Ok(w)
    }

    fn edges_channel(&mut self) -> Result<u16> {
        if let Some(id) = self.edges_id {
            return Ok(id);
        }
        let schema = match self.edges_schema {
            Some(s) => s,
            None => {
                self.file
                    .add_schema(TACHO_EDGES_SCHEMA, ENCODING, TACHO_EDGES_LAYOUT.as_bytes())?
            }
        };
        self.edges_schema = Some(schema);
        let meta = BTreeMap::from([("sample_rate_hz".to_string(), self.sample_rate.to_string())]);
        let id = self
            .file
            .add_channel(schema, TACHO_EDGES_TOPIC, ENCODING, &meta)?;
        self.edges_id = Some(id);
        Ok(id)
    }

    fn header(&mut self, channel_id: u16, first_sample: u64) -> mcap::records::MessageHeader {
        let t = self
            .start_time_ns
            .saturating_add((first_sample as f64 / self.sample_rate * 1e9).round() as u64);
        self.sequence = self.sequence.wrapping_add(1);
        mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: t,
            publish_time: t,
        }
    }

    /// Write one block: `channels` in the order given at creation (all the same length),
    /// the analog tacho for the same samples (when the stream has one) and the tacho edges
    /// (seconds since the recording start) that belong to this block.
    pub fn write_block(
        &mut self,
        first_sample: u64,
        channels: &[&[f32]],
        tacho_analog: Option<&[f32]>,
        tacho_edges_s: &[f64],
    ) -> Result<()> {
        if channels.len() != self.accel_ids.len() {
            bail!(
                "write_block: {} channels given, the recording has {}",
                channels.len(),
                self.accel_ids.len()
            );
        }
        let n = channels.first().map_or(0, |c| c.len());
        if let Some(c) = channels.iter().position(|c| c.len() != n) {
            bail!(
                "write_block: channel {c} has {} samples, channel 0 has {n}",
                channels[c].len()
            );
        }
        if n > u32::MAX as usize {
            bail!("write_block: block of {n} samples is too long");
        }
        if n > 0 {
            for (k, samples) in channels.iter().enumerate() {
                let id = self.accel_ids[k];
                let unit = std::mem::take(&mut self.units[k]);
                encode_block(
                    &mut self.buf,
                    first_sample,
                    self.sample_rate,
                    &unit,
                    samples,
                );
                self.units[k] = unit;
                let h = self.header(id, first_sample);
                self.file.write(&h, &self.buf)?;
            }
        }
        match (tacho_analog, self.tacho_analog_id) {
            (Some(t), Some(id)) => {
                if t.len() != n {
                    bail!("write_block: analog tacho has {} samples, the channels have {n}", t.len());
                }
                if n > 0 {
                    let unit = self.tacho_unit.take().unwrap_or_default();
                    encode_block(&mut self.buf, first_sample, self.sample_rate, &unit, t);
                    self.tacho_unit = Some(unit);
                    let h = self.header(id, first_sample);
                    self.file.write(&h, &self.buf)?;
                }
            }
            (Some(_), None) => bail!("write_block: analog tacho samples given but the recording was created without an analog tacho"),
            (None, _) => {}
        }
        if !tacho_edges_s.is_empty() {
            let id = self.edges_channel()?;
            encode_edges(&mut self.buf, first_sample, self.sample_rate, tacho_edges_s);
            let h = self.header(id, first_sample);
            self.file.write(&h, &self.buf)?;
        }
        self.blocks += 1;
        Ok(())
    }

    /// Bytes [`write_block`](Self::write_block) can add to the finished file for a block of
    /// `n` samples with `edges` tacho edges (see [`McapFile::size_bound`]).
    pub fn block_cost(&self, n: usize, analog: bool, edges: usize) -> u64 {
        let unit = self.units.iter().map(String::len).max().unwrap_or(0);
        let unit = unit.max(self.tacho_unit.as_ref().map_or(0, String::len));
        let per_channel = 30 + unit + 4 * n;
        let channels = self.accel_ids.len() + usize::from(analog);
        let mut cost = channels as u64 * McapFile::message_cost(per_channel);
        if edges > 0 {
            cost += McapFile::message_cost(20 + 8 * edges);
        }
        cost
    }

    /// Close the current chunk and flush it to the file: everything written so far survives
    /// a crash.
    pub fn flush(&mut self) -> Result<()> {
        self.file.flush()
    }

    /// The underlying MCAP file, to add channels of other layouts to the same file (the
    /// daemon's recorder adds `/features` and `/health`; readers of this layout skip them).
    pub fn file_mut(&mut self) -> &mut McapFile {
        &mut self.file
    }

    /// Blocks written so far.
    pub fn blocks(&self) -> u64 {
        self.blocks
    }

    /// Write the summary and close the file; its size in bytes.
    pub fn finish(self) -> Result<u64> {
        self.file.finish()
    }

    /// After a failed write: cut the file back to its last complete chunk (see
    /// [`McapFile::abandon`]).
    pub fn abandon(self) -> Result<u64> {
        self.file.abandon()
    }
}
