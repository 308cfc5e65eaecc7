//! Scoring labelled recordings of a manifest whole-record: an ONNX model file run through
//! tract (as the daemon runs it) on the recordings' feature windows, and the rule baseline
//! ([`crate::model::rule`]) on the same recordings, so both go through the same
//! [`crate::evaluate::score`]. `rigmon evaluate` and `rigmon adapt` share this.

use super::dataset::RecordingFeatures;
use crate::config::RigConfig;
use crate::evaluate::{daemon_outcome, RecordOutcome, WindowEvidence};
use crate::health::HealthPolicy;
use crate::importers;
use crate::manifest::ManifestEntry;
use crate::model::rule::{class_map, EnvelopeRule};
use crate::model::OnnxClassifier;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;

/// Per-window outcomes of a model on featurised recordings, plus what was left out.
#[derive(Debug, Clone, Default)]
pub struct ModelOutcomes {
    pub outcomes: Vec<RecordOutcome>,
    /// Recordings the model was fine-tuned on (by content hash): never scored.
    pub excluded: Vec<String>,
    /// Recordings whose label is not among the model's classes.
    pub skipped: Vec<String>,
}

/// Hashes of the recordings a model was fine-tuned on (from its metadata).
pub fn finetune_hashes(meta: &crate::model::ModelMeta) -> Vec<String> {
    serde_json::from_str::<serde_json::Value>(&meta.finetune)
        .ok()
        .and_then(|v| v.get("finetune_sha256").cloned())
        .and_then(|v| serde_json::from_value::<Vec<String>>(v).ok())
        .unwrap_or_default()
}

/// Run the model on every window of every recording it may be scored on, and the windows
/// through the daemon's health state machine (default `[health]`, windows of `rig`).
pub fn model_outcomes(
    clf: &OnnxClassifier,
    recs: &[RecordingFeatures],
    rig: &RigConfig,
) -> Result<ModelOutcomes> {
    let meta = clf.meta();
    let used = finetune_hashes(meta);
    let mut out = ModelOutcomes::default();
    for r in recs {
        if used.contains(&r.sha256) {
            out.excluded.push(r.path_text.clone());
            continue;
        }
        let Some(label) = meta.labels.iter().position(|l| l == &r.label) else {
            out.skipped.push(r.path_text.clone());
            continue;
        };
        let (mut predicted, mut unknown, mut evidence) = (Vec::new(), Vec::new(), Vec::new());
        for row in r.windows.rows() {
            let p = clf.predict(&row.to_vec())?;
            predicted.push(p.class);
            unknown.push(p.unknown);
            evidence.push(WindowEvidence {
                probs: p.probs,
                novelty: p.novelty,
                beyond_baseline: p.beyond_baseline,
            });
        }
        let daemon = daemon_outcome(
            &meta.labels,
            &evidence,
            meta.novelty_threshold,
            rig.features.window_s,
            rig.features.hop_s,
            &HealthPolicy::default(),
        )?;
        out.outcomes.push(RecordOutcome {
            path: r.path_text.clone(),
            label,
            predicted,
            unknown,
            rpm: r.rpm,
            daemon: Some(daemon),
        });
    }
    Ok(out)
}

/// The scored classes of the rule alone: healthy, outer and inner race, and `ball` when a
/// manifest holds ball records (the rule never names it; such a record counts as an alarm).
pub fn rule_labels(entries: &[ManifestEntry]) -> Vec<String> {
    let mut l: Vec<String> = crate::model::rule::RULE_LABELS
        .iter()
        .map(|s| s.to_string())
        .collect();
    if entries.iter().any(|e| e.label == "ball") {
        l.push("ball".into());
    }
    l
}

/// The rule on every window of the entries whose label is in `labels` (in parallel, manifest
/// order kept); class indices are into `labels`. `progress` is ticked per file.
pub fn rule_outcomes(
    rule: &EnvelopeRule,
    entries: &[ManifestEntry],
    rig: &RigConfig,
    labels: &[String],
    progress: &indicatif::ProgressBar,
) -> Result<Vec<RecordOutcome>> {
    let map = class_map(labels)?;
    let scored: Vec<&ManifestEntry> = entries
        .iter()
        .filter(|e| labels.contains(&e.label))
        .collect();
    scored
        .par_iter()
        .map(|e| {
            let rec = importers::load(&e.path, rig, &e.import_options()).with_context(|| {
                format!("manifest line {}: loading {}", e.line, e.path.display())
            })?;
            let window_s = rig.features.window_s;
            let v: Vec<_> = rule
                .judge_recording(&rec, rig)?
                .into_iter()
                .filter(|w| e.keeps_window(w.t_start, w.t_start + window_s))
                .collect();
            if v.is_empty() {
                bail!(
                    "{}: no whole window within the manifest row's span (line {})",
                    e.path.display(),
                    e.line
                );
            }
            progress.inc(1);
            let n = v.len().max(1) as f64;
            Ok(RecordOutcome {
                path: e.display_name(),
                label: labels
                    .iter()
                    .position(|l| l == &e.label)
                    .expect("filtered on the labels"),
                predicted: v.iter().map(|w| map[w.class]).collect(),
                unknown: vec![false; v.len()],
                rpm: v.iter().map(|w| w.rpm).sum::<f64>() / n,
                daemon: None,
            })
        })
        .collect()
}
