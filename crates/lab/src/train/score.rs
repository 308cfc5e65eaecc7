//! Scoring labelled recordings of a manifest whole-record, with what the daemon would say.
//! Each recording is cut into the daemon's windows by the analysis stage
//! ([`crate::analysis::analyze_recording`]: real window times, quality flags, the fault-band
//! ratios, no window dropped), then an ONNX model file runs through tract (as the daemon runs
//! it) and every window through the daemon's own verdict and health state machine
//! ([`HealthStateMachine::observe`], default `[health]`); the rule baseline
//! ([`crate::model::rule`]) judges the same windows. Both go through the same
//! [`crate::evaluate::score`]. `rigmon evaluate` and `rigmon adapt` share this.
//!
//! Every record is scored whatever its label: a class the model lacks (a ball record for a
//! three-class model) is its own row of the confusion matrix, so a ball fault the model calls
//! healthy is a missed alarm. A window whose quality forbids a verdict votes for nothing (the
//! daemon calls it `unknown`).

use crate::config::RigConfig;
use crate::dsp::fault_band_ratios::FaultBandRatios;
use crate::evaluate::{DaemonOutcome, RecordOutcome};
use crate::health::verdict::{quality_problem, speed_only};
use crate::health::{Basis, HealthPolicy, HealthStateMachine, WindowInput};
use crate::importers;
use crate::manifest::ManifestEntry;
use crate::model::evidence::{BaselineSpread, FamilyBins};
use crate::model::rule::{EnvelopeRule, RULE_LABELS};
use crate::model::{OnnxClassifier, ALL_LABELS};
use crate::vocabulary::QualityFlag;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;

/// One window of a labelled recording, as the analysis stage gives it.
#[derive(Debug, Clone)]
pub struct ScoredWindow {
    /// Window start and end, s since the recording's first sample.
    pub t_start: f64,
    pub t_end: f64,
    /// Mean shaft speed (NaN without features).
    pub rpm: f64,
    /// The classifier channel's features (empty without features).
    pub features: Vec<f32>,
    /// Why the daemon would call the window `unknown` for its data quality (None: it would
    /// not); [`quality_problem`].
    pub quality: Option<QualityFlag>,
    /// The classifier channel's band ratios at the fault orders (what the rule judges).
    pub fault_bands: Option<FaultBandRatios>,
    /// The classifier channel's excess kurtosis and the samples it was measured over (a
    /// window without a speed has it too; None for spoilt samples).
    pub kurtosis: Option<(f32, usize)>,
}

/// A labelled recording cut into the daemon's windows.
#[derive(Debug, Clone)]
pub struct ScoredRecording {
    /// As the manifest names it (with its span, if any).
    pub path_text: String,
    pub label: String,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    pub windows: Vec<ScoredWindow>,
}

impl ScoredRecording {
    /// Mean rpm over the windows that have one.
    pub fn rpm(&self) -> f64 {
        let v: Vec<f64> = self
            .windows
            .iter()
            .map(|w| w.rpm)
            .filter(|r| r.is_finite())
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }
}

/// Load one manifest row and cut it into the daemon's windows (those inside its span).
pub fn analyze_entry(entry: &ManifestEntry, rig: &RigConfig) -> Result<ScoredRecording> {
    let at = || format!("manifest line {}: {}", entry.line, entry.path.display());
    let sha256 =
        crate::model::digest::sha256_of_path(&entry.path).with_context(|| at().to_string())?;
    let rec = importers::load(&entry.path, rig, &entry.import_options())
        .with_context(|| format!("{}: loading", at()))?;
    let classifier = rig
        .classifier_channel()
        .context("the rig file names no classifier channel (features.classifier_axis)")?
        .name
        .clone();
    let all = crate::analysis::analyze_recording(&rec, rig).with_context(at)?;
    let n_all = all.len();
    let windows: Vec<ScoredWindow> = all
        .into_iter()
        .filter(|a| entry.keeps_window(a.t_start, a.t_end))
        .map(|a| {
            let quality = quality_problem(&a, &classifier);
            let (rpm, features) = match &a.features {
                Ok(fw) => (fw.rpm, fw.classifier_features(rig).to_vec()),
                Err(_) => (f64::NAN, Vec::new()),
            };
            let kurtosis = a.classifier_kurtosis;
            ScoredWindow {
                t_start: a.t_start,
                t_end: a.t_end,
                rpm,
                features,
                quality,
                fault_bands: a.fault_bands,
                kurtosis,
            }
        })
        .collect();
    if windows.is_empty() {
        bail!(
            "{}: no whole feature window within the row's span ({:?}; {n_all} windows of {} s in the recording): widen the span or use a longer recording",
            at(),
            entry.span,
            rig.features.window_s
        );
    }
    Ok(ScoredRecording {
        path_text: entry.display_name(),
        label: entry.label.clone(),
        sha256,
        windows,
    })
}

/// [`analyze_entry`] on every row, in parallel, keeping manifest order; `progress` is ticked
/// per file.
pub fn analyze_all(
    entries: &[ManifestEntry],
    rig: &RigConfig,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<ScoredRecording>> {
    entries
        .par_iter()
        .map(|e| {
            let r = analyze_entry(e, rig);
            progress.inc(1);
            r
        })
        .collect()
}

/// Per-window outcomes of a model on labelled recordings.
#[derive(Debug, Clone, Default)]
pub struct ModelOutcomes {
    /// The scored classes: the model's, then those only the records or the verdicts name
    /// (e.g. `ball` for a three-class model). Outcome class indices point into this list.
    pub labels: Vec<String>,
    pub outcomes: Vec<RecordOutcome>,
    /// Recordings the model was fine-tuned on (by content hash): never scored.
    pub excluded: Vec<String>,
}

impl ModelOutcomes {
    /// The recordings that were scored (not excluded), in order.
    pub fn scored<'a>(&self, recs: &'a [ScoredRecording]) -> Vec<&'a ScoredRecording> {
        recs.iter()
            .filter(|r| !self.excluded.contains(&r.path_text))
            .collect()
    }

    /// Record labels that are not among the model's classes (scored as their own rows).
    pub fn labels_not_in_model(&self, model: &[String]) -> Vec<String> {
        self.labels
            .iter()
            .filter(|l| !model.contains(l))
            .cloned()
            .collect()
    }
}

/// Hashes of the recordings a model was fine-tuned on (from its metadata).
pub fn finetune_hashes(meta: &crate::model::ModelMeta) -> Vec<String> {
    serde_json::from_str::<serde_json::Value>(&meta.finetune)
        .ok()
        .and_then(|v| v.get("finetune_sha256").cloned())
        .and_then(|v| serde_json::from_value::<Vec<String>>(v).ok())
        .unwrap_or_default()
}

/// `first`, then every label of `more` not in it: [`ALL_LABELS`] in their order, others
/// sorted.
pub fn scored_labels<'a>(first: &[String], more: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut extra: Vec<&str> = more
        .into_iter()
        .filter(|l| !first.iter().any(|f| f == l))
        .collect();
    extra.sort_by_key(|l| (ALL_LABELS.iter().position(|a| a == l).unwrap_or(99), *l));
    extra.dedup();
    let mut out = first.to_vec();
    out.extend(extra.into_iter().map(str::to_string));
    out
}

/// One record's windows through the model and the daemon's verdict and state machine.
struct RecordRun {
    /// The decided class of each window that has one (its name).
    classes: Vec<String>,
    /// Whether that window's state is `unknown` (novel or doubtful and not clearly a fault).
    unknown: Vec<bool>,
    daemon: DaemonOutcome,
}

/// Whether the classifier runs on a window: sound data, or sound samples whose speed alone is
/// in doubt (classified at the speed it was analysed at, to name a speed-free alarm).
fn classified(w: &ScoredWindow) -> bool {
    match w.quality {
        None => true,
        Some(q) => {
            speed_only(q) && !w.features.is_empty() && w.features.iter().all(|v| v.is_finite())
        }
    }
}

fn run_record(
    clf: &OnnxClassifier,
    r: &ScoredRecording,
    (bins, rule): (&FamilyBins, &EnvelopeRule),
    spread: Option<BaselineSpread>,
    policy: &HealthPolicy,
) -> Result<RecordRun> {
    let meta = clf.meta();
    let impulse_baseline = meta.alignment.as_ref().and_then(|a| a.impulse());
    let mut sm = HealthStateMachine::new(policy.clone(), &meta.labels)?;
    sm.set_hop_fraction(bins.hop_fraction());
    let mut run = RecordRun {
        classes: Vec::new(),
        unknown: Vec::new(),
        daemon: DaemonOutcome::default(),
    };
    for w in &r.windows {
        let p =
            if classified(w) {
                Some(clf.predict(&w.features).with_context(|| {
                    format!("{}: window at t = {:.3} s", r.path_text, w.t_start)
                })?)
            } else {
                None
            };
        let evidence = p.as_ref().and_then(|p| {
            let dev = p.baseline_deviation.as_deref()?;
            Some(bins.evidence(dev, spread?, w.rpm))
        });
        let s = sm.observe(
            w.t_end,
            &WindowInput {
                labels: &meta.labels,
                probs: p.as_ref().map_or(&[][..], |p| &p.probs),
                novelty: p.as_ref().map_or(f32::NAN, |p| p.novelty),
                model_novelty_threshold: meta.novelty_threshold,
                quality: w.quality,
                beyond_baseline: p.as_ref().and_then(|p| p.beyond_baseline),
                evidence,
                impulse: w
                    .kurtosis
                    .zip(impulse_baseline)
                    .map(|((k, n), b)| b.impulse(k, n)),
                rule: w.fault_bands.as_ref().map(|b| rule.reading(b)),
            },
        );
        let d = &mut run.daemon;
        match &s.window.class {
            Some(c) => {
                run.classes.push(c.clone());
                run.unknown.push(s.window.unknown_reason.is_some());
                d.unknown_windows += usize::from(s.window.unknown_reason.is_some());
            }
            None => d.bad_quality_windows += 1,
        }
        d.alarm_despite_windows += usize::from(s.window.alarm_despite.is_some());
        d.evidence_windows += usize::from(s.window.basis == Basis::Evidence);
        d.impulsive_windows += usize::from(s.window.basis == Basis::Impulsive);
        d.window_states.push(s.window_state);
        d.state = s.state;
    }
    Ok(run)
}

/// Run the model on every window of every recording it may be scored on, each window through
/// the daemon's verdict and health state machine (default `[health]`).
pub fn model_outcomes(
    clf: &OnnxClassifier,
    recs: &[ScoredRecording],
    rig: &RigConfig,
) -> Result<ModelOutcomes> {
    model_outcomes_with(clf, recs, rig, &HealthPolicy::default())
}

/// [`model_outcomes`] under a given `[health]` policy.
pub fn model_outcomes_with(
    clf: &OnnxClassifier,
    recs: &[ScoredRecording],
    rig: &RigConfig,
    policy: &HealthPolicy,
) -> Result<ModelOutcomes> {
    let meta = clf.meta();
    let used = finetune_hashes(meta);
    let (bins, spread) = (
        FamilyBins::for_rig(rig),
        meta.alignment.as_ref().and_then(|a| a.spread()),
    );
    let rule = EnvelopeRule::for_rig(rig, crate::model::rule::RuleSettings::default());
    let mut excluded = Vec::new();
    let mut runs = Vec::new();
    for r in recs {
        if used.contains(&r.sha256) {
            excluded.push(r.path_text.clone());
            continue;
        }
        runs.push((r, run_record(clf, r, (&bins, &rule), spread, policy)?));
    }
    let labels = scored_labels(
        &meta.labels,
        runs.iter().flat_map(|(r, run)| {
            std::iter::once(r.label.as_str()).chain(run.classes.iter().map(String::as_str))
        }),
    );
    let index = |l: &str| labels.iter().position(|x| x == l).expect("listed above");
    let outcomes = runs
        .into_iter()
        .map(|(r, run)| RecordOutcome {
            path: r.path_text.clone(),
            label: index(&r.label),
            predicted: run.classes.iter().map(|c| index(c)).collect(),
            unknown: run.unknown,
            rpm: r.rpm(),
            daemon: Some(run.daemon),
        })
        .collect();
    Ok(ModelOutcomes {
        labels,
        outcomes,
        excluded,
    })
}

/// The scored classes of the rule: `first` (e.g. a model's scored classes), then healthy,
/// outer and inner race, then every record's label (a ball record is its own row: the rule
/// never names it, so it can only be an alarm or a miss).
pub fn rule_labels(first: &[String], recs: &[&ScoredRecording]) -> Vec<String> {
    scored_labels(
        first,
        RULE_LABELS
            .iter()
            .copied()
            .chain(recs.iter().map(|r| r.label.as_str())),
    )
}

/// The rule on the analysis stage's windows of `recs` (windows whose quality forbids a
/// verdict are not judged, as the daemon judges none); class indices are into `labels`,
/// which must hold the rule's classes and every record's label ([`rule_labels`]).
pub fn rule_outcomes(
    rule: &EnvelopeRule,
    recs: &[&ScoredRecording],
    labels: &[String],
) -> Result<Vec<RecordOutcome>> {
    let map = crate::model::rule::class_map(labels)?;
    recs.iter()
        .map(|r| {
            let label = labels.iter().position(|l| l == &r.label).with_context(|| {
                format!(
                    "{}: label {:?} is not among the scored classes {labels:?}",
                    r.path_text, r.label
                )
            })?;
            let predicted: Vec<usize> = r
                .windows
                .iter()
                .filter(|w| w.quality.is_none())
                .filter_map(|w| w.fault_bands.as_ref())
                .map(|b| map[rule.judge_bands(b).class])
                .collect();
            Ok(RecordOutcome {
                path: r.path_text.clone(),
                label,
                unknown: vec![false; predicted.len()],
                predicted,
                rpm: r.rpm(),
                daemon: None,
            })
        })
        .collect()
}
