//! The rigmon MCAP layout: how a [`Recording`](super::Recording) is stored in an MCAP file.
//! (Owned by the importers; documented in the README.)
//!
//! Profile `rigmon`, zstd chunks. All message payloads are little-endian binary with message
//! encoding [`ENCODING`] (`rigmon-le`); each schema's data is a UTF-8 text copy of its layout
//! table, so a file documents itself.
//!
//! | topic | schema | one message = |
//! |---|---|---|
//! | `/accel/<channel name>` | `rigmon.SampleBlock` | a block of consecutive samples of one acceleration channel |
//! | `/tacho/analog` | `rigmon.SampleBlock` | a block of the analog tacho voltage, same clock as the channels |
//! | `/tacho/edges` | `rigmon.TachoEdges` | the tacho edge times delivered with one block |
//!
//! `rigmon.SampleBlock`: `u64 first_sample` (sample index since the recording start),
//! `f64 t0_s` (= first_sample / sample_rate_hz), `f64 sample_rate_hz`, `u32 n`,
//! `u16 unit_len`, `unit_len` bytes UTF-8 unit, then `n` x `f32` samples in that unit.
//!
//! `rigmon.TachoEdges`: `u64 first_sample` (of the block they came with), `f64 sample_rate_hz`,
//! `u32 n`, then `n` x `f64` edge times in seconds since the recording start.
//!
//! Two MCAP Metadata records, written before any chunk (so a file cut short keeps them):
//! `rigmon.recording` (layout_version, sample_rate_hz, start_time_ns, rpm, channels as JSON,
//! tacho kind and unit, provenance as JSON) and `rigmon.metadata` (the recording's metadata map
//! verbatim: `label`, ..., and `rig_id`/`rig_config` (rig TOML) when an importer set them).
//!
//! Message log/publish time = start_time_ns + first_sample / sample_rate_hz in ns.
//!
//! Reading tolerates a file cut short (kill -9) or damaged: every complete chunk whose CRC
//! checks is used, reading stops at the first bad one, and a provenance note says so. Gaps on the sample clock (lost blocks) are filled
//! with zeros and noted.

use super::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

/// MCAP profile written in the header.
pub const PROFILE: &str = "rigmon";
/// Version of this layout (in `rigmon.recording`).
pub const LAYOUT_VERSION: &str = "1";
/// Message encoding and schema encoding of every rigmon channel.
pub const ENCODING: &str = "rigmon-le";
pub const SAMPLE_BLOCK_SCHEMA: &str = "rigmon.SampleBlock";
pub const TACHO_EDGES_SCHEMA: &str = "rigmon.TachoEdges";
pub const ACCEL_TOPIC_PREFIX: &str = "/accel/";
pub const TACHO_ANALOG_TOPIC: &str = "/tacho/analog";
pub const TACHO_EDGES_TOPIC: &str = "/tacho/edges";
/// Name of the metadata record describing the recording.
pub const RECORDING_METADATA: &str = "rigmon.recording";
/// Name of the metadata record holding the recording's key/value metadata (labels...).
pub const LABELS_METADATA: &str = "rigmon.metadata";

/// Schema data of `rigmon.SampleBlock` (a text copy of the layout).
pub const SAMPLE_BLOCK_LAYOUT: &str = "rigmon.SampleBlock (little-endian)\n\
offset      type        field\n\
0           u64         first_sample     index of the first sample since the recording start\n\
8           f64         t0_s             first_sample / sample_rate_hz, seconds\n\
16          f64         sample_rate_hz\n\
24          u32         n                number of samples\n\
28          u16         unit_len\n\
30          u8[unit_len] unit            UTF-8, e.g. m/s^2, g, V\n\
30+unit_len f32[n]      samples          in unit\n";

/// Schema data of `rigmon.TachoEdges`.
pub const TACHO_EDGES_LAYOUT: &str = "rigmon.TachoEdges (little-endian)\n\
offset  type    field\n\
0       u64     first_sample     first sample of the block these edges came with\n\
8       f64     sample_rate_hz\n\
16      u32     n                number of edges\n\
20      f64[n]  times_s          edge times, seconds since the recording start\n";

/// Largest record (or decompressed chunk) the reader accepts, bytes: a damaged length field
/// gives an error instead of a huge allocation (the reader allocates a chunk's declared
/// uncompressed size up front). Writers close chunks at 512 KiB; blocks are ~0.1 s.
const MAX_RECORD_BYTES: usize = 64 << 20;
/// Lost blocks are zero-filled, up to this many times the samples a stream really holds ...
const MAX_FILL_RATIO: u64 = 16;
/// ... plus this many samples.
const MAX_FILL_EXTRA: u64 = 1 << 20;

/// Samples per message when [`write_recording`] splits a recording into blocks: about 0.1 s.
fn default_block_len(sample_rate: f64) -> usize {
    ((sample_rate * 0.1).round() as usize).clamp(64, 1 << 16)
}

/// Name, axis and unit of one acceleration channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelInfo {
    pub name: String,
    #[serde(default)]
    pub axis: String,
    pub unit: String,
}

/// The kind of speed reference a stream carries.
#[derive(Debug, Clone, PartialEq)]
pub enum TachoInfo {
    None,
    /// Analog voltage in `unit`, on the sample clock.
    Analog {
        unit: String,
    },
    /// Edge times.
    Edges,
}

/// Everything about a recording except its samples: what the streaming writer needs up front.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingInfo {
    pub sample_rate: f64,
    pub start_time_ns: u64,
    pub channels: Vec<ChannelInfo>,
    pub tacho: TachoInfo,
    pub rpm: Option<f64>,
    pub provenance: Provenance,
    pub metadata: BTreeMap<String, String>,
}

impl RecordingInfo {
    /// The description of an in-memory recording.
    pub fn of(rec: &Recording) -> Self {
        RecordingInfo {
            sample_rate: rec.sample_rate,
            start_time_ns: rec.start_time_ns,
            channels: rec
                .channels
                .iter()
                .map(|c| ChannelInfo {
                    name: c.name.clone(),
                    axis: c.axis.clone(),
                    unit: c.unit.clone(),
                })
                .collect(),
            tacho: match &rec.tacho {
                None => TachoInfo::None,
                Some(Tacho::Analog { unit, .. }) => TachoInfo::Analog { unit: unit.clone() },
                Some(Tacho::Edges { .. }) => TachoInfo::Edges,
            },
            rpm: rec.rpm,
            provenance: rec.provenance.clone(),
            metadata: rec.metadata.clone(),
        }
    }
}

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
/// [`write_recording`], the simulator and the daemon's recording sink.
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

fn encode_block(buf: &mut Vec<u8>, first_sample: u64, fs: f64, unit: &str, samples: &[f32]) {
    buf.clear();
    buf.reserve(30 + unit.len() + 4 * samples.len());
    buf.extend_from_slice(&first_sample.to_le_bytes());
    buf.extend_from_slice(&(first_sample as f64 / fs).to_le_bytes());
    buf.extend_from_slice(&fs.to_le_bytes());
    buf.extend_from_slice(&(samples.len() as u32).to_le_bytes());
    let unit = &unit.as_bytes()[..unit.len().min(u16::MAX as usize)];
    buf.extend_from_slice(&(unit.len() as u16).to_le_bytes());
    buf.extend_from_slice(unit);
    for x in samples {
        buf.extend_from_slice(&x.to_le_bytes());
    }
}

fn encode_edges(buf: &mut Vec<u8>, first_sample: u64, fs: f64, times: &[f64]) {
    buf.clear();
    buf.extend_from_slice(&first_sample.to_le_bytes());
    buf.extend_from_slice(&fs.to_le_bytes());
    buf.extend_from_slice(&(times.len() as u32).to_le_bytes());
    for t in times {
        buf.extend_from_slice(&t.to_le_bytes());
    }
}

/// A decoded `rigmon.SampleBlock`.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedBlock {
    pub first_sample: u64,
    pub t0_s: f64,
    pub sample_rate_hz: f64,
    pub unit: String,
    pub samples: Vec<f32>,
}

fn le<const N: usize>(b: &[u8], at: usize) -> Option<[u8; N]> {
    b.get(at..at + N).map(|s| s.try_into().unwrap())
}

/// Decode a `rigmon.SampleBlock` payload.
pub fn decode_block(b: &[u8]) -> Result<DecodedBlock> {
    let short = || {
        anyhow::anyhow!(
            "SampleBlock of {} bytes is shorter than its header",
            b.len()
        )
    };
    let first_sample = u64::from_le_bytes(le(b, 0).ok_or_else(short)?);
    let t0_s = f64::from_le_bytes(le(b, 8).ok_or_else(short)?);
    let sample_rate_hz = f64::from_le_bytes(le(b, 16).ok_or_else(short)?);
    let n = u32::from_le_bytes(le(b, 24).ok_or_else(short)?) as usize;
    let unit_len = u16::from_le_bytes(le(b, 28).ok_or_else(short)?) as usize;
    let data = 30 + unit_len;
    if b.len() != data + 4 * n {
        bail!("SampleBlock at sample {first_sample}: {} bytes, but n = {n} and unit_len = {unit_len} need {}", b.len(), data + 4 * n);
    }
    let unit = String::from_utf8_lossy(&b[30..data]).into_owned();
    let samples = b[data..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    Ok(DecodedBlock {
        first_sample,
        t0_s,
        sample_rate_hz,
        unit,
        samples,
    })
}

/// Decode a `rigmon.TachoEdges` payload: (first_sample, sample_rate_hz, edge times).
pub fn decode_edges(b: &[u8]) -> Result<(u64, f64, Vec<f64>)> {
    let short = || anyhow::anyhow!("TachoEdges of {} bytes is shorter than its header", b.len());
    let first_sample = u64::from_le_bytes(le(b, 0).ok_or_else(short)?);
    let fs = f64::from_le_bytes(le(b, 8).ok_or_else(short)?);
    let n = u32::from_le_bytes(le(b, 16).ok_or_else(short)?) as usize;
    if b.len() != 20 + 8 * n {
        bail!(
            "TachoEdges at sample {first_sample}: {} bytes, but n = {n} needs {}",
            b.len(),
            20 + 8 * n
        );
    }
    Ok((
        first_sample,
        fs,
        b[20..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect(),
    ))
}

fn recording_record(info: &RecordingInfo) -> Result<BTreeMap<String, String>> {
    let mut m = BTreeMap::new();
    m.insert("layout_version".into(), LAYOUT_VERSION.into());
    m.insert("sample_rate_hz".into(), info.sample_rate.to_string());
    m.insert("start_time_ns".into(), info.start_time_ns.to_string());
    if let Some(rpm) = info.rpm {
        m.insert("rpm".into(), rpm.to_string());
    }
    m.insert("channels".into(), serde_json::to_string(&info.channels)?);
    let (kind, unit) = match &info.tacho {
        TachoInfo::None => ("none", None),
        TachoInfo::Analog { unit } => ("analog", Some(unit.clone())),
        TachoInfo::Edges => ("edges", None),
    };
    m.insert("tacho".into(), kind.into());
    if let Some(u) = unit {
        m.insert("tacho_unit".into(), u);
    }
    m.insert(
        "provenance".into(),
        serde_json::to_string(&info.provenance)?,
    );
    Ok(m)
}

/// Write a whole recording (blocks of ~0.1 s).
pub fn write_recording(path: &Path, rec: &Recording) -> Result<()> {
    let mut w = RecordingWriter::create(path, &RecordingInfo::of(rec))?;
    let n = rec.len();
    if let Some(c) = rec.channels.iter().find(|c| c.samples.len() != n) {
        bail!(
            "{}: channel {:?} has {} samples but {:?} has {n}",
            path.display(),
            c.name,
            c.samples.len(),
            rec.channels[0].name
        );
    }
    let analog = match &rec.tacho {
        Some(Tacho::Analog { samples, .. }) => {
            if samples.len() != n {
                bail!(
                    "{}: the analog tacho has {} samples but the channels have {n}",
                    path.display(),
                    samples.len()
                );
            }
            Some(samples.as_slice())
        }
        _ => None,
    };
    let edges: &[f64] = match &rec.tacho {
        Some(Tacho::Edges { times_s }) => times_s,
        _ => &[],
    };
    let block = default_block_len(rec.sample_rate);
    let mut e = 0;
    let mut start = 0;
    let mut slices: Vec<&[f32]> = Vec::with_capacity(rec.channels.len());
    while start < n {
        let end = (start + block).min(n);
        slices.clear();
        slices.extend(rec.channels.iter().map(|c| &c.samples[start..end]));
        // Edges up to the end of this block (the last block takes all that remain).
        let t_end = end as f64 / rec.sample_rate;
        let e0 = e;
        while e < edges.len() && (edges[e] < t_end || end == n) {
            e += 1;
        }
        w.write_block(
            start as u64,
            &slices,
            analog.map(|a| &a[start..end]),
            &edges[e0..e],
        )
        .with_context(|| format!("{}: writing block at sample {start}", path.display()))?;
        start = end;
    }
    if n == 0 && !edges.is_empty() {
        w.write_block(0, &vec![&[][..]; rec.channels.len()], analog, edges)?;
    }
    w.finish()
        .with_context(|| format!("{}: finishing MCAP", path.display()))
}

/// Read a rigmon MCAP file. A file cut short yields everything up to its last complete chunk
/// (with a provenance note).
pub fn read_recording(path: &Path) -> Result<Recording> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    read_recording_bytes(&bytes).with_context(|| format!("{}", path.display()))
}

struct Stream {
    blocks: Vec<(u64, Vec<f32>)>,
}

/// The `mcap` crate allocates a string's or map's declared length before reading it, so a
/// damaged length prefix could ask for gigabytes (found by fuzzing). Check every length prefix
/// of the records [`read_recording_bytes`] parses (Schema, Channel, Metadata) against the
/// record's own size first.
fn lengths_fit(opcode: u8, d: &[u8]) -> std::result::Result<(), String> {
    fn skip(d: &[u8], at: &mut usize, n: usize) -> bool {
        match at.checked_add(n) {
            Some(e) if e <= d.len() => {
                *at = e;
                true
            }
            _ => false,
        }
    }
    fn len(d: &[u8], at: &mut usize) -> Option<usize> {
        let b = d.get(*at..*at + 4)?;
        *at += 4;
        Some(u32::from_le_bytes(b.try_into().unwrap()) as usize)
    }
    fn string(d: &[u8], at: &mut usize) -> bool {
        len(d, at).is_some_and(|n| skip(d, at, n))
    }
    fn map(d: &[u8], at: &mut usize) -> bool {
        let Some(n) = len(d, at) else { return false };
        let end = match at.checked_add(n) {
            Some(e) if e <= d.len() => e,
            _ => return false,
        };
        while *at < end {
            if !(string(d, at) && string(d, at)) {
                return false;
            }
        }
        *at == end
    }
    let mut at = 0;
    use mcap::records::op;
    let ok = match opcode {
        // Schema: id, name, encoding, data.
        op::SCHEMA => {
            skip(d, &mut at, 2) && string(d, &mut at) && string(d, &mut at) && string(d, &mut at)
        }
        // Channel: id, schema id, topic, message encoding, metadata.
        op::CHANNEL => {
            skip(d, &mut at, 4) && string(d, &mut at) && string(d, &mut at) && map(d, &mut at)
        }
        // Metadata: name, metadata.
        op::METADATA => string(d, &mut at) && map(d, &mut at),
        _ => true,
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "record (opcode 0x{opcode:02x}, {} bytes) declares a field longer than itself",
            d.len()
        ))
    }
}

/// The offset of the first uncompressed chunk whose inner records overrun the chunk, with a
/// reason. `mcap` 0.26's reader panics on such a chunk (an unchecked subtraction, found by
/// fuzzing), so the bytes from there on are treated like a file cut short.
fn first_overrunning_chunk(bytes: &[u8]) -> Option<(usize, String)> {
    let u64_at = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(
            bytes.get(at..at.checked_add(8)?)?.try_into().unwrap(),
        ))
    };
    let u32_at = |at: usize| -> Option<u32> {
        Some(u32::from_le_bytes(
            bytes.get(at..at.checked_add(4)?)?.try_into().unwrap(),
        ))
    };
    let mut at = mcap::MAGIC.len();
    while at < bytes.len() {
        let op = bytes[at];
        let len = usize::try_from(u64_at(at + 1)?).ok()?;
        let body = at + 9;
        let end = body.checked_add(len)?;
        if end > bytes.len() {
            return None; // cut short: the reader reports it
        }
        if op == mcap::records::op::CHUNK {
            // start time, end time, uncompressed size, uncompressed crc, compression, records
            let c_len = u32_at(body + 28)? as usize;
            let recs_len_at = (body + 32).checked_add(c_len)?;
            let recs_len = usize::try_from(u64_at(recs_len_at)?).ok()?;
            let recs = recs_len_at + 8;
            if c_len == 0 && recs.checked_add(recs_len).is_some_and(|e| e <= end) {
                let mut r = 0usize;
                while r < recs_len {
                    let inner = u64_at(recs + r + 1).filter(|_| r + 9 <= recs_len);
                    match inner.and_then(|l| usize::try_from(l).ok()) {
                        Some(l) if l <= recs_len - r - 9 => r += 9 + l,
                        _ => {
                            return Some((
                                at,
                                format!(
                                    "chunk at byte {at}: a record inside overruns the chunk's \
                                     {recs_len} bytes"
                                ),
                            ))
                        }
                    }
                }
            }
        }
        at = end;
    }
    None
}

/// [`read_recording`] from bytes in memory.
pub fn read_recording_bytes(bytes: &[u8]) -> Result<Recording> {
    if bytes.is_empty() {
        bail!("the file is empty (0 bytes)");
    }
    if !bytes.starts_with(mcap::MAGIC) {
        bail!("not an MCAP file (no MCAP magic at the start)");
    }
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut topics: BTreeMap<u16, (String, u16)> = BTreeMap::new();
    let mut metadata: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    let mut streams: BTreeMap<String, Stream> = BTreeMap::new();
    let mut edges: Vec<f64> = Vec::new();
    let mut cut_short: Option<String> = None;
    let mut seen_footer = false;
    // The sans-io reader, with every chunk decompressed and its CRC checked before any of its
    // records is used: a chunk cut short (or damaged) contributes nothing.
    let mut reader = mcap::sans_io::LinearReader::new_with_options(
        mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    let mut rest = bytes;
    if let Some((at, why)) = first_overrunning_chunk(bytes) {
        cut_short = Some(why);
        rest = &bytes[..at];
    }
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event {
            Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                let len = need.min(rest.len());
                reader.insert(len).copy_from_slice(&rest[..len]);
                reader.notify_read(len);
                rest = &rest[len..];
                continue;
            }
            Ok(mcap::sans_io::LinearReadEvent::Record { opcode, data }) => (opcode, data),
            Err(e) => {
                cut_short.get_or_insert(e.to_string());
                break;
            }
        };
        // Only the records this reader uses are parsed (others cannot stop the read).
        use mcap::records::op;
        if !matches!(
            opcode,
            op::FOOTER | op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA
        ) {
            continue;
        }
        if let Err(e) = lengths_fit(opcode, data) {
            cut_short.get_or_insert(e);
            break;
        }
        let rec = match mcap::parse_record(opcode, data) {
            Ok(r) => r,
            Err(e) => {
                cut_short.get_or_insert(e.to_string());
                break;
            }
        };
        use mcap::records::Record;
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                topics.insert(c.id, (c.topic, c.schema_id));
            }
            Record::Metadata(m) => {
                metadata.insert(m.name, m.metadata);
            }
            Record::Message { header, data } => {
                let Some((topic, schema_id)) = topics.get(&header.channel_id) else {
                    bail!("message on unknown channel id {}", header.channel_id);
                };
                let schema = schemas.get(schema_id).map(String::as_str).unwrap_or("");
                if schema == SAMPLE_BLOCK_SCHEMA {
                    let b = decode_block(&data).with_context(|| format!("topic {topic}"))?;
                    streams
                        .entry(topic.clone())
                        .or_insert_with(|| Stream { blocks: Vec::new() })
                        .blocks
                        .push((b.first_sample, b.samples));
                } else if schema == TACHO_EDGES_SCHEMA {
                    let (_, _, t) =
                        decode_edges(&data).with_context(|| format!("topic {topic}"))?;
                    edges.extend(t);
                }
            }
            Record::Footer(_) => seen_footer = true,
            _ => {}
        }
    }
    let Some(info) = metadata.get(RECORDING_METADATA) else {
        match cut_short {
            Some(e) => bail!(
                "truncated or damaged before the `{RECORDING_METADATA}` metadata record ({e})"
            ),
            None => bail!("not a rigmon recording: no `{RECORDING_METADATA}` metadata record"),
        }
    };
    let get = |k: &str| {
        info.get(k)
            .with_context(|| format!("`{RECORDING_METADATA}` record lacks `{k}`"))
    };
    let version = get("layout_version")?;
    if version != LAYOUT_VERSION {
        bail!("rigmon MCAP layout version {version} is not supported (this rigmon reads version {LAYOUT_VERSION})");
    }
    let sample_rate: f64 = get("sample_rate_hz")?.parse().context("sample_rate_hz")?;
    let start_time_ns: u64 = get("start_time_ns")?.parse().context("start_time_ns")?;
    let rpm = info
        .get("rpm")
        .map(|s| s.parse::<f64>())
        .transpose()
        .context("rpm")?;
    let infos: Vec<ChannelInfo> = serde_json::from_str(get("channels")?).context("channels")?;
    let mut provenance: Provenance =
        serde_json::from_str(get("provenance")?).context("provenance")?;
    let tacho_kind = info.get("tacho").map(String::as_str).unwrap_or("none");
    let labels = metadata.get(LABELS_METADATA).cloned().unwrap_or_default();
    if let Some(e) = &cut_short {
        provenance.notes.push(format!(
            "MCAP file cut short or damaged ({e}); read up to its last complete, intact chunk"
        ));
    } else if !seen_footer {
        provenance
            .notes
            .push("MCAP file has no footer (not finished); read all complete chunks".into());
    }

    // Assemble each stream on the sample clock; gaps are zero-filled.
    let mut assemble = |topic: &str, notes: &mut Vec<String>| -> Result<Vec<f32>> {
        let Some(mut s) = streams.remove(topic) else {
            return Ok(Vec::new());
        };
        s.blocks.sort_by_key(|b| b.0);
        let total = s
            .blocks
            .last()
            .map_or(0, |(f, v)| f.saturating_add(v.len() as u64));
        // Zero-filling is for lost blocks; a damaged first_sample must not make a tiny file
        // claim gigabytes (found by fuzzing).
        let present: u64 = s.blocks.iter().map(|(_, v)| v.len() as u64).sum();
        let fill_limit = present.saturating_mul(MAX_FILL_RATIO) + MAX_FILL_EXTRA;
        if total - present.min(total) > fill_limit {
            bail!(
                "{topic}: a block starts at sample {} but only {present} samples are recorded: \
                 filling the gap with zeros would exceed {fill_limit} samples; the file is damaged",
                s.blocks.last().map_or(0, |b| b.0)
            );
        }
        let mut out = Vec::with_capacity(total as usize);
        for (first, v) in s.blocks {
            let first = first as usize;
            if first < out.len() {
                bail!(
                    "{topic}: blocks overlap at sample {first} (already have {} samples)",
                    out.len()
                );
            }
            if first > out.len() {
                notes.push(format!(
                    "{topic}: {} samples missing before sample {first}, filled with zeros",
                    first - out.len()
                ));
                out.resize(first, 0.0);
            }
            out.extend_from_slice(&v);
        }
        Ok(out)
    };
    let mut notes = Vec::new();
    let mut channels = Vec::new();
    for c in &infos {
        let samples = assemble(&format!("{ACCEL_TOPIC_PREFIX}{}", c.name), &mut notes)?;
        channels.push(Channel {
            name: c.name.clone(),
            axis: c.axis.clone(),
            unit: c.unit.clone(),
            samples,
        });
    }
    let mut analog = if tacho_kind == "analog" {
        Some(assemble(TACHO_ANALOG_TOPIC, &mut notes)?)
    } else {
        None
    };
    // Equal lengths: a file cut short may end channels at different blocks.
    let mut n = channels.iter().map(|c| c.samples.len()).min().unwrap_or(0);
    if let Some(a) = &analog {
        n = n.min(a.len());
    }
    let longest = channels
        .iter()
        .map(|c| c.samples.len())
        .chain(analog.as_ref().map(Vec::len))
        .max()
        .unwrap_or(0);
    if longest != n {
        notes.push(format!(
            "channels end at different samples (shortest {n}, longest {longest}); all cut to {n}"
        ));
        channels.iter_mut().for_each(|c| c.samples.truncate(n));
        if let Some(a) = analog.as_mut() {
            a.truncate(n);
        }
    }
    if n == 0 {
        match cut_short {
            Some(e) => bail!("cut short before the first complete chunk of samples ({e})"),
            None => bail!("the recording holds no samples"),
        }
    }
    provenance.notes.extend(notes);
    let tacho = match tacho_kind {
        "analog" => Some(Tacho::Analog {
            samples: analog.unwrap_or_default(),
            unit: info.get("tacho_unit").cloned().unwrap_or_default(),
        }),
        "edges" => {
            edges.sort_by(f64::total_cmp);
            if cut_short.is_some() {
                let t_end = n as f64 / sample_rate;
                edges.retain(|&t| t < t_end);
            }
            Some(Tacho::Edges { times_s: edges })
        }
        _ => None,
    };
    Ok(Recording {
        sample_rate,
        start_time_ns,
        channels,
        tacho,
        rpm,
        provenance,
        metadata: labels,
    })
}
