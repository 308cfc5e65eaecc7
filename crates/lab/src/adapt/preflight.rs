//! Everything `rigmon adapt` can know is wrong, refused before minutes of work start: the
//! rig file and its `[simulation]` section, the manifests, every listed file (it exists, it
//! imports, the rig's speed source reads a speed from it over the span calibration analyses,
//! it gives at least one whole feature window), the plan (derived from the machine's speeds
//! or given; no standing shaft, no speed the rig file does not allow:
//! [`super::plan::check_speeds`]) and one simulated recording of the plan at its slowest
//! speed, featurised as training will featurise it. What it loads is kept for the later
//! steps (labelled recordings featurised once, the measured recordings with their speeds).
//!
//! A healthy recording whose speed cannot be read (no shaft line, no hint) is no reason to
//! stop (issue 34): it is left out of calibration and of the spectral reference (its orders
//! are unknown), its windows' kurtosis joins the machine's speed-free healthy baseline, the
//! plan takes its speeds from the other recordings, and a warning says so. A faulty
//! recording, or a machine none of whose recordings gives a speed, is still refused.
//!
//! A row's `rpm` is a prior, not the truth (issue 34 item 3): where the vibration clearly
//! turns at the octave above or below it, the vibration's speed is used, and a warning names
//! the row ("labels.csv line 4, column rpm: rpm 600, the vibration turns at 1184 rpm in 9 of
//! 9 windows: the vibration is used; check the label"), kept in the report's warnings.

use super::plan::{self, MeasuredRange};
use super::AdaptOptions;
use crate::calibrate::measured;
use crate::config::RigConfig;
use crate::manifest::{read_manifest, ManifestEntry};
use crate::recording::Recording;
use crate::sim::plan::Plan;
use crate::train::dataset::RecordingFeatures;
use crate::train::featurise::featurise_all;
use crate::train::score::{analyze_all, ScoredRecording};
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use std::path::Path;

/// A manifest's rows, cut into the daemon's windows (the models and the rule score these).
pub struct LabelledSet {
    pub manifest: std::path::PathBuf,
    pub entries: Vec<ManifestEntry>,
    pub scored: Vec<ScoredRecording>,
}

/// What the checks loaded.
pub struct Checked {
    pub rig: RigConfig,
    pub measured: LabelledSet,
    /// The measured recordings labelled healthy whose speed was read, featurised (the model
    /// is aligned to them).
    pub healthy: Vec<RecordingFeatures>,
    /// Healthy recordings whose speed could not be read: (name, their windows' excess
    /// kurtosis), the speed-free part of the healthy baseline only.
    pub speed_free: Vec<(String, Vec<f32>)>,
    /// The measured rows calibration reads (every row whose speed was read).
    pub calibrated: Vec<ManifestEntry>,
    /// What the checks let through with a warning (also printed as it happens).
    pub warnings: Vec<String>,
    /// The measured recordings over their spans: (name, label, speed rpm, recording).
    pub recordings: Vec<(String, String, f64, Recording)>,
    pub holdout: Option<LabelledSet>,
    pub range: MeasuredRange,
    /// Seconds of each measured recording calibration analyses.
    pub calibration_seconds: f64,
    pub plan: Plan,
    pub plan_source: String,
    /// Where the plan's speeds come from.
    pub plan_speeds: String,
}

/// Rows of `manifest`, each file present, featurised (every error names the file).
fn labelled_set(manifest: &Path, rig: &RigConfig, what: &str) -> Result<LabelledSet> {
    let entries = read_manifest(manifest)?;
    if entries.is_empty() {
        bail!(
            "{}: no recordings listed; give at least one {what} recording of the machine",
            manifest.display()
        );
    }
    for e in &entries {
        if !e.path.exists() {
            bail!(
                "{}:{}: {} does not exist (paths are relative to the manifest's folder)",
                manifest.display(),
                e.line,
                e.path.display()
            );
        }
    }
    let scored = analyze_all(&entries, rig, &ProgressBar::hidden())
        .with_context(|| format!("{what} recordings of {}", manifest.display()))?;
    Ok(LabelledSet {
        manifest: manifest.to_path_buf(),
        entries,
        scored,
    })
}

/// Load a measured row over its span and read its mean speed as the analysis stage does
/// (the rig's speed source over the whole piece, as [`measured::mean_rpm`] reads it, with the
/// windows that contradict the row's `rpm`: a warning in `warnings`) from the first
/// `seconds` of it, as calibration reads it. When the speed source reads no speed from so
/// little signal (an estimate needs a few revolutions at the rig's lowest speed), the piece
/// is doubled, up to the whole span, until it does. Returns the speed, the seconds it
/// needed and the recording over its whole span; a span from which no speed can be read is
/// refused here, naming the file and the fix.
fn measured_speed(
    e: &ManifestEntry,
    rig: &RigConfig,
    seconds: f64,
    warnings: &mut Vec<String>,
) -> Result<(f64, f64, Recording)> {
    let mut rec = crate::importers::load(&e.path, rig, &e.import_options())
        .with_context(|| format!("loading {}", e.path.display()))?;
    let (a, b) = e.span.unwrap_or((0.0, f64::INFINITY));
    measured::cut_span(&mut rec, a, b);
    let whole = rec.duration_s();
    let mut s = seconds.min(whole);
    loop {
        let mut piece = rec.clone();
        measured::cut(&mut piece, 0.0, s);
        let read = crate::analysis::whole_recording_checked(&piece, rig).and_then(|(t, c)| {
            let rpm = t.mean_rpm(0.0, piece.duration_s());
            anyhow::ensure!(rpm.is_finite() && rpm > 0.0, "its speed reads {rpm} rpm");
            Ok((rpm, c))
        });
        match read {
            Ok((rpm, against)) => {
                if let Some(c) = against {
                    let w = match &e.nominal_rpm {
                        Some((_, at)) => format!("{at}: {}", c.message()),
                        None => format!("{}: {}", e.display_name(), c.message()),
                    };
                    tracing::warn!("{w}");
                    eprintln!("warning: {w}");
                    warnings.push(w);
                }
                return Ok((rpm, s, rec));
            }
            Err(err) if s >= whole => {
                return Err(err).with_context(|| {
                    format!(
                        "{}: no speed can be read from its {whole:.2} s (the rig file's [speed]: {:?}); \
                         give a longer recording or span, or a speed source that reads it",
                        e.display_name(),
                        rig.speed
                    )
                })
            }
            Err(_) => s = (2.0 * s).min(whole),
        }
    }
}

/// Calibration from one recording splits it in two halves (one to fit, one to confirm), so
/// where the speed is read from the vibration each half must hold the tracker's history: the
/// span is widened to twice it (as far as the recording reaches; shorter is refused by the
/// split, naming both lengths).
fn one_recording_span(
    loaded: &[(&ManifestEntry, (f64, f64, Recording))],
    rig: &RigConfig,
    span: f64,
) -> Result<f64> {
    let [(_, (_, _, rec))] = loaded else {
        return Ok(span);
    };
    let need = measured::split_needs_s(rec, rig)?;
    Ok(need.map_or(span, |n| span.max(n.min(rec.duration_s()))))
}

/// The plan's slowest recording, simulated and featurised as training will: a plan whose
/// recordings give no feature window on this rig fails here, not after the whole dataset.
fn dry_run(plan: &Plan, rig: &RigConfig) -> Result<()> {
    let runs = plan.expand()?;
    let slowest = runs
        .iter()
        .min_by(|a, b| {
            let lo = |r: &crate::sim::plan::PlannedRun| {
                r.scenario.profile.range_rpm(r.scenario.seconds).0
            };
            lo(a).total_cmp(&lo(b))
        })
        .context("the plan has no recording")?;
    let s = &slowest.scenario;
    let why = || {
        format!(
            "plan {:?}: its slowest recording ({}, {:.0} rpm, {} s) cannot be featurised on rig {:?}; \
             fix the plan (speeds, seconds) or the rig file before simulating the dataset",
            plan.name,
            slowest.stem,
            s.profile.range_rpm(s.seconds).0,
            s.seconds,
            rig.machine.id
        )
    };
    let rec = crate::sim::simulate(rig, s).with_context(why)?;
    let wins = crate::analysis::extract_recording(&rec, rig).with_context(why)?;
    let usable = wins.iter().any(|w| {
        let f = w.classifier_features(rig);
        f.len() == rig.features.n_bins() && f.iter().all(|v| v.is_finite())
    });
    if !usable {
        return Err(anyhow::anyhow!(
            "{} windows computed, none usable",
            wins.len()
        ))
        .with_context(why);
    }
    Ok(())
}

/// Refuse a plan without a recording of every class the model will predict (healthy, the
/// two race faults, and ball when a measured recording is labelled `ball`): training would
/// stop on it after the whole dataset is simulated.
fn check_classes(plan: &Plan, range: &MeasuredRange) -> Result<()> {
    let labels =
        crate::train::fit::class_labels(range.labels.iter().any(|l| *l == Condition::Ball));
    let runs = plan.expand()?;
    let missing: Vec<&String> = labels
        .iter()
        .filter(|l| {
            !runs
                .iter()
                .any(|r| crate::sim::label_of(&r.scenario.faults) == l.as_str())
        })
        .collect();
    if !missing.is_empty() {
        bail!(
            "plan {:?} simulates no {missing:?} recording; the model predicts {} and needs recordings of each: add a [[case]] for each",
            plan.name,
            labels.join(", ")
        );
    }
    Ok(())
}

/// A measured row's speed, as [`measured_speed`] reads it.
type Loaded<'a> = (&'a ManifestEntry, (f64, f64, Recording));
/// A healthy row without a speed: its name and its windows' excess kurtosis.
type SpeedFree = (String, Vec<f32>);

/// Every measured row's speed ([`measured_speed`]). A healthy row whose speed cannot be read
/// is set aside with a warning (its windows' kurtosis kept: [`SpeedFree`]); any other row
/// without a speed, or no row with one, is refused.
fn speeds<'a>(
    measured: &'a LabelledSet,
    rig: &RigConfig,
    seconds: f64,
) -> Result<(Vec<Loaded<'a>>, Vec<SpeedFree>, Vec<String>)> {
    let (mut loaded, mut speed_free, mut warnings) = (Vec::new(), Vec::new(), Vec::new());
    let mut first_error = None;
    for (e, scored) in measured.entries.iter().zip(&measured.scored) {
        match measured_speed(e, rig, seconds, &mut warnings) {
            Ok(x) => loaded.push((e, x)),
            Err(err) if Condition::is_healthy(&e.label) => {
                let kurtosis: Vec<f32> = scored
                    .windows
                    .iter()
                    .filter_map(|w| w.kurtosis.map(|(k, _)| k))
                    .collect();
                let w = format!(
                    "{}:{}: {err:#}. Going on without its speed: it is left out of calibration and of the spectral healthy reference, its {} windows' kurtosis joins the speed-free healthy baseline, and the plan's speeds come from the other recordings",
                    measured.manifest.display(),
                    e.line,
                    kurtosis.len()
                );
                tracing::warn!("{w}");
                eprintln!("warning: {w}");
                warnings.push(w);
                speed_free.push((e.display_name(), kurtosis));
                first_error.get_or_insert(err);
            }
            Err(err) => return Err(err),
        }
    }
    if loaded.is_empty() {
        let err = first_error.unwrap_or_else(|| anyhow::anyhow!("no measured recording"));
        return Err(err.context(format!(
            "{}: the speed of none of the measured recordings can be read; state it (labels.csv `rpm`, [speed] source = \"fixed\") for at least one",
            measured.manifest.display()
        )));
    }
    Ok((loaded, speed_free, warnings))
}

/// Run every check; returns what they loaded.
pub fn check(o: &AdaptOptions) -> Result<Checked> {
    if o.seeds == 0 {
        bail!("--seeds 0: give at least 1");
    }
    let rig = RigConfig::load(&o.rig)?;
    crate::sim::rig_simulation(&rig)?;
    let measured = labelled_set(&o.measured, &rig, "measured")?;
    let holdout = match &o.holdout {
        Some(h) => Some(labelled_set(h, &rig, "held-out")?),
        None => None,
    };
    let (loaded, speed_free, warnings) = speeds(&measured, &rig, o.seconds)?;
    let read: Vec<ManifestEntry> = loaded.iter().map(|(e, _)| (*e).clone()).collect();
    let healthy_rows: Vec<ManifestEntry> = read
        .iter()
        .filter(|e| Condition::is_healthy(&e.label))
        .cloned()
        .collect();
    let healthy = featurise_all(&healthy_rows, &rig, &ProgressBar::hidden())
        .with_context(|| format!("healthy recordings of {}", o.measured.display()))?;
    // one span for every recording: the longest any of them needed for its speed
    let calibration_seconds = loaded
        .iter()
        .map(|(_, (_, s, _))| *s)
        .fold(o.seconds, f64::max);
    let calibration_seconds = one_recording_span(&loaded, &rig, calibration_seconds)?;
    let mut recordings = Vec::new();
    let mut items = Vec::new();
    for (e, (rpm, _, mut rec)) in loaded {
        measured::cut(&mut rec, 0.0, calibration_seconds);
        items.push((e.display_name(), rpm, rec.sample_rate, e.label.clone()));
        recordings.push((e.display_name(), e.label.clone(), rpm, rec));
    }
    let range = MeasuredRange::of(&items)?;
    let (plan, plan_source) = match &o.plan {
        Some(p) => (Plan::load(p)?, p.display().to_string()),
        None => (
            plan::derive(&rig, &range, o.recordings, o.sim_seconds)?,
            "derived".to_string(),
        ),
    };
    plan::check_speeds(&plan, &rig)
        .with_context(|| format!("checking the plan ({plan_source})"))?;
    check_classes(&plan, &range).with_context(|| format!("checking the plan ({plan_source})"))?;
    let plan_speeds = match &o.plan {
        Some(p) => format!("the given plan {}", p.display()),
        None => plan::speed_basis(&rig, &range).1,
    };
    dry_run(&plan, &rig)?;
    Ok(Checked {
        rig,
        healthy,
        speed_free,
        calibrated: read,
        warnings,
        measured,
        recordings,
        holdout,
        range,
        calibration_seconds,
        plan,
        plan_source,
        plan_speeds,
    })
}
