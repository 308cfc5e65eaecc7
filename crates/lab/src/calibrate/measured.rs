//! The measured side of calibration: recordings (a `labels.csv` manifest, or recording files
//! whose label is taken from their metadata, else `healthy`), each reduced to an operating
//! point (mean speed from the rig's speed source, fault class), cut to a common length and
//! brought to the simulator's output rate ([`super::rate`]). Also the checkerboard fit /
//! held-out split.

use super::rate;
use crate::config::RigConfig;
use crate::importers::{self, ImportOptions};
use crate::manifest::{manifest_path, read_manifest};
use crate::recording::captures::{self, Timeline};
use crate::recording::Recording;
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Two operating speeds count as different when they differ by more than 5 %: enough to tell
/// order-locked from frequency-locked content, and to fit a speed law.
pub fn distinct_speeds(a: f64, b: f64) -> bool {
    (a - b).abs() > 0.05 * a.max(b)
}

/// Whether `rpm` holds more than one operating speed ([`distinct_speeds`]).
pub fn several_speeds(rpm: &[f64]) -> bool {
    rpm.iter().any(|&a| distinct_speeds(a, rpm[0]))
}

/// One measured recording at one operating point.
#[derive(Debug, Clone)]
pub struct Measured {
    /// File name (or `file#half`) for reports.
    pub name: String,
    pub label: String,
    pub faults: Vec<Condition>,
    /// Mean shaft speed over the analysed span, rpm.
    pub rpm: f64,
    /// The analysed span, at the rate it is analysed at (`recording.sample_rate`: the
    /// simulator's output rate when it was recorded faster, [`super::rate`]).
    pub recording: Recording,
    /// The rate the recording was made at, Hz.
    pub recorded_sample_rate: f64,
}

/// Load measured recordings: one `labels.csv` (or a folder holding one) or recording files.
/// Each is cut to at most `max_seconds` (`f64::INFINITY`: whole), its mean speed taken at
/// the recorded rate, and then brought to the simulator's output rate
/// ([`rate::to_analysis_rate`]).
/// One recording to load: path, label, import options, the manifest row's start_s/end_s.
type ToLoad = (PathBuf, Option<String>, ImportOptions, Option<(f64, f64)>);

pub fn load(rig: &RigConfig, inputs: &[PathBuf], max_seconds: f64) -> Result<Vec<Measured>> {
    load_with(rig, inputs, max_seconds, true)
}

/// [`load`], the files read in parallel or (as before issue 37, `rigmon bench calibrate`'s
/// comparison) one after the other.
pub fn load_with(
    rig: &RigConfig,
    inputs: &[PathBuf],
    max_seconds: f64,
    parallel: bool,
) -> Result<Vec<Measured>> {
    let mut files: Vec<ToLoad> = Vec::new();
    for p in inputs {
        let is_manifest = p.is_dir() || p.extension().is_some_and(|e| e == "csv") && is_manifest(p);
        if is_manifest {
            for e in read_manifest(&manifest_path(p))? {
                let opts = e.import_options();
                files.push((e.path, Some(e.label), opts, e.span));
            }
        } else {
            files.push((p.clone(), None, ImportOptions::default(), None));
        }
    }
    load_files(rig, files, max_seconds, parallel)
}

/// [`load`] on manifest rows already read (`rigmon adapt` leaves out a healthy row whose
/// speed cannot be read).
pub fn load_entries(
    rig: &RigConfig,
    entries: &[crate::manifest::ManifestEntry],
    max_seconds: f64,
) -> Result<Vec<Measured>> {
    let files = entries
        .iter()
        .map(|e| {
            (
                e.path.clone(),
                Some(e.label.clone()),
                e.import_options(),
                e.span,
            )
        })
        .collect();
    load_files(rig, files, max_seconds, true)
}

fn load_files(
    rig: &RigConfig,
    files: Vec<ToLoad>,
    max_seconds: f64,
    parallel: bool,
) -> Result<Vec<Measured>> {
    if files.is_empty() {
        bail!("no measured recordings given; pass --measured <labels.csv> or recording files");
    }
    // each file is read, cut, its speed read and resampled on its own: in parallel
    if parallel {
        files
            .into_par_iter()
            .map(|f| load_one(rig, f, max_seconds))
            .collect()
    } else {
        files
            .into_iter()
            .map(|f| load_one(rig, f, max_seconds))
            .collect()
    }
}

/// Load one recording of [`load_files`].
fn load_one(rig: &RigConfig, file: ToLoad, max_seconds: f64) -> Result<Measured> {
    let (path, label, opts, span) = file;
    let mut rec = importers::load(&path, rig, &opts)
        .with_context(|| format!("loading measured recording {}", path.display()))?;
    let label = label
        .or_else(|| rec.metadata.get("label").cloned())
        .unwrap_or_else(|| Condition::Healthy.as_str().into());
    let faults =
        Condition::parse_faults(&label).with_context(|| format!("label of {}", path.display()))?;
    // A manifest row may name part of its file (`start_s`/`end_s`): only that part is
    // analysed, and at most `max_seconds` of it.
    let (start_s, end_s) = span.unwrap_or((0.0, f64::INFINITY));
    cut_span(&mut rec, start_s, end_s);
    cut(&mut rec, 0.0, max_seconds);
    if rec.is_empty() {
        bail!(
                "{}: nothing left between start_s {start_s} and end_s {end_s}; the recording is shorter, widen the span in the manifest",
                path.display()
            );
    }
    let rpm = mean_rpm(&rec, rig).with_context(|| format!("speed of {}", path.display()))?;
    let recorded_sample_rate = rate::to_analysis_rate(&mut rec, rig)
        .with_context(|| format!("bringing {} to the simulation rate", path.display()))?;
    Ok(Measured {
        name: path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into(),
        ),
        label,
        faults,
        rpm,
        recording: rec,
        recorded_sample_rate,
    })
}

fn is_manifest(p: &Path) -> bool {
    std::fs::read_to_string(p)
        .ok()
        .and_then(|t| t.lines().next().map(|h| h.to_ascii_lowercase()))
        .is_some_and(|h| h.split(',').any(|c| c.trim() == "label"))
}

/// Mean speed of a recording over its whole length, rpm.
pub fn mean_rpm(rec: &Recording, rig: &RigConfig) -> Result<f64> {
    let track = crate::analysis::whole_recording(rec, rig)?;
    Ok(track.mean_rpm(0.0, rec.duration_s()))
}

/// Seconds a recording must last to be split in two halves ([`split_single`]) whose speed can
/// each be read: twice the vibration tracker's history; None when the speed is not read from
/// the vibration.
pub fn split_needs_s(rec: &Recording, rig: &RigConfig) -> Result<Option<f64>> {
    let speed = crate::analysis::SpeedSource::for_recording(rec, rig)?;
    Ok(speed.history_s().map(|h| 2.0 * h))
}

/// Keep a manifest row's span `[start_s, end_s)`: times on the recording's clock (for a
/// series of captures, since the first capture, the time between captures included).
pub fn cut_span(rec: &mut Recording, start_s: f64, end_s: f64) {
    if !captures::cut_on(rec, start_s, end_s - start_s, Timeline::Clock) {
        cut(rec, start_s, end_s - start_s);
    }
}

/// Keep samples in [t0, t0 + seconds) of every channel and the analog tacho: seconds of
/// signal, as [`Recording::duration_s`] counts them (a series of captures keeps the whole
/// captures that start in it, never a piece of one).
pub fn cut(rec: &mut Recording, t0: f64, seconds: f64) {
    if captures::cut_on(rec, t0, seconds, Timeline::Signal) {
        return;
    }
    let n = rec.len();
    let a = ((t0 * rec.sample_rate) as usize).min(n);
    let b = (a + (seconds * rec.sample_rate).clamp(0.0, n as f64) as usize).min(n);
    for c in &mut rec.channels {
        c.samples = c.samples[a..b].to_vec();
    }
    match &mut rec.tacho {
        Some(crate::recording::Tacho::Analog { samples, .. }) => {
            *samples = samples[a.min(samples.len())..b.min(samples.len())].to_vec()
        }
        Some(crate::recording::Tacho::Edges { times_s }) => {
            let (ta, tb) = (a as f64 / rec.sample_rate, b as f64 / rec.sample_rate);
            *times_s = times_s
                .iter()
                .filter(|t| **t >= ta && **t < tb)
                .map(|t| t - ta)
                .collect();
        }
        None => {}
    }
}

/// Which part each recording belongs to: `true` = fit, `false` = held out. Checkerboard by
/// (speed rank + class rank), so both parts see every speed when there are >= 2 classes.
/// A single recording is split in time by the caller (see [`split_single`]).
pub fn checkerboard(ms: &[Measured]) -> Vec<bool> {
    let mut speeds: Vec<i64> = ms.iter().map(|m| m.rpm.round() as i64).collect();
    speeds.sort_unstable();
    speeds.dedup_by(|a, b| (*a - *b).abs() <= 20);
    let mut labels: Vec<&str> = ms.iter().map(|m| m.label.as_str()).collect();
    labels.sort_unstable();
    labels.dedup();
    let mut part: Vec<bool> = ms
        .iter()
        .map(|m| {
            let si = speeds
                .iter()
                .position(|s| (m.rpm.round() as i64 - s).abs() <= 20)
                .unwrap_or(0);
            let li = labels.iter().position(|l| *l == m.label).unwrap_or(0);
            (si + li) % 2 == 0
        })
        .collect();
    // one class, several recordings per speed: alternate by order
    if part.iter().all(|p| *p) || part.iter().all(|p| !*p) {
        part = (0..ms.len()).map(|i| i % 2 == 0).collect();
    }
    part
}

/// A single recording: its first half fits, its second half is held out.
pub fn split_single(m: &Measured, rig: &RigConfig) -> Result<Vec<Measured>> {
    let half = m.recording.duration_s() / 2.0;
    if let Some(need) = split_needs_s(&m.recording, rig)?.filter(|&n| 2.0 * half < n) {
        let need = need / 2.0;
        bail!(
            "{}: {:.2} s of signal; calibrating from one recording splits it in two halves (one \
             to fit, one to confirm the fit), and reading the speed from the vibration down to \
             the rig's min_rpm needs {need:.2} s in each: give at least {:.2} s, or a second \
             recording, or state the speed (labels.csv `rpm`, [speed] source = \"fixed\")",
            m.name,
            m.recording.duration_s(),
            2.0 * need
        );
    }
    let mut out = Vec::new();
    for (i, tag) in ["first half", "second half"].iter().enumerate() {
        let mut rec = m.recording.clone();
        cut(&mut rec, i as f64 * half, half);
        let rpm = mean_rpm(&rec, rig)?;
        out.push(Measured {
            name: format!("{} ({tag})", m.name),
            label: m.label.clone(),
            faults: m.faults.clone(),
            rpm,
            recording: rec,
            recorded_sample_rate: m.recorded_sample_rate,
        });
    }
    Ok(out)
}
