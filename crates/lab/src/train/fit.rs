//! From featurised recordings to a complete classifier: choose the classes, split by
//! recording, train, fit and calibrate the novelty detector on held-out simulated windows,
//! score the validation recordings whole-record, and fill the model metadata.

use super::dataset::{data_hash, RecordingFeatures};
use super::split;
use super::trainer::{self, EpochStats, TrainConfig, Windows};
use crate::config::RigConfig;
use crate::evaluate::{self, Evaluation, RecordOutcome};
use crate::model::classifier::TrainedModel;
use crate::model::meta::ModelMeta;
use crate::model::novelty::Mahalanobis;
use crate::model::preprocess::NORMALIZATION_NAME;
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use ndarray::{concatenate, Array2, Axis};
use serde::Serialize;

/// Quantile of validation novelty scores used for the threshold, and the margin on top.
pub const NOVELTY_QUANTILE: f64 = 0.99;
pub const NOVELTY_MARGIN: f32 = 1.25;
/// Shrinkage of the novelty covariance towards its mean variance.
pub const NOVELTY_SHRINKAGE: f64 = 0.1;

/// The classes a model learns: healthy, outer_race, inner_race (+ ball).
pub fn class_labels(ball: bool) -> Vec<String> {
    let n = if ball { 4 } else { 3 };
    Condition::NAMES[..n]
        .iter()
        .map(|s| s.to_string())
        .collect()
}

/// Stack the windows of the chosen recordings (all must have a label in `labels`).
pub fn to_windows(recs: &[RecordingFeatures], idx: &[usize], labels: &[String]) -> Windows {
    let n_bins = recs.first().map_or(0, |r| r.windows.ncols());
    let mut parts = Vec::new();
    let (mut y, mut rec) = (Vec::new(), Vec::new());
    for &i in idx {
        let r = &recs[i];
        let c = labels
            .iter()
            .position(|l| l == &r.label)
            .expect("label filtered before");
        parts.push(r.windows.view());
        y.extend(std::iter::repeat_n(c, r.windows.nrows()));
        rec.extend(std::iter::repeat_n(i, r.windows.nrows()));
    }
    let x = if parts.is_empty() {
        Array2::zeros((0, n_bins))
    } else {
        concatenate(Axis(0), &parts).expect("same bin count")
    };
    Windows { x, y, rec }
}

/// Mean log ratio of the healthy training windows (empty when the model has no healthy class).
fn healthy_reference(tr: &Windows, labels: &[String], floor: f32) -> Vec<f32> {
    let Some(h) = Condition::Healthy.index_in(labels) else {
        return Vec::new();
    };
    let rows: Vec<usize> = (0..tr.y.len()).filter(|&i| tr.y[i] == h).collect();
    if rows.is_empty() {
        return Vec::new();
    }
    let x = tr.x.select(Axis(0), &rows);
    crate::model::align::log_mean(x.view(), floor).to_vec()
}

/// Score a model on recordings (in memory): per-window argmax and novelty, whole-record vote.
pub fn score_records(
    model: &TrainedModel,
    recs: &[RecordingFeatures],
    idx: &[usize],
) -> Evaluation {
    let labels = &model.meta.labels;
    let outcomes: Vec<RecordOutcome> = idx
        .iter()
        .filter_map(|&i| {
            let r = &recs[i];
            let label = labels.iter().position(|l| l == &r.label)?;
            let out = model.predict(r.windows.view());
            Some(RecordOutcome {
                path: r.path_text.clone(),
                label,
                predicted: TrainedModel::argmax(out.probs.view()),
                unknown: out
                    .novelty
                    .iter()
                    .map(|&s| s.is_nan() || s > model.novelty.threshold)
                    .collect(),
                rpm: r.rpm,
                daemon: None,
            })
        })
        .collect();
    evaluate::score(labels, &outcomes)
}

/// Training summary stored in the model metadata and printed by `rigmon train`.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    pub config: TrainConfig,
    pub labels: Vec<String>,
    pub train_records: Vec<String>,
    pub validation_records: Vec<String>,
    /// Recordings in the manifest whose label the model does not learn (e.g. ball).
    pub skipped_records: Vec<String>,
    pub train_windows: usize,
    pub validation_windows: usize,
    pub epochs_run: usize,
    pub best_epoch: usize,
    pub validation_window_accuracy: f64,
    pub validation_record_accuracy: f64,
    pub validation_balanced_accuracy: f64,
    pub novelty_threshold: f32,
    pub validation_unknown_rate: f64,
}

/// Train a complete model on featurised recordings.
pub fn fit(
    recs: &[RecordingFeatures],
    rig: &RigConfig,
    labels: &[String],
    cfg: &TrainConfig,
    val_fraction: f64,
    on_epoch: impl FnMut(&EpochStats),
) -> Result<(TrainedModel, FitReport, Evaluation)> {
    let usable: Vec<usize> = (0..recs.len())
        .filter(|&i| labels.contains(&recs[i].label))
        .collect();
    let skipped: Vec<String> = (0..recs.len())
        .filter(|i| !usable.contains(i))
        .map(|i| recs[i].path_text.clone())
        .collect();
    for l in labels {
        if !usable.iter().any(|&i| &recs[i].label == l) {
            bail!("no training recording is labelled {l:?}; the model needs every class it predicts (classes: {})", labels.join(", "));
        }
    }
    let n_bins = rig.features.n_bins();
    if let Some(r) = recs.iter().find(|r| r.windows.ncols() != n_bins) {
        bail!(
            "{}: {} features per window, but the rig's layout has {n_bins}",
            r.path_text,
            r.windows.ncols()
        );
    }
    let lab: Vec<String> = usable.iter().map(|&i| recs[i].label.clone()).collect();
    let sp = split::stratified(&lab, val_fraction, cfg.seed);
    let train_idx: Vec<usize> = sp.train.iter().map(|&k| usable[k]).collect();
    let val_idx: Vec<usize> = sp.held_out.iter().map(|&k| usable[k]).collect();
    let tr = to_windows(recs, &train_idx, labels);
    let va = to_windows(recs, &val_idx, labels);
    let t = trainer::train(&tr, &va, labels.len(), cfg, on_epoch);

    let z_train = t.pre.apply(tr.x.view());
    let (h_train, _) = t.mlp.forward(z_train.view());
    let mut novelty = Mahalanobis::fit(h_train.view(), &tr.y, labels.len(), NOVELTY_SHRINKAGE)?;
    let calib = if va.is_empty() { &tr } else { &va };
    let (h_cal, _) = t.mlp.forward(t.pre.apply(calib.x.view()).view());
    let scores = novelty.score(h_cal.view());
    novelty.calibrate(
        scores.as_slice().unwrap_or(&[]),
        NOVELTY_QUANTILE,
        NOVELTY_MARGIN,
    );

    let used: Vec<RecordingFeatures> = usable.iter().map(|&i| recs[i].clone()).collect();
    let meta = ModelMeta {
        labels: labels.to_vec(),
        bin_width: rig.features.bin_width_order,
        max_order: rig.features.max_order,
        axis: rig.features.classifier_axis.clone(),
        rig_id: rig.machine.id.clone(),
        data_hash: data_hash(&used),
        calibration_id: rig
            .calibration
            .as_ref()
            .map_or("none".to_string(), |c| c.id.clone()),
        rigmon_version: env!("CARGO_PKG_VERSION").to_string(),
        novelty_threshold: novelty.threshold,
        sha256: String::new(),
        n_features: n_bins,
        normalization: NORMALIZATION_NAME.to_string(),
        training: String::new(),
        finetune: String::new(),
        healthy_reference: healthy_reference(&tr, labels, t.pre.floor),
        trained_mean: Vec::new(),
        alignment: None,
        lowpass_hz: Some(rig.features.lowpass_hz),
        window_s: Some(rig.features.window_s),
        bearing_orders: Some(crate::model::identity::bearing_orders(rig)),
    };
    let mut model = TrainedModel {
        pre: t.pre,
        mlp: t.mlp,
        novelty,
        meta,
        baseline: None,
    };
    let eval_idx = if val_idx.is_empty() {
        &train_idx
    } else {
        &val_idx
    };
    let ev = score_records(&model, recs, eval_idx);
    let report = FitReport {
        config: cfg.clone(),
        labels: labels.to_vec(),
        train_records: train_idx
            .iter()
            .map(|&i| recs[i].path_text.clone())
            .collect(),
        validation_records: val_idx.iter().map(|&i| recs[i].path_text.clone()).collect(),
        skipped_records: skipped,
        train_windows: tr.len(),
        validation_windows: va.len(),
        epochs_run: t.history.len(),
        best_epoch: t.best_epoch,
        validation_window_accuracy: ev.window_accuracy,
        validation_record_accuracy: ev.record_accuracy,
        validation_balanced_accuracy: ev.balanced_accuracy,
        novelty_threshold: model.novelty.threshold,
        validation_unknown_rate: ev.unknown_rate,
    };
    // Metadata keeps the validation list but only the count of training recordings (small file).
    let mut compact = serde_json::to_value(&report)?;
    compact["train_records"] = serde_json::json!(report.train_records.len());
    model.meta.training = compact.to_string();
    Ok((model, report, ev))
}
