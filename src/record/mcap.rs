//! The rotating MCAP recorder (see the module above for the file layout). It runs on the
//! recording thread and is fed [`RecordEvent`]s; every error is counted and logged, and the
//! recorder retries with a fresh segment after `RETRY` instead of giving up.

use super::RecordConfig;
use crate::acquire::SampleBlock;
use crate::recording::mcap_layout::{RecordingInfo, RecordingWriter, WriterSettings};
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Wait this long after a write error before opening a new segment.
const RETRY: Duration = Duration::from_secs(5);

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

/// Counters of the recorder (reported in the status topic).
#[derive(Debug, Default, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordStats {
    pub segments: u64,
    pub blocks: u64,
    pub messages: u64,
    pub write_errors: u64,
    /// The last write failed for lack of space (ENOSPC).
    pub disk_full: bool,
    pub last_error: Option<String>,
    /// Current raw file.
    pub file: Option<PathBuf>,
    /// Events dropped because the recorder was behind or between segments after an error.
    pub dropped: u64,
}

struct EventsFile {
    mcap: ::mcap::Writer<BufWriter<File>>,
    features: u16,
    health: u16,
    seq: u32,
}

struct Segment {
    raw: Option<RecordingWriter>,
    raw_path: PathBuf,
    events: Option<EventsFile>,
    opened: Instant,
    opened_ns: u64,
    /// Source sample index of the segment's first sample (raw sample indices are rebased).
    first_sample: Option<u64>,
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
    last_size_check: Instant,
    retry_after: Option<Instant>,
    stats: RecordStats,
}

impl Recorder {
    /// `info` describes the stream; `stem` prefixes the file names (e.g. the rig id).
    pub fn new(cfg: RecordConfig, info: RecordingInfo, stem: &str) -> Result<Self> {
        cfg.validate()?;
        std::fs::create_dir_all(&cfg.dir).with_context(|| {
            format!(
                "recording.dir {}: cannot create the folder; fix the path or its permissions",
                cfg.dir.display()
            )
        })?;
        Ok(Recorder {
            cfg,
            info,
            stem: stem.to_string(),
            seg: None,
            last_flush: Instant::now(),
            last_size_check: Instant::now(),
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

    fn fail(&mut self, e: anyhow::Error) {
        self.stats.write_errors += 1;
        self.stats.disk_full = e.chain().any(|c| {
            c.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.raw_os_error() == Some(libc::ENOSPC))
                || c.to_string().contains("No space left")
        });
        let msg = format!("{e:#}");
        if self.stats.write_errors <= 3 || self.stats.write_errors.is_power_of_two() {
            tracing::warn!("recording: {msg} ({} errors so far); monitoring continues, retrying with a new file in {RETRY:?}", self.stats.write_errors);
        }
        self.stats.last_error = Some(msg);
        // Drop the broken segment without finishing it (its complete chunks stay readable).
        self.seg = None;
        self.stats.file = None;
        self.retry_after = Some(Instant::now() + RETRY);
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
        let seg = self.seg.as_mut().expect("segment opened above");
        match ev {
            RecordEvent::Block(b) => {
                if !self.cfg.raw {
                    return Ok(());
                }
                let first = *seg.first_sample.get_or_insert(b.first_sample);
                if b.first_sample < first {
                    // The source clock went backwards (a looping replay): new segment.
                    self.close_segment()?;
                    return self.try_handle(RecordEvent::Block(b));
                }
                if seg.raw.is_none() {
                    // Created at the first block so the file's start time is that sample's time
                    // and its sample indices start at 0.
                    let mut info = self.info.clone();
                    let start = if info.start_time_ns == 0 {
                        seg.opened_ns
                    } else {
                        info.start_time_ns
                    };
                    info.start_time_ns =
                        start + (first as f64 / b.sample_rate * 1e9).round() as u64;
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
                    seg.raw = Some(RecordingWriter::create_with(
                        &seg.raw_path,
                        &info,
                        &settings,
                    )?);
                }
                let raw = seg.raw.as_mut().expect("created above");
                let rel = b.first_sample - first;
                let shift = first as f64 / b.sample_rate;
                let chans: Vec<&[f32]> = b.channels.iter().map(Vec::as_slice).collect();
                let edges: Vec<f64> = b.tacho_edges.iter().map(|e| e - shift).collect();
                raw.write_block(rel, &chans, b.tacho_analog.as_deref(), &edges)?;
                self.stats.blocks += 1;
            }
            RecordEvent::Features { t_ns, json } => {
                if let Some(ev) = &mut seg.events {
                    write_event(ev, ev.features, t_ns, &json)?;
                    self.stats.messages += 1;
                }
            }
            RecordEvent::Health { t_ns, json } => {
                if let Some(ev) = &mut seg.events {
                    write_event(ev, ev.health, t_ns, &json)?;
                    self.stats.messages += 1;
                }
            }
        }
        Ok(())
    }

    fn rotate_if_due(&mut self) -> Result<()> {
        let Some(seg) = &self.seg else { return Ok(()) };
        let mut due = seg.opened.elapsed().as_secs_f64() >= self.cfg.max_file_s;
        if !due && self.last_size_check.elapsed() >= Duration::from_millis(500) {
            self.last_size_check = Instant::now();
            let size = std::fs::metadata(&seg.raw_path)
                .map(|m| m.len())
                .unwrap_or(0);
            due = size as f64 >= self.cfg.max_file_mb * 1e6;
        }
        if due {
            self.close_segment()?;
        }
        Ok(())
    }

    fn open_segment(&mut self) -> Result<()> {
        let now_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let stamp = utc_stamp(now_ns);
        let mut stem = format!("{}-{stamp}", self.stem);
        let mut k = 1;
        while self.cfg.dir.join(format!("{stem}.mcap")).exists()
            || self.cfg.dir.join(format!("{stem}.events.mcap")).exists()
        {
            k += 1;
            stem = format!("{}-{stamp}-{k}", self.stem);
        }
        let raw_path = self.cfg.dir.join(format!("{stem}.mcap"));
        let events = if self.cfg.features || self.cfg.health {
            Some(open_events(
                &self.cfg.dir.join(format!("{stem}.events.mcap")),
                self.cfg.chunk_kb * 1024,
            )?)
        } else {
            None
        };
        tracing::info!("recording to {}", raw_path.display());
        self.stats.segments += 1;
        self.stats.file = Some(raw_path.clone());
        self.stats.disk_full = false;
        self.retry_after = None;
        self.seg = Some(Segment {
            raw: None,
            raw_path,
            events,
            opened: Instant::now(),
            opened_ns: now_ns,
            first_sample: None,
        });
        Ok(())
    }

    /// Close the current chunk of both files (bounded loss on a crash).
    pub fn flush(&mut self) {
        self.last_flush = Instant::now();
        let r = (|| -> Result<()> {
            if let Some(seg) = &mut self.seg {
                if let Some(raw) = &mut seg.raw {
                    raw.flush()?;
                }
                if let Some(ev) = &mut seg.events {
                    ev.mcap.flush()?;
                }
            }
            Ok(())
        })();
        if let Err(e) = r {
            self.fail(e);
        }
    }

    fn close_segment(&mut self) -> Result<()> {
        if let Some(seg) = self.seg.take() {
            self.stats.file = None;
            if let Some(raw) = seg.raw {
                raw.finish()
                    .with_context(|| format!("finishing {}", seg.raw_path.display()))?;
            }
            if let Some(mut ev) = seg.events {
                ev.mcap.finish()?;
            }
        }
        Ok(())
    }

    /// Finish the files cleanly (SIGTERM, end of replay).
    pub fn finish(mut self) -> RecordStats {
        if let Err(e) = self.close_segment() {
            self.stats.write_errors += 1;
            self.stats.last_error = Some(format!("{e:#}"));
            tracing::warn!("recording: closing the last file failed: {e:#}");
        }
        self.stats
    }
}

fn open_events(path: &Path, chunk_size: u64) -> Result<EventsFile> {
    let f = File::create(path).with_context(|| format!("{}: cannot create", path.display()))?;
    let mut mcap = ::mcap::WriteOptions::new()
        .profile("rigmon")
        .library(concat!("rigmon ", env!("CARGO_PKG_VERSION")))
        .compression(Some(::mcap::Compression::Zstd))
        .chunk_size(Some(chunk_size))
        .create(BufWriter::with_capacity(1 << 16, f))
        .with_context(|| format!("{}: cannot write MCAP", path.display()))?;
    let schema = br#"{"type":"object"}"#;
    let fs = mcap.add_schema("rigmon.FeatureWindow", "jsonschema", schema)?;
    let hs = mcap.add_schema(crate::health::message::SCHEMA, "jsonschema", schema)?;
    let features = mcap.add_channel(fs, "/features", "json", &BTreeMap::new())?;
    let health = mcap.add_channel(hs, "/health", "json", &BTreeMap::new())?;
    Ok(EventsFile {
        mcap,
        features,
        health,
        seq: 0,
    })
}

fn write_event(ev: &mut EventsFile, channel_id: u16, t_ns: u64, json: &[u8]) -> Result<()> {
    ev.seq = ev.seq.wrapping_add(1);
    let h = ::mcap::records::MessageHeader {
        channel_id,
        sequence: ev.seq,
        log_time: t_ns,
        publish_time: t_ns,
    };
    ev.mcap.write_to_known_channel(&h, json)?;
    Ok(())
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

    #[test]
    fn utc_stamp_is_right() {
        assert_eq!(utc_stamp(0), "19700101T000000Z");
        assert_eq!(utc_stamp(1_795_314_780_000_000_000), "20261122T023300Z");
    }
}
