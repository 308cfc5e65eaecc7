//! File replay: any recording the importers read (rigmon MCAP, any-layout .mat, WAV, CSV)
//! delivered as [`SampleBlock`]s of about `block_ms`, at a real-time factor or as fast as the
//! consumer takes them, optionally looping. Channels come out in rig order; an analog tacho
//! becomes `tacho_analog`, recorded tacho edges become `tacho_edges`. The `[source] type =
//! "file"` section ([`FileSourceConfig`]); the daemon streams the file
//! ([`FileSourceConfig::open`], [`StreamReplay`]); [`FileReplay`] replays a recording held in
//! memory (the serial emulator).

use super::stream_replay::StreamReplay;
use super::{
    send_block, sleep_unless_stopped, BlockSender, SampleBlock, Source, SourceStats, StopToken,
};
use crate::config::RigConfig;
use crate::importers::{self, ImportOptions};
use crate::recording::{Recording, Tacho};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How fast a recording is replayed: a real-time factor (1 = real time, 2 = twice as fast),
/// or `max` (as fast as the consumer takes blocks; nothing is dropped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    Factor(f64),
    Max,
}

impl Default for ReplaySpeed {
    fn default() -> Self {
        ReplaySpeed::Factor(1.0)
    }
}

impl fmt::Display for ReplaySpeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReplaySpeed::Factor(x) => write!(f, "{x}x"),
            ReplaySpeed::Max => f.write_str("max"),
        }
    }
}

impl ReplaySpeed {
    fn from_factor(x: f64) -> Result<Self, String> {
        if x.is_finite() && x > 0.0 {
            Ok(ReplaySpeed::Factor(x))
        } else {
            Err(format!(
                "speed = {x}: must be a positive real-time factor (1 = real time) or \"max\""
            ))
        }
    }
}

impl FromStr for ReplaySpeed {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        if t.eq_ignore_ascii_case("max") {
            return Ok(ReplaySpeed::Max);
        }
        let x: f64 = t.trim_end_matches(['x', 'X']).parse().map_err(|_| {
            format!("speed {s:?}: expected a real-time factor such as 1 or 0.5, or \"max\"")
        })?;
        ReplaySpeed::from_factor(x)
    }
}

impl Serialize for ReplaySpeed {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            ReplaySpeed::Factor(x) => s.serialize_f64(*x),
            ReplaySpeed::Max => s.serialize_str("max"),
        }
    }
}

impl<'de> Deserialize<'de> for ReplaySpeed {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = ReplaySpeed;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a positive real-time factor (1 = real time) or \"max\"")
            }
            fn visit_f64<E: serde::de::Error>(self, x: f64) -> Result<ReplaySpeed, E> {
                ReplaySpeed::from_factor(x).map_err(E::custom)
            }
            fn visit_i64<E: serde::de::Error>(self, x: i64) -> Result<ReplaySpeed, E> {
                self.visit_f64(x as f64)
            }
            fn visit_u64<E: serde::de::Error>(self, x: u64) -> Result<ReplaySpeed, E> {
                self.visit_f64(x as f64)
            }
            fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<ReplaySpeed, E> {
                s.parse().map_err(E::custom)
            }
        }
        d.deserialize_any(V)
    }
}

fn default_block_ms() -> f64 {
    100.0
}

/// `[source] type = "file"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileSourceConfig {
    /// The recording (relative paths are relative to the daemon config file).
    pub path: PathBuf,
    /// Real-time factor, or "max".
    #[serde(default)]
    pub speed: ReplaySpeed,
    /// Start again at the end (the sample clock keeps counting up).
    #[serde(default, rename = "loop")]
    pub looping: bool,
    /// Block length, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// Sample-rate override for files that do not carry one (passed to the importer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Speed override, rpm (passed to the importer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpm: Option<f64>,
}

impl FileSourceConfig {
    /// A replay of `path` with the defaults (real time, no loop, 100 ms blocks).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        FileSourceConfig {
            path: path.into(),
            speed: ReplaySpeed::default(),
            looping: false,
            block_ms: default_block_ms(),
            sample_rate_hz: None,
            rpm: None,
        }
    }

    /// Open the recording as the daemon's source: streamed from disk (rigmon MCAP, WAV) with
    /// bounded memory, checked against the rig (see [`StreamReplay`]).
    pub fn open(&self, rig: &RigConfig) -> Result<StreamReplay> {
        check_block_ms(self.block_ms)?;
        let opts = ImportOptions {
            sample_rate: self.sample_rate_hz,
            rpm: self.rpm,
            ..Default::default()
        };
        let name = self.path.display().to_string();
        let stream = importers::open(&self.path, rig, &opts)
            .with_context(|| format!("file source: cannot replay {name}"))?;
        StreamReplay::new(stream, rig, self.speed, self.looping, self.block_ms, &name)
            .with_context(|| format!("file source {name}"))
    }

    /// Read the whole recording into memory and check it against the rig (the serial
    /// emulator needs it whole; the daemon uses [`open`](Self::open)).
    pub fn build(&self, rig: &RigConfig) -> Result<FileReplay> {
        check_block_ms(self.block_ms)?;
        let opts = ImportOptions {
            sample_rate: self.sample_rate_hz,
            rpm: self.rpm,
            ..Default::default()
        };
        let rec = importers::load(&self.path, rig, &opts)
            .with_context(|| format!("file source: cannot replay {}", self.path.display()))?;
        let mut replay =
            FileReplay::from_recording(rec, rig, self.speed, self.looping, self.block_ms)
                .with_context(|| format!("file source {}", self.path.display()))?;
        replay.name = self.path.display().to_string();
        Ok(replay)
    }
}

fn check_block_ms(block_ms: f64) -> Result<()> {
    if !(block_ms.is_finite() && (1.0..=10_000.0).contains(&block_ms)) {
        bail!("block_ms = {block_ms}: must be between 1 and 10000 (100 is a good choice)");
    }
    Ok(())
}

/// A recording ready to be replayed as a [`Source`].
#[derive(Debug)]
pub struct FileReplay {
    rec: Recording,
    /// For each rig acceleration channel, the index of the recording channel, or `None`.
    order: Vec<Option<usize>>,
    absent: Vec<String>,
    speed: ReplaySpeed,
    looping: bool,
    block: usize,
    /// What `describe` calls it: the path it was read from, else the recording's provenance.
    name: String,
}

impl FileReplay {
    /// Replay an in-memory recording. Rig acceleration channels are matched to recording
    /// channels by name (exact, then ignoring case); a rig channel the recording lacks is
    /// delivered as NaN and listed by [`Source::absent_channels`], unless it is the
    /// classifier channel (an error).
    pub fn from_recording(
        rec: Recording,
        rig: &RigConfig,
        speed: ReplaySpeed,
        looping: bool,
        block_ms: f64,
    ) -> Result<Self> {
        check_block_ms(block_ms)?;
        if let ReplaySpeed::Factor(x) = speed {
            ReplaySpeed::from_factor(x).map_err(anyhow::Error::msg)?;
        }
        if !(rec.sample_rate.is_finite() && rec.sample_rate > 0.0) {
            bail!(
                "the recording's sample rate is {} Hz; give the right one with `sample_rate_hz`",
                rec.sample_rate
            );
        }
        if rec.is_empty() {
            bail!("the recording has no samples");
        }
        if let Some(bad) = rec.channels.iter().find(|c| c.samples.len() != rec.len()) {
            bail!(
                "channel {:?} has {} samples but {:?} has {}; channels must be the same length",
                bad.name,
                bad.samples.len(),
                rec.channels[0].name,
                rec.len()
            );
        }
        if let Some(Tacho::Analog { samples, .. }) = &rec.tacho {
            if samples.len() != rec.len() {
                bail!(
                    "the analog tacho has {} samples but the channels have {}",
                    samples.len(),
                    rec.len()
                );
            }
        }
        let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
        let (order, absent) =
            super::channel_order::rig_channel_order(rig, &names, rec.sample_rate, "the recording")?;
        let block = super::BlockAssembler::samples_for_ms(rec.sample_rate, block_ms);
        let name = rec.provenance.source_path.clone();
        Ok(FileReplay {
            rec,
            order,
            absent,
            speed,
            looping,
            block,
            name,
        })
    }

    /// The recording being replayed.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    /// The block holding samples `[start, end)` of the recording (every pass of a loop
    /// alike).
    pub(crate) fn block_at(&self, start: usize, end: usize) -> SampleBlock {
        let fs = self.rec.sample_rate;
        let channels = self
            .order
            .iter()
            .map(|idx| match idx {
                Some(i) => self.rec.channels[*i].samples[start..end].to_vec(),
                None => vec![f32::NAN; end - start],
            })
            .collect();
        let (tacho_analog, tacho_edges) = match &self.rec.tacho {
            Some(Tacho::Analog { samples, .. }) => (Some(samples[start..end].to_vec()), Vec::new()),
            Some(Tacho::Edges { times_s }) => {
                let (t0, t1) = (start as f64 / fs, end as f64 / fs);
                let lo = times_s.partition_point(|&t| t < t0);
                let hi = times_s.partition_point(|&t| t < t1);
                (None, times_s[lo..hi].to_vec())
            }
            None => (None, Vec::new()),
        };
        // Each pass starts the sample clock again: the seam is a clock going backwards,
        // which restarts the windows and their speed (analysis::windows), instead of joining
        // the end of the recording to its start as if the shaft had turned on across it.
        SampleBlock {
            first_sample: start as u64,
            sample_rate: fs,
            channels,
            tacho_analog,
            tacho_edges,
        }
    }
}

impl Source for FileReplay {
    fn describe(&self) -> String {
        let p = &self.rec.provenance;
        format!(
            "file {} ({}, {} Hz, {:.1} s, speed {}{})",
            self.name,
            if p.format.is_empty() {
                "recording"
            } else {
                &p.format
            },
            self.rec.sample_rate,
            self.rec.duration_s(),
            self.speed,
            if self.looping { ", loop" } else { "" }
        )
    }

    fn analog_tacho(&self) -> bool {
        matches!(self.rec.tacho, Some(Tacho::Analog { .. }))
    }

    fn sample_rate(&self) -> f64 {
        self.rec.sample_rate
    }

    fn nominal_rpm(&self) -> Option<f64> {
        self.rec.rpm
    }

    fn absent_channels(&self) -> Vec<String> {
        self.absent.clone()
    }

    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        let n = self.rec.len();
        let fs = self.rec.sample_rate;
        let t0 = Instant::now();
        stats.connected.store(true, Ordering::Relaxed);
        let mut pass = 0u64;
        'outer: loop {
            let mut start = 0;
            while start < n {
                if stop.is_stopped() {
                    break 'outer;
                }
                let end = (start + self.block).min(n);
                let block = self.block_at(start, end);
                if let ReplaySpeed::Factor(x) = self.speed {
                    // A live DAQ delivers a block once its last sample has been taken.
                    let due = t0
                        + Duration::from_secs_f64((pass * n as u64 + end as u64) as f64 / fs / x);
                    let now = Instant::now();
                    if due > now && !sleep_unless_stopped(due - now, &stop) {
                        break 'outer;
                    }
                }
                let len = block.len() as u64;
                if !send_block(&tx, block, &stop) {
                    break 'outer;
                }
                SourceStats::add(&stats.blocks, 1);
                SourceStats::add(&stats.samples, len);
                start = end;
            }
            if !self.looping {
                break;
            }
            pass += 1;
        }
        stats.connected.store(false, Ordering::Relaxed);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::{Channel, Provenance};
    use std::path::Path;

    fn rig(name: &str) -> RigConfig {
        RigConfig::load(
            &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("config")
                .join(name),
        )
        .unwrap()
    }

    fn recording(names: &[&str], n: usize, fs: f64, tacho: Option<Tacho>) -> Recording {
        Recording {
            sample_rate: fs,
            start_time_ns: 0,
            channels: names
                .iter()
                .enumerate()
                .map(|(c, name)| Channel {
                    name: name.to_string(),
                    axis: String::new(),
                    unit: "g".into(),
                    samples: (0..n).map(|i| (c * 100_000 + i) as f32).collect(),
                })
                .collect(),
            tacho,
            rpm: Some(1797.0),
            nominal_rpm: None,
            provenance: Provenance {
                source_path: "mem".into(),
                format: "test".into(),
                notes: vec![],
            },
            metadata: Default::default(),
        }
    }

    fn collect(src: FileReplay) -> (Vec<SampleBlock>, Arc<SourceStats>) {
        let (tx, rx) = std::sync::mpsc::sync_channel(4);
        let stats = Arc::new(SourceStats::default());
        let st = stats.clone();
        let h = std::thread::spawn(move || Box::new(src).run(tx, st, StopToken::new()));
        let blocks: Vec<SampleBlock> = rx.iter().collect();
        h.join().unwrap().unwrap();
        (blocks, stats)
    }

    #[test]
    fn speed_parses_from_toml_and_cli() {
        #[derive(Deserialize)]
        struct T {
            s: ReplaySpeed,
        }
        let p = |t: &str| toml::from_str::<T>(t).map(|t| t.s);
        assert_eq!(p("s = 1").unwrap(), ReplaySpeed::Factor(1.0));
        assert_eq!(p("s = 0.5").unwrap(), ReplaySpeed::Factor(0.5));
        assert_eq!(p("s = \"max\"").unwrap(), ReplaySpeed::Max);
        assert!(p("s = -1").unwrap_err().to_string().contains("positive"));
        assert!(p("s = \"fast\"").is_err());
        assert_eq!(
            "2x".parse::<ReplaySpeed>().unwrap(),
            ReplaySpeed::Factor(2.0)
        );
        assert_eq!("MAX".parse::<ReplaySpeed>().unwrap(), ReplaySpeed::Max);
        assert!("0".parse::<ReplaySpeed>().is_err());
    }

    #[test]
    fn replays_in_rig_order_with_analog_tacho() {
        let n = 25_000;
        let tacho = Tacho::Analog {
            samples: (0..n).map(|i| (i % 7) as f32).collect(),
            unit: "V".into(),
        };
        // Recording channels in another order than the rig's.
        let rec = recording(
            &["horizontal", "axial", "Vertical"],
            n,
            10_000.0,
            Some(tacho),
        );
        let src = FileReplay::from_recording(
            rec.clone(),
            &rig("lut-rig.toml"),
            ReplaySpeed::Max,
            false,
            100.0,
        )
        .unwrap();
        assert!(src.absent_channels().is_empty());
        assert_eq!(src.nominal_rpm(), Some(1797.0));
        let (blocks, stats) = collect(src);
        assert_eq!(blocks.len(), 25);
        assert!(blocks[..24].iter().all(|b| b.len() == 1000));
        assert_eq!(blocks[24].len(), 1000);
        let mut next = 0;
        for b in &blocks {
            assert_eq!(b.first_sample, next);
            next += b.len() as u64;
            assert_eq!(b.channels.len(), 3);
        }
        let cat = |c: usize| {
            blocks
                .iter()
                .flat_map(|b| b.channels[c].clone())
                .collect::<Vec<f32>>()
        };
        assert_eq!(cat(0), rec.channels[1].samples); // axial
        assert_eq!(cat(1), rec.channels[2].samples); // vertical (case-insensitive match)
        assert_eq!(cat(2), rec.channels[0].samples); // horizontal
        let t: Vec<f32> = blocks
            .iter()
            .flat_map(|b| b.tacho_analog.clone().unwrap())
            .collect();
        assert_eq!(t.len(), n);
        assert_eq!(stats.samples.load(Ordering::Relaxed), n as u64);
        assert_eq!(stats.blocks.load(Ordering::Relaxed), 25);
    }

    #[test]
    fn edges_follow_their_block_and_each_loop_restarts_the_clock() {
        let n = 1200; // 0.1 s at 12 kHz
        let edges: Vec<f64> = (0..10).map(|k| 0.005 + 0.01 * k as f64).collect();
        let rec = recording(
            &["DE", "FE"],
            n,
            12_000.0,
            Some(Tacho::Edges {
                times_s: edges.clone(),
            }),
        );
        let src =
            FileReplay::from_recording(rec, &rig("cwru-de.toml"), ReplaySpeed::Max, true, 50.0)
                .unwrap();
        assert_eq!(src.absent_channels(), ["BA"]);
        let (tx, rx) = std::sync::mpsc::sync_channel(2);
        let stop = StopToken::new();
        let st = stop.clone();
        let h =
            std::thread::spawn(move || Box::new(src).run(tx, Arc::new(SourceStats::default()), st));
        let blocks: Vec<SampleBlock> = rx.iter().take(6).collect();
        stop.stop();
        h.join().unwrap().unwrap();
        assert_eq!(
            blocks.iter().map(|b| b.first_sample).collect::<Vec<_>>(),
            [0, 600, 0, 600, 0, 600]
        );
        assert!(
            blocks[0].channels[2].iter().all(|v| v.is_nan()),
            "BA is absent"
        );
        assert_eq!(blocks[0].tacho_edges, edges[..5]);
        for b in &blocks {
            let (t0, t1) = (
                b.first_sample as f64 / 12_000.0,
                (b.first_sample + b.len() as u64) as f64 / 12_000.0,
            );
            assert_eq!(b.tacho_edges.len(), 5);
            assert!(
                b.tacho_edges.iter().all(|&t| t >= t0 && t < t1),
                "{:?} outside [{t0}, {t1})",
                b.tacho_edges
            );
        }
        assert!((blocks[4].tacho_edges[0] - 0.005).abs() < 1e-12);
    }

    #[test]
    fn real_time_pacing_follows_the_sample_clock() {
        // 0.3 s of data at 4x: blocks are due at 25, 50, 75 ms; the last no earlier than 75 ms.
        let rec = recording(&["DE"], 3000, 10_000.0, None);
        let src = FileReplay::from_recording(
            rec,
            &rig("cwru-de.toml"),
            ReplaySpeed::Factor(4.0),
            false,
            100.0,
        )
        .unwrap();
        let t = Instant::now();
        let (blocks, _) = collect(src);
        assert_eq!(blocks.len(), 3);
        assert!(
            t.elapsed() >= Duration::from_millis(75),
            "{:?}",
            t.elapsed()
        );
    }

    #[test]
    fn missing_classifier_channel_is_an_error_that_names_it() {
        let rec = recording(&["FE", "BA"], 100, 12_000.0, None);
        let err =
            FileReplay::from_recording(rec, &rig("cwru-de.toml"), ReplaySpeed::Max, false, 100.0)
                .unwrap_err()
                .to_string();
        assert!(
            err.contains("\"DE\"") && err.contains("classifier"),
            "{err}"
        );
        let rec = recording(&["DE"], 0, 12_000.0, None);
        assert!(FileReplay::from_recording(
            rec,
            &rig("cwru-de.toml"),
            ReplaySpeed::Max,
            false,
            100.0
        )
        .is_err());
    }
}
