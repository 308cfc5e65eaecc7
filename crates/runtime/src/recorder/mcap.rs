//! The rotating MCAP recorder (see the module above for the file layout). It runs on the
//! recording thread and is fed [`RecordEvent`]s; every error is counted and logged, and the
//! recorder retries with a fresh segment after `retry_s` instead of giving up. A segment is
//! closed before a write would take it past `max_file_mb` (an upper bound of the finished
//! file's size is kept, [`McapFile::size_bound`]); a segment whose write failed is cut back to
//! its last complete chunk, or removed when it holds none (no empty files on retry).

use super::RecordConfig;
use crate::recording::mcap::{
    McapFile, McapFileOptions, RecordingInfo, RecordingWriter, WriterSettings,
};
use crate::recording::SampleBlock;
use crate::wire::status::RecordStats;
use anyhow::{Context, Result};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What the pipeline hands the recorder.
#[derive(Debug, Clone)]
pub enum RecordEvent {
    /// Raw samples as they came from the source (shared with the pipeline, not copied).
    Block(Arc<SampleBlock>),
    /// A feature window (JSON) ending at `t_ns` (ns since the epoch).
    Features { t_ns: u64, json: Vec<u8> },
    /// A health message (JSON).
    Health { t_ns: u64, json: Vec<u8> },
}

/// The MCAP writer of a segment: the raw layout's writer (raw recording on), or a plain one.
enum SegWriter {
    Raw(RecordingWriter),
    Events(McapFile),
}

impl SegWriter {
    fn file(&mut self) -> &mut McapFile {
        match self {
            SegWriter::Raw(r) => r.file_mut(),
            SegWriter::Events(m) => m,
        }
    }

    fn finish(self) -> Result<u64> {
        match self {
            SegWriter::Raw(r) => r.finish(),
            SegWriter::Events(m) => m.finish(),
        }
    }

    fn abandon(self) -> Result<u64> {
        match self {
            SegWriter::Raw(r) => r.abandon(),
            SegWriter::Events(m) => m.abandon(),
        }
    }
}

/// Events waiting for the segment's first block (its start time names the raw layout).
const MAX_PENDING: usize = 4096;

struct Segment {
    path: PathBuf,
    writer: Option<SegWriter>,
    /// Channel ids of `/features` and `/health` once the writer exists.
    features: u16,
    health: u16,
    seq: u32,
    /// Features (`true`) and health events that came before the first block.
    pending: Vec<(bool, u64, Vec<u8>)>,
    opened: Instant,
    opened_ns: u64,
    /// Source sample index of the segment's first sample (raw sample indices are rebased).
    first_sample: Option<u64>,
    /// Something was written since the segment opened.
    written: bool,
}

/// The rotating recorder.
pub struct Recorder {
    cfg: RecordConfig,
    /// Description of the stream (channels, rate, start time; 0 = use the wall clock); per
    /// segment the start time is moved to the segment's first sample.
    info: RecordingInfo,
    stem: String,
    seg: Option<Segment>,
    last_flush: Instant,
    retry_after: Option<Instant>,
    stats: RecordStats,
}

impl Recorder {
    /// `info` describes the stream; `stem` prefixes the file names (e.g. the rig id). The
    /// folder is created with the first segment: a folder that cannot be created is a
    /// recording failure (counted, reported, retried), never a reason to stop monitoring.
    pub fn new(cfg: RecordConfig, info: RecordingInfo, stem: &str) -> Result<Self> {
        cfg.validate()?;
        Ok(Recorder {
            cfg,
            info,
            stem: stem.to_string(),
            seg: None,
            last_flush: Instant::now(),
            retry_after: None,
            stats: RecordStats::default(),
        })
    }

    pub fn stats(&self) -> &RecordStats {
        &self.stats
    }

    /// Handle one event; errors are counted, never returned.
    pub fn handle(&mut self, ev: RecordEvent) {
        if let Err(e) = self.try_handle(ev) {
            self.fail(e);
        }
        if self.last_flush.elapsed().as_secs_f64() >= self.cfg.flush_s {
            self.flush();
        }
    }

    /// Call when idle: closes the current chunk when `flush_s` has passed.
    pub fn tick(&mut self) {
        if self.seg.is_some() && self.last_flush.elapsed().as_secs_f64() >= self.cfg.flush_s {
            self.flush();
        }
    }

    fn retry(&self) -> Duration {
        Duration::from_secs_f64(self.cfg.retry_s)
    }

    fn fail(&mut self, e: anyhow::Error) {
        self.stats.write_errors += 1;
        let full = is_disk_full(&e);
        self.stats.disk_full = full;
        let msg = format!("{e:#}");
        let file = self
            .seg
            .as_ref()
            .map(|s| s.path.display().to_string())
            .unwrap_or_else(|| self.cfg.dir.display().to_string());
        self.stats.failed = Some(if full {
            format!("{file}: disk full ({msg})")
        } else {
            format!("{file}: {msg}")
        });
        if self.stats.write_errors <= 3 || self.stats.write_errors.is_power_of_two() {
            tracing::warn!(
                "recording {file}: {msg} ({} errors so far){}; monitoring continues without recording, retrying with a new file in {:?}",
                self.stats.write_errors,
                if full { " — disk full: free space or lower recording.max_file_mb" } else { "" },
                self.retry()
            );
        }
        self.stats.last_error = Some(msg);
        if let Some(seg) = self.seg.take() {
            self.discard(seg);
        }
        self.stats.file = None;
        self.retry_after = Some(Instant::now() + self.retry());
    }

    /// A segment whose write failed: cut back to its last complete chunk (a readable MCAP),
    /// or removed when it holds none.
    fn discard(&mut self, seg: Segment) {
        let path = seg.path.display().to_string();
        match seg.writer.map_or(Ok(0), SegWriter::abandon) {
            Ok(0) => match std::fs::remove_file(&seg.path) {
                Ok(()) => {
                    self.stats.removed_empty += 1;
                    tracing::warn!("recording: removed {path}: the write failed before it held a complete chunk (it holds no complete chunk)");
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => tracing::warn!("recording: cannot remove the empty {path}: {e}"),
            },
            Ok(bytes) => {
                tracing::info!(
                    "recording: kept {path}: {bytes} bytes, readable up to its last complete chunk"
                )
            }
            Err(e) => tracing::warn!("recording: {path}: {e:#}"),
        }
    }

    fn try_handle(&mut self, ev: RecordEvent) -> Result<()> {
        if self.retry_after.is_some_and(|t| Instant::now() < t) {
            self.stats.dropped += 1;
            return Ok(());
        }
        self.rotate_if_due()?;
        if self.seg.is_none() {
            self.open_segment()?;
        }
        match ev {
            RecordEvent::Block(b) => {
                if self.cfg.raw {
                    self.write_block(&b)?;
                }
            }
            RecordEvent::Features { t_ns, json } => {
                if self.cfg.features {
                    self.write_event(true, t_ns, json)?;
                }
            }
            RecordEvent::Health { t_ns, json } => {
                if self.cfg.health {
                    self.write_event(false, t_ns, json)?;
                }
            }
        }
        Ok(())
    }

    /// The segment's size limit, bytes.
    fn max_bytes(&self) -> u64 {
        (self.cfg.max_file_mb * 1e6) as u64
    }

    /// Close the segment first when `cost` more bytes would take it past `max_file_mb` (a
    /// segment holds at least one write). Returns whether it was closed.
    fn make_room(&mut self, cost: u64) -> Result<bool> {
        let max = self.max_bytes();
        let Some(seg) = self.seg.as_mut() else {
            return Ok(false);
        };
        let full = match (&mut seg.writer, seg.written) {
            (Some(w), true) => w.file().size_bound() + cost > max,
            _ => false,
        };
        if full {
            self.close_segment()?;
            self.open_segment()?;
        }
        Ok(full)
    }

    fn write_block(&mut self, b: &SampleBlock) -> Result<()> {
        let seg = self.seg.as_mut().expect("segment opened above");
        let first = *seg.first_sample.get_or_insert(b.first_sample);
        if b.first_sample < first {
            // The source clock went backwards (a looping replay): new segment.
            self.close_segment()?;
            self.open_segment()?;
            return self.write_block(b);
        }
        let cost = match &seg.writer {
            Some(SegWriter::Raw(raw)) => {
                Some(raw.block_cost(b.len(), b.tacho_analog.is_some(), b.tacho_edges.len()))
            }
            _ => None,
        };
        if let Some(cost) = cost {
            if self.make_room(cost)? {
                return self.write_block(b);
            }
        }
        let seg = self.seg.as_mut().expect("segment open");
        if seg.writer.is_none() {
            self.create_raw_writer(b)?;
        }
        let seg = self.seg.as_mut().expect("segment open");
        let first = seg.first_sample.expect("set above");
        let Some(SegWriter::Raw(raw)) = seg.writer.as_mut() else {
            unreachable!("raw recording on: the writer is the raw layout's")
        };
        let rel = b.first_sample - first;
        let shift = first as f64 / b.sample_rate;
        let chans: Vec<&[f32]> = b.channels.iter().map(Vec::as_slice).collect();
        let edges: Vec<f64> = b.tacho_edges.iter().map(|e| e - shift).collect();
        raw.write_block(rel, &chans, b.tacho_analog.as_deref(), &edges)
            .with_context(|| format!("{}: writing", seg.path.display()))?;
        seg.written = true;
        self.stats.blocks += 1;
        Ok(())
    }

    /// Create the segment's file at its first block, so the file's start time is that
    /// sample's time and its sample indices start at 0; then write the waiting events.
    fn create_raw_writer(&mut self, b: &SampleBlock) -> Result<()> {
        let seg = self.seg.as_mut().expect("segment open");
        let first = seg.first_sample.unwrap_or(b.first_sample);
        let mut info = self.info.clone();
        let start = if info.start_time_ns == 0 {
            seg.opened_ns
        } else {
            info.start_time_ns
        };
        info.start_time_ns = start + (first as f64 / b.sample_rate * 1e9).round() as u64;
        info.sample_rate = b.sample_rate;
        info.metadata.insert(
            "recorded_by".into(),
            format!("rigmon {}", env!("CARGO_PKG_VERSION")),
        );
        info.metadata
            .insert("source_first_sample".into(), first.to_string());
        let settings = WriterSettings {
            chunk_size: self.cfg.chunk_kb * 1024,
            ..WriterSettings::default()
        };
        let mut raw = RecordingWriter::create_with(&seg.path, &info, &settings)?;
        (seg.features, seg.health) = add_event_channels(raw.file_mut())?;
        seg.writer = Some(SegWriter::Raw(raw));
        self.write_pending()
    }

    fn write_event(&mut self, features: bool, t_ns: u64, json: Vec<u8>) -> Result<()> {
        if self.make_room(McapFile::message_cost(json.len()))? {
            // A new segment: with raw recording on, its file waits for the next block.
        }
        let seg = self.seg.as_mut().expect("segment opened above");
        if seg.writer.is_none() {
            if seg.pending.len() >= MAX_PENDING {
                self.stats.dropped += 1;
            } else {
                seg.pending.push((features, t_ns, json));
            }
            return Ok(());
        }
        let channel_id = if features { seg.features } else { seg.health };
        seg.seq = seg.seq.wrapping_add(1);
        let h = ::mcap::records::MessageHeader {
            channel_id,
            sequence: seg.seq,
            log_time: t_ns,
            publish_time: t_ns,
        };
        let w = seg.writer.as_mut().expect("checked above");
        w.file()
            .write(&h, &json)
            .with_context(|| format!("{}: writing", seg.path.display()))?;
        seg.written = true;
        self.stats.messages += 1;
        Ok(())
    }

    fn write_pending(&mut self) -> Result<()> {
        let pending = std::mem::take(&mut self.seg.as_mut().expect("segment open").pending);
        for (features, t_ns, json) in pending {
            self.write_event(features, t_ns, json)?;
        }
        Ok(())
    }

    fn rotate_if_due(&mut self) -> Result<()> {
        let Some(seg) = &self.seg else { return Ok(()) };
        if seg.opened.elapsed().as_secs_f64() >= self.cfg.max_file_s {
            self.close_segment()?;
        }
        Ok(())
    }

    fn open_segment(&mut self) -> Result<()> {
        std::fs::create_dir_all(&self.cfg.dir).with_context(|| {
            format!(
                "recording.dir {}: cannot create the folder; fix the path or its permissions",
                self.cfg.dir.display()
            )
        })?;
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let stamp = utc_stamp(now_ns);
        let mut stem = format!("{}-{stamp}", self.stem);
        let mut k = 1;
        while self.cfg.dir.join(format!("{stem}.mcap")).exists() {
            k += 1;
            stem = format!("{}-{stamp}-{k}", self.stem);
        }
        let path = self.cfg.dir.join(format!("{stem}.mcap"));
        let mut seg = Segment {
            path,
            writer: None,
            features: 0,
            health: 0,
            seq: 0,
            pending: Vec::new(),
            opened: Instant::now(),
            opened_ns: now_ns,
            first_sample: None,
            written: false,
        };
        tracing::info!("recording to {}", seg.path.display());
        self.stats.segments += 1;
        self.stats.file = Some(seg.path.clone());
        self.retry_after = None;
        if !self.cfg.raw {
            // No raw layout: a plain MCAP with the two JSON channels, created now.
            let created = open_events(&seg.path, self.cfg.chunk_kb * 1024).and_then(|mut m| {
                (seg.features, seg.health) = add_event_channels(&mut m)?;
                Ok(m)
            });
            self.seg = Some(seg);
            let m = created?;
            self.seg.as_mut().expect("set above").writer = Some(SegWriter::Events(m));
            return Ok(());
        }
        self.seg = Some(seg);
        Ok(())
    }

    /// Close the current chunk (bounded loss on a crash) and push it to the file.
    pub fn flush(&mut self) {
        self.last_flush = Instant::now();
        let r = (|| -> Result<bool> {
            if let Some(seg) = &mut self.seg {
                if let Some(w) = &mut seg.writer {
                    w.file()
                        .flush()
                        .with_context(|| format!("{}: writing", seg.path.display()))?;
                    return Ok(seg.written);
                }
            }
            Ok(false)
        })();
        match r {
            Ok(true) => {
                // Data reached the file again: the failure is over.
                self.stats.failed = None;
                self.stats.disk_full = false;
            }
            Ok(false) => {}
            Err(e) => self.fail(e),
        }
    }

    fn close_segment(&mut self) -> Result<()> {
        let Some(mut seg) = self.seg.take() else {
            return Ok(());
        };
        self.stats.file = None;
        if seg.writer.is_none() && !seg.pending.is_empty() {
            // Events but never a block (raw on, the source stopped): keep them anyway in a
            // plain MCAP so nothing recorded is lost.
            self.seg = Some(seg);
            let created = {
                let seg = self.seg.as_mut().expect("put back above");
                open_events(&seg.path, self.cfg.chunk_kb * 1024).and_then(|mut m| {
                    (seg.features, seg.health) = add_event_channels(&mut m)?;
                    seg.writer = Some(SegWriter::Events(m));
                    Ok(())
                })
            };
            created.and_then(|_| self.write_pending())?;
            seg = self.seg.take().expect("put back above");
        }
        let path = seg.path.display().to_string();
        if let Some(w) = seg.writer.take() {
            let finished = w.finish().with_context(|| format!("{path}: finishing"));
            if let Err(e) = finished {
                // Put it back so the failure path can cut it back or remove it.
                self.seg = Some(seg);
                return Err(e);
            }
        }
        Ok(())
    }

    /// Finish the file cleanly (SIGTERM, end of replay).
    pub fn finish(mut self) -> RecordStats {
        if let Err(e) = self.close_segment() {
            self.stats.write_errors += 1;
            self.stats.disk_full = is_disk_full(&e);
            self.stats.last_error = Some(format!("{e:#}"));
            tracing::warn!("recording: closing the last file failed: {e:#}");
            if let Some(seg) = self.seg.take() {
                self.discard(seg);
            }
        }
        self.stats
    }
}

/// ENOSPC, EDQUOT or EFBIG anywhere in the error chain (the MCAP writer wraps io errors).
fn is_disk_full(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        let io = c.downcast_ref::<std::io::Error>().or_else(|| {
            c.downcast_ref::<::mcap::McapError>().and_then(|m| match m {
                ::mcap::McapError::Io(io) => Some(io),
                _ => None,
            })
        });
        io.and_then(|io| io.raw_os_error())
            .is_some_and(|c| c == libc::ENOSPC || c == libc::EDQUOT || c == libc::EFBIG)
            || {
                let s = c.to_string();
                s.contains("No space left")
                    || s.contains("File too large")
                    || s.contains("quota exceeded")
            }
    })
}

fn open_events(path: &Path, chunk_size: u64) -> Result<McapFile> {
    McapFile::create(
        path,
        &McapFileOptions {
            chunk_size,
            zstd_level: WriterSettings::default().zstd_level,
            profile: "rigmon".into(),
        },
    )
}

/// Add the `/features` and `/health` JSON channels; their ids.
fn add_event_channels(file: &mut McapFile) -> Result<(u16, u16)> {
    let schema = br#"{"type":"object"}"#;
    let fs = file.add_schema("rigmon.FeatureWindow", "jsonschema", schema)?;
    let hs = file.add_schema(crate::wire::health::SCHEMA, "jsonschema", schema)?;
    let features = file.add_channel(fs, "/features", "json", &BTreeMap::new())?;
    let health = file.add_channel(hs, "/health", "json", &BTreeMap::new())?;
    Ok((features, health))
}

/// `20261122T041300Z` from ns since the epoch.
fn utc_stamp(ns: u64) -> String {
    let secs = (ns / 1_000_000_000) as i64;
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Civil from days (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::mcap::{read_recording, ChannelInfo, TachoInfo};

    const FS: f64 = 1000.0;

    fn info() -> RecordingInfo {
        RecordingInfo {
            sample_rate: FS,
            start_time_ns: 1_795_314_780_000_000_000,
            channels: ["a", "b"]
                .iter()
                .map(|n| ChannelInfo {
                    name: n.to_string(),
                    axis: "vertical".into(),
                    unit: "m/s^2".into(),
                })
                .collect(),
            tacho: TachoInfo::Edges,
            rpm: None,
            provenance: Default::default(),
            metadata: BTreeMap::new(),
        }
    }

    fn block(k: u64, n: usize) -> RecordEvent {
        let first = k * n as u64;
        RecordEvent::Block(Arc::new(SampleBlock {
            first_sample: first,
            sample_rate: FS,
            channels: vec![
                (0..n).map(|i| (first + i as u64) as f32).collect(),
                (0..n).map(|i| -((first + i as u64) as f32)).collect(),
            ],
            tacho_analog: None,
            tacho_edges: vec![first as f64 / FS + 0.01],
        }))
    }

    fn cfg(dir: &Path) -> RecordConfig {
        RecordConfig {
            enabled: true,
            dir: dir.to_path_buf(),
            chunk_kb: 4,
            ..RecordConfig::default()
        }
    }

    fn mcaps(dir: &Path) -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .collect();
        v.sort();
        v
    }

    /// Messages per topic, read with the mcap crate's own (strict) reader.
    fn topics(path: &Path) -> BTreeMap<String, usize> {
        let bytes = std::fs::read(path).unwrap();
        let mut n = BTreeMap::new();
        for m in ::mcap::MessageStream::new(&bytes).unwrap() {
            *n.entry(m.unwrap().channel.topic.clone()).or_insert(0) += 1;
        }
        n
    }

    #[test]
    fn one_file_holds_raw_features_and_health() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Recorder::new(cfg(dir.path()), info(), "rig").unwrap();
        for k in 0..20 {
            r.handle(block(k, 100));
            r.handle(RecordEvent::Features {
                t_ns: k,
                json: br#"{"f":1}"#.to_vec(),
            });
            r.handle(RecordEvent::Health {
                t_ns: k,
                json: br#"{"state":"normal"}"#.to_vec(),
            });
        }
        let st = r.finish();
        assert_eq!((st.segments, st.blocks, st.messages), (1, 20, 40));
        let files = mcaps(dir.path());
        assert_eq!(files.len(), 1, "{files:?}");
        let t = topics(&files[0]);
        assert_eq!(t["/features"], 20);
        assert_eq!(t["/health"], 20);
        assert_eq!(t["/accel/a"], 20);
        assert_eq!(t["/tacho/edges"], 20);
        // The raw layout's reader still reads it (layout_version 1), all samples, no note.
        let rec = read_recording(&files[0]).unwrap();
        assert_eq!(rec.channels[0].samples.len(), 2000);
        assert_eq!(rec.channels[1].samples[1999], -1999.0);
        assert!(
            rec.provenance.notes.is_empty(),
            "{:?}",
            rec.provenance.notes
        );
    }

    #[test]
    fn a_copy_taken_while_writing_reads_back_to_the_last_flush() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = Recorder::new(cfg(dir.path()), info(), "rig").unwrap();
        for k in 0..10 {
            r.handle(block(k, 100));
            r.handle(RecordEvent::Health {
                t_ns: k,
                json: b"{}".to_vec(),
            });
        }
        r.flush();
        // Written after the flush, still in the open chunk: not on disk yet.
        r.handle(block(10, 100));
        let file = mcaps(dir.path()).remove(0);
        // What a kill -9 leaves: the bytes on disk now, without summary or footer.
        let cut = dir.path().join("cut.bin");
        std::fs::copy(&file, &cut).unwrap();
        let rec = read_recording(&cut).unwrap();
        assert_eq!(rec.channels[0].samples.len(), 1000);
        assert_eq!(rec.channels[0].samples[999], 999.0);
        assert!(
            rec.provenance
                .notes
                .iter()
                .any(|n| n.contains("had not finished the file")),
            "{:?}",
            rec.provenance.notes
        );
        // A complete MCAP as it is (the provisional end after the last chunk): the mcap
        // crate's strict reader reads it too.
        let bytes = std::fs::read(&cut).unwrap();
        assert_eq!(&bytes[bytes.len() - 8..], ::mcap::MAGIC);
        let n = ::mcap::MessageStream::new(&bytes)
            .unwrap()
            .filter(|m| m.as_ref().unwrap().channel.topic == "/accel/a")
            .count();
        assert_eq!(n, 10);
        drop(r);
    }

    #[test]
    fn rotates_by_time_and_records_events_only_when_raw_is_off() {
        let dir = tempfile::tempdir().unwrap();
        let mut c = cfg(dir.path());
        c.max_file_s = 0.2;
        let mut r = Recorder::new(c, info(), "rig").unwrap();
        for k in 0..3 {
            r.handle(block(k, 100));
            std::thread::sleep(Duration::from_millis(250));
        }
        let st = r.finish();
        assert_eq!(st.segments, 3);
        let files = mcaps(dir.path());
        assert_eq!(files.len(), 3, "{files:?}");
        let total: usize = files
            .iter()
            .map(|f| read_recording(f).unwrap().channels[0].samples.len())
            .sum();
        assert_eq!(total, 300);

        let dir = tempfile::tempdir().unwrap();
        let mut c = cfg(dir.path());
        c.raw = false;
        let mut r = Recorder::new(c, info(), "rig").unwrap();
        r.handle(block(0, 100));
        r.handle(RecordEvent::Health {
            t_ns: 1,
            json: b"{}".to_vec(),
        });
        let st = r.finish();
        assert_eq!((st.blocks, st.messages), (0, 1));
        let t = topics(&mcaps(dir.path())[0]);
        assert_eq!(t.get("/health"), Some(&1));
        assert!(!t.contains_key("/accel/a"));
    }

    #[test]
    fn disk_full_errors_are_recognised() {
        for code in [libc::ENOSPC, libc::EDQUOT, libc::EFBIG] {
            let e = anyhow::Error::from(::mcap::McapError::Io(std::io::Error::from_raw_os_error(
                code,
            )))
            .context("x.mcap: writing");
            assert!(is_disk_full(&e), "{code}");
        }
        let e = anyhow::Error::from(std::io::Error::from_raw_os_error(libc::EACCES));
        assert!(!is_disk_full(&e));
    }

    #[test]
    fn utc_stamp_is_right() {
        assert_eq!(utc_stamp(0), "19700101T000000Z");
        assert_eq!(utc_stamp(1_795_314_780_000_000_000), "20261122T023300Z");
    }
}
