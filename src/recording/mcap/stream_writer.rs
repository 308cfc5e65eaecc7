//! The streaming writer of the rigmon MCAP layout ([`RecordingWriter`]): create with a
//! [`RecordingInfo`], write blocks as they come, flush chunks, finish. Used by the
//! whole-recording writer, the simulator and the daemon's recorder.

use super::codec::{encode_block, encode_edges};
use super::layout::*;
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
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
pub struct RecordingWriter<W: Write + Seek = BufWriter<File>> {
    mcap: mcap::Writer<W>,
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

impl RecordingWriter<BufWriter<File>> {
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
        let f = File::create(path).with_context(|| format!("{}: cannot create", path.display()))?;
        Self::new(BufWriter::with_capacity(1 << 16, f), info, settings)
            .with_context(|| format!("{}: cannot write MCAP", path.display()))
    }
}

impl<W: Write + Seek> RecordingWriter<W> {
    /// Start a rigmon MCAP on any seekable writer.
    pub fn new(w: W, info: &RecordingInfo, settings: &WriterSettings) -> Result<Self> {
        if !(info.sample_rate.is_finite() && info.sample_rate > 0.0) {
            bail!(
                "sample rate {} Hz is not a positive number",
                info.sample_rate
            );
        }
        if info.channels.is_empty() {
            bail!("a recording needs at least one acceleration channel");
        }
        let mut mcap = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(concat!("rigmon ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(settings.zstd_level)
            .chunk_size(Some(settings.chunk_size))
            .create(w)?;
        mcap.write_metadata(&mcap::records::Metadata {
            name: RECORDING_METADATA.into(),
            metadata: recording_record(info)?,
        })?;
        mcap.write_metadata(&mcap::records::Metadata {
            name: LABELS_METADATA.into(),
            metadata: info.metadata.clone(),
        })?;
        let block_schema = mcap.add_schema(
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
            accel_ids.push(mcap.add_channel(
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
                    Some(mcap.add_channel(block_schema, TACHO_ANALOG_TOPIC, ENCODING, &meta)?),
                )
            }
            _ => (None, None),
        };
        let mut w = RecordingWriter {
            mcap,
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
        Ok(w)
    }

    fn edges_channel(&mut self) -> Result<u16> {
        if let Some(id) = self.edges_id {
            return Ok(id);
        }
        let schema = match self.edges_schema {
            Some(s) => s,
            None => {
                self.mcap
                    .add_schema(TACHO_EDGES_SCHEMA, ENCODING, TACHO_EDGES_LAYOUT.as_bytes())?
            }
        };
        self.edges_schema = Some(schema);
        let meta = BTreeMap::from([("sample_rate_hz".to_string(), self.sample_rate.to_string())]);
        let id = self
            .mcap
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
                self.mcap.write_to_known_channel(&h, &self.buf)?;
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
                    self.mcap.write_to_known_channel(&h, &self.buf)?;
                }
            }
            (Some(_), None) => bail!("write_block: analog tacho samples given but the recording was created without an analog tacho"),
            (None, _) => {}
        }
        if !tacho_edges_s.is_empty() {
            let id = self.edges_channel()?;
            encode_edges(&mut self.buf, first_sample, self.sample_rate, tacho_edges_s);
            let h = self.header(id, first_sample);
            self.mcap.write_to_known_channel(&h, &self.buf)?;
        }
        self.blocks += 1;
        Ok(())
    }

    /// Close the current chunk and flush it to the file: everything written so far survives
    /// a crash.
    pub fn flush(&mut self) -> Result<()> {
        self.mcap.flush()?;
        Ok(())
    }

    /// The underlying MCAP writer, to add channels of other layouts to the same file (the
    /// daemon's recorder adds `/features` and `/health`; readers of this layout skip them).
    pub fn mcap_mut(&mut self) -> &mut mcap::Writer<W> {
        &mut self.mcap
    }

    /// Blocks written so far.
    pub fn blocks(&self) -> u64 {
        self.blocks
    }

    /// Write the summary and close the file.
    pub fn finish(mut self) -> Result<()> {
        self.mcap.finish()?;
        Ok(())
    }
}
