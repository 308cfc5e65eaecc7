//! A folder of periodic captures (snapshots) read as one recording: FEMTO PRONOSTIA's
//! headerless CSVs ([`headerless`]: the capture clock, then the rig's channels in order), or
//! WAV, CSV (with a header) or MAT captures, one file each, read by their importer.
//!
//! Files are taken in natural name order (`acc_2` before `acc_10`); hidden files, FEMTO's
//! temperature files (`temp_*`) and files of other types are skipped and counted in a note; a
//! folder mixing capture types is refused. Each capture is placed at its time ([`clock`]):
//! from the captures' clock where they carry one, else k x `acquisition.capture_interval_s`
//! (the rig-file key that states the interval; it also wins over a clock's median step).
//!
//! [`open`] streams the captures one file at a time ([`stream::SnapshotStream`]), each as one
//! block at its time on the sample clock: memory holds one capture and the list of file
//! names, however many files there are. [`load`] collects them whole for the commands that
//! need a recording in memory, with where each capture starts in its metadata
//! ([`crate::recording::captures`]), after checking the total fits in the memory available.
//! Either way the time between captures is a gap on the clock, never lost samples, and no
//! window straddles two captures.

pub mod clock;
pub mod headerless;
pub mod stream;

use super::{resolve_sample_rate, ImportOptions};
use crate::config::RigConfig;
use crate::recording::mcap::ChannelInfo;
use crate::recording::Recording;
use anyhow::{bail, Context, Result};
use clock::CaptureTimes;
use headerless::Layout;
use std::path::{Path, PathBuf};

/// How each capture file is read.
#[derive(Debug, Clone)]
pub enum Kind {
    /// Headerless CSV (FEMTO's layout), read here; sensitivities in channel order.
    Headerless {
        layout: Layout,
        sensitivity: Vec<f64>,
    },
    /// One recording per file, read by its importer ([`super::load`]).
    Files,
}

/// A folder of captures, listed and timed; the samples are read capture by capture.
#[derive(Debug, Clone)]
pub struct Series {
    pub dir: PathBuf,
    pub files: Vec<PathBuf>,
    pub times: CaptureTimes,
    pub kind: Kind,
    pub sample_rate: f64,
    pub channels: Vec<ChannelInfo>,
    /// Samples per channel of the first capture.
    pub capture_len: usize,
    /// "femto-csv series", "wav series", ...
    pub format: String,
    pub notes: Vec<String>,
}

/// Natural order: digit runs compared as numbers.
fn natural_key(name: &str) -> String {
    let mut key = String::with_capacity(name.len() + 16);
    let mut digits = String::new();
    for ch in name.chars().chain(std::iter::once('\0')) {
        if ch.is_ascii_digit() {
            digits.push(ch);
            continue;
        }
        if !digits.is_empty() {
            key.push_str(&format!("{:0>20}", digits));
            digits.clear();
        }
        if ch != '\0' {
            key.push(ch);
        }
    }
    key
}

/// The capture files of a folder in natural order, their extension, and notes on what was
/// skipped.
fn list(dir: &Path) -> Result<(Vec<PathBuf>, String, Vec<String>)> {
    let d = dir.display();
    let mut by_ext: std::collections::BTreeMap<String, Vec<PathBuf>> = Default::default();
    let (mut temperature, mut other) = (0usize, 0usize);
    for entry in std::fs::read_dir(dir).with_context(|| format!("{d}: cannot list the folder"))? {
        let path = entry
            .with_context(|| format!("{d}: cannot list the folder"))?
            .path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let ext = ext.to_ascii_lowercase();
        if name.starts_with('.') || !path.is_file() {
            continue;
        }
        if name.to_ascii_lowercase().starts_with("temp") {
            temperature += 1;
        } else if ["csv", "txt", "wav", "mat"].contains(&ext.as_str()) {
            by_ext.entry(ext).or_default().push(path);
        } else {
            other += 1;
        }
    }
    let mut notes = Vec::new();
    if temperature > 0 {
        notes.push(format!(
            "{temperature} temperature file(s) (temp_*) skipped: not acceleration"
        ));
    }
    if other > 0 {
        notes.push(format!(
            "{other} file(s) that are not .csv, .txt, .wav or .mat skipped"
        ));
    }
    if by_ext.len() > 1 {
        let counts: Vec<String> = by_ext
            .iter()
            .map(|(e, f)| format!("{} .{e}", f.len()))
            .collect();
        bail!(
            "{d}: the folder mixes capture types ({}); a series is one type: move the others out",
            counts.join(", ")
        );
    }
    let Some((ext, mut files)) = by_ext.into_iter().next() else {
        bail!("{d}: holds no capture files (.csv, .txt, .wav or .mat); a folder is read as a series of periodic captures");
    };
    files.sort_by_cached_key(|p| natural_key(&p.file_name().unwrap_or_default().to_string_lossy()));
    Ok((files, ext, notes))
}

impl Series {
    /// List and time the captures of `dir` for `rig`, reading the first capture whole and
    /// the first line of the others (their clock).
    pub fn scan(dir: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Series> {
        let (files, ext, notes) = list(dir)?;
        let stated = rig.acquisition.capture_interval_s;
        let accel: Vec<_> = rig.acceleration_channels().collect();
        let layout = match ext.as_str() {
            "csv" | "txt" => {
                headerless::sniff(&files[0], &headerless::first_line(&files[0])?, accel.len())?
            }
            _ => None,
        };
        let mut series = match layout {
            Some(layout) => {
                let sensitivity = accel.iter().map(|c| c.sensitivity).collect();
                let kind = Kind::Headerless {
                    layout,
                    sensitivity,
                };
                let (fs, note) = resolve_sample_rate(&files[0], None, &rig.acquisition, opts)?;
                let channels = accel
                    .iter()
                    .map(|c| ChannelInfo {
                        name: c.name.clone(),
                        axis: c.axis.clone(),
                        unit: c.unit.to_string(),
                    })
                    .collect();
                let format = if layout.clock { "femto-csv" } else { "csv" };
                let mut s = Series::new(dir, files, kind, fs, channels, format, notes);
                s.notes.push(note);
                s
            }
            None => {
                let first = super::load(&files[0], rig, opts)?;
                let channels = crate::recording::mcap::RecordingInfo::of(&first).channels;
                let fmt = first.provenance.format.clone();
                Series::new(
                    dir,
                    files,
                    Kind::Files,
                    first.sample_rate,
                    channels,
                    &fmt,
                    notes,
                )
            }
        };
        series.times = series.capture_times(stated)?;
        series.capture_len = series.read(0, rig, opts)?[0].len();
        series.describe_times();
        Ok(series)
    }

    fn new(
        dir: &Path,
        files: Vec<PathBuf>,
        kind: Kind,
        sample_rate: f64,
        channels: Vec<ChannelInfo>,
        format: &str,
        notes: Vec<String>,
    ) -> Series {
        Series {
            dir: dir.to_path_buf(),
            files,
            times: clock::from_interval(0, 1.0),
            kind,
            sample_rate,
            channels,
            capture_len: 0,
            format: format!("{format} series"),
            notes,
        }
    }

    /// Capture times from the files' clocks, or from the stated interval.
    fn capture_times(&self, stated: Option<f64>) -> Result<CaptureTimes> {
        let d = self.dir.display();
        match &self.kind {
            Kind::Headerless { layout, .. } if layout.clock => {
                let clocks: Vec<f64> = self
                    .files
                    .iter()
                    .map(|f| headerless::read_clock(f, layout))
                    .collect::<Result<_>>()?;
                clock::from_clock(&clocks, stated).map_err(|e| anyhow::anyhow!("{d}: {e}"))
            }
            _ => match stated {
                Some(dt) => Ok(clock::from_interval(self.files.len(), dt)),
                None if self.files.len() == 1 => Ok(clock::from_interval(1, 1.0)),
                None => bail!(
                    "{d}: {} captures carry no clock, so the time between them is unknown: set \
                     acquisition.capture_interval_s (seconds from one capture's start to the next) \
                     in the rig file",
                    self.files.len()
                ),
            },
        }
    }

    /// Notes on the timing: the interval and where it came from, the clock's jumps.
    fn describe_times(&mut self) {
        let t = &self.times;
        let n = self.files.len();
        let capture_s = self.capture_len as f64 / self.sample_rate;
        self.notes.push(format!(
            "{n} captures of {} samples ({capture_s:.3} s) every {} s ({}), {:.1} h in all",
            self.capture_len,
            t.interval_s,
            t.interval_from,
            (t.times_s.last().copied().unwrap_or(0.0) + capture_s) / 3600.0
        ));
        if !t.jumps.is_empty() {
            let listed: Vec<String> = t
                .jumps
                .iter()
                .take(5)
                .map(|&(k, d)| format!("{} ({:+.1} s)", self.name(k), d))
                .collect();
            self.notes.push(format!(
                "{}the capture clock jumps at {} file(s): {}{}; each placed one interval ({} s) after the capture before it",
                super::WARNING,
                t.jumps.len(),
                listed.join(", "),
                if t.jumps.len() > 5 { ", ..." } else { "" },
                t.interval_s
            ));
        }
    }

    /// The file name of capture `k`.
    pub fn name(&self, k: usize) -> String {
        self.files[k]
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    }

    /// Capture `k`'s samples, one vector per channel (in [`Series::channels`] order).
    pub fn read(&self, k: usize, rig: &RigConfig, opts: &ImportOptions) -> Result<Vec<Vec<f32>>> {
        let path = &self.files[k];
        let out = match &self.kind {
            Kind::Headerless {
                layout,
                sensitivity,
            } => headerless::read_capture(path, layout, sensitivity)?,
            Kind::Files => self.read_file(path, rig, opts)?,
        };
        if out.iter().any(|c| c.len() != out[0].len()) {
            bail!("{}: its channels differ in length", path.display());
        }
        Ok(out)
    }

    fn read_file(
        &self,
        path: &Path,
        rig: &RigConfig,
        opts: &ImportOptions,
    ) -> Result<Vec<Vec<f32>>> {
        let mut rec = super::load(path, rig, opts)?;
        if super::rates_differ(rec.sample_rate, self.sample_rate) {
            bail!(
                "{}: sampled at {} Hz but the series' first capture ({}) at {} Hz; a series has one sample rate",
                path.display(),
                rec.sample_rate,
                self.name(0),
                self.sample_rate
            );
        }
        self.channels
            .iter()
            .map(|c| {
                let i = rec.channels.iter().position(|r| r.name == c.name);
                match i {
                    Some(i) => Ok(std::mem::take(&mut rec.channels[i].samples)),
                    None => bail!(
                        "{}: has no channel {:?}, which the series' first capture ({}) has",
                        path.display(),
                        c.name,
                        self.name(0)
                    ),
                }
            })
            .collect()
    }
}

/// Stream a folder of captures ([`stream::SnapshotStream`]).
pub fn open(dir: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<stream::SnapshotStream> {
    let series = Series::scan(dir, rig, opts)?;
    stream::SnapshotStream::new(series, rig, opts)
}

/// Read a folder of captures whole, after checking it fits in the memory available.
pub fn load(dir: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let mut s = open(dir, rig, opts)?;
    let need = s.whole_bytes();
    if let Some(avail) = super::memory::available() {
        if need > avail.bytes {
            bail!(
                "{}: this command reads the whole series into memory: {} captures need about {} \
                 but {} is available ({}); `rigmon replay` streams a series capture by capture",
                dir.display(),
                s.series().files.len(),
                super::memory::size_text(need),
                super::memory::size_text(avail.bytes),
                avail.limited_by
            );
        }
    }
    stream::collect(&mut s)
}
