//! Fine-tuning (the thesis' transfer step): retrain only the output layer on a fraction of
//! labelled measured RECORDINGS (whole recordings, seeded choice) and report whole-record
//! figures before and after on the recordings held out. The chosen recordings' hashes go into
//! the model metadata so `rigmon evaluate` can refuse to score them.

use super::dataset::{data_hash, RecordingFeatures};
use super::fit::{score_records, to_windows};
use super::split;
use super::trainer::{train_output_layer, TrainConfig};
use crate::evaluate::Evaluation;
use crate::model::classifier::TrainedModel;
use anyhow::{bail, Result};
use serde::Serialize;

/// What fine-tuning did, stored (without the evaluations) in the model metadata.
#[derive(Debug, Clone, Serialize)]
pub struct FinetuneReport {
    pub fraction: f64,
    pub seed: u64,
    pub epochs: usize,
    /// Recordings used to retrain the output layer.
    pub finetune_records: Vec<String>,
    /// Their file hashes (evaluate excludes recordings with these hashes).
    pub finetune_sha256: Vec<String>,
    pub finetune_data_hash: String,
    /// Recordings held out for the before/after figures.
    pub held_out_records: Vec<String>,
    /// Recordings whose label the model does not predict.
    pub skipped_records: Vec<String>,
}

/// Default fine-tuning schedule: output layer only, small learning rate, fixed epochs.
pub fn default_config(seed: u64) -> TrainConfig {
    TrainConfig {
        seed,
        epochs: 60,
        batch: 16,
        lr: 1e-3,
        weight_decay: 0.0,
        ..TrainConfig::default()
    }
}

/// Fine-tune `model` on about `fraction` of `recs`; returns the new model, the report and the
/// held-out evaluations before and after.
pub fn finetune(
    model: &TrainedModel,
    recs: &[RecordingFeatures],
    fraction: f64,
    cfg: &TrainConfig,
) -> Result<(TrainedModel, FinetuneReport, Evaluation, Evaluation)> {
    if !(fraction > 0.0 && fraction < 1.0) {
        bail!(
            "--fraction {fraction}: must be between 0 and 1 (e.g. 0.1 for 10 % of the recordings)"
        );
    }
    let labels = &model.meta.labels;
    let usable: Vec<usize> = (0..recs.len())
        .filter(|&i| labels.contains(&recs[i].label))
        .collect();
    let skipped: Vec<String> = (0..recs.len())
        .filter(|i| !usable.contains(i))
        .map(|i| recs[i].path_text.clone())
        .collect();
    if usable.len() < 2 {
        bail!("fine-tuning needs at least two recordings with the model's labels ({}); the manifest has {}", labels.join(", "), usable.len());
    }
    let sp = split::sample(usable.len(), fraction, cfg.seed);
    let ft_idx: Vec<usize> = sp.train.iter().map(|&k| usable[k]).collect();
    let ho_idx: Vec<usize> = sp.held_out.iter().map(|&k| usable[k]).collect();
    let before = score_records(model, recs, &ho_idx);
    let data = to_windows(recs, &ft_idx, labels);
    let mut tuned = model.clone();
    tuned.mlp = train_output_layer(&model.pre, &model.mlp, &data, cfg);
    let after = score_records(&tuned, recs, &ho_idx);
    let used: Vec<RecordingFeatures> = ft_idx.iter().map(|&i| recs[i].clone()).collect();
    let report = FinetuneReport {
        fraction,
        seed: cfg.seed,
        epochs: cfg.epochs,
        finetune_records: used.iter().map(|r| r.path_text.clone()).collect(),
        finetune_sha256: used.iter().map(|r| r.sha256.clone()).collect(),
        finetune_data_hash: data_hash(&used),
        held_out_records: ho_idx.iter().map(|&i| recs[i].path_text.clone()).collect(),
        skipped_records: skipped,
    };
    tuned.meta.finetune = serde_json::to_string(&report)?;
    tuned.meta.sha256.clear();
    Ok((tuned, report, before, after))
}
