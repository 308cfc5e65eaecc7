//! `rigmon evaluate`: run a model file (through tract, as the daemon does) on labelled
//! recordings and score it whole-record; recordings the model was fine-tuned on are excluded.

use crate::config::RigConfig;
use crate::evaluate::{score, summary, RecordOutcome};
use crate::model::OnnxClassifier;
use crate::train::dataset::{manifest_path, read_manifest};
use crate::train::featurise::featurise_all;
use anyhow::Result;
use indicatif::ProgressBar;
use std::path::PathBuf;

/// Arguments of `rigmon evaluate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model file (.onnx).
    #[arg(long)]
    pub model: PathBuf,
    /// Rig file of the recordings.
    #[arg(long)]
    pub rig: PathBuf,
    /// labels.csv (`path,label`; relative paths are relative to the CSV) or a dataset folder.
    #[arg(long)]
    pub manifest: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Draw the whole-record and per-window confusion matrices to this PNG (the per-window one
    /// goes next to it as `<name>.windows.png`).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// Hashes of the recordings a model was fine-tuned on (from its metadata).
fn finetune_hashes(meta: &crate::model::ModelMeta) -> Vec<String> {
    serde_json::from_str::<serde_json::Value>(&meta.finetune)
        .ok()
        .and_then(|v| v.get("finetune_sha256").cloned())
        .and_then(|v| serde_json::from_value::<Vec<String>>(v).ok())
        .unwrap_or_default()
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let clf = OnnxClassifier::load(&args.model)?;
    clf.check_rig(&rig)?;
    let meta = clf.meta().clone();
    let entries = read_manifest(&manifest_path(&args.manifest))?;
    let recs = featurise_all(&entries, &rig, &ProgressBar::hidden())?;
    let used = finetune_hashes(&meta);
    let (mut outcomes, mut excluded, mut skipped) = (Vec::new(), Vec::new(), Vec::new());
    for r in &recs {
        if used.contains(&r.sha256) {
            excluded.push(r.path_text.clone());
            continue;
        }
        let Some(label) = meta.labels.iter().position(|l| l == &r.label) else {
            skipped.push(r.path_text.clone());
            continue;
        };
        let (mut predicted, mut unknown) = (Vec::new(), Vec::new());
        for row in r.windows.rows() {
            let p = clf.predict(&row.to_vec())?;
            predicted.push(p.class);
            unknown.push(p.unknown);
        }
        outcomes.push(RecordOutcome {
            path: r.path_text.clone(),
            label,
            predicted,
            unknown,
            rpm: r.rpm,
        });
    }
    let ev = score(&meta.labels, &outcomes);
    if let Some(png) = &args.png {
        let name = args
            .model
            .file_name()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        crate::plots::confusion::draw(
            png,
            &ev.confusion,
            &format!(
                "{name}: whole records (balanced acc. {:.1} %)",
                100.0 * ev.balanced_accuracy
            ),
        )?;
        let wpng = png.with_extension("windows.png");
        crate::plots::confusion::draw(
            &wpng,
            &ev.window_confusion,
            &format!("{name}: windows (acc. {:.1} %)", 100.0 * ev.window_accuracy),
        )?;
    }
    let split = serde_json::json!({
        "model_trained_on_data_hash": meta.data_hash,
        "model_calibration_id": meta.calibration_id,
        "excluded_finetune_records": excluded,
        "skipped_unknown_label_records": skipped,
    });
    if args.json {
        let mut v = serde_json::to_value(&ev)?;
        v["model"] = serde_json::json!({"path": args.model, "sha256": meta.sha256, "labels": meta.labels, "rig_id": meta.rig_id});
        v["split"] = split;
        println!("{v}");
        return Ok(());
    }
    println!(
        "model {} (rig {}, trained on data {}, calibration {})",
        args.model.display(),
        meta.rig_id,
        &meta.data_hash[..meta.data_hash.len().min(12)],
        meta.calibration_id
    );
    if !excluded.is_empty() {
        println!(
            "excluded (the model was fine-tuned on them): {}",
            excluded.join(", ")
        );
    }
    if !skipped.is_empty() {
        println!(
            "skipped (label not among the model's classes): {}",
            skipped.join(", ")
        );
    }
    for r in &ev.records {
        println!(
            "  {:<60} {:>11} -> {:<11} {} windows {:>4}  window acc {:>5.1} %  unknown {:>5.1} %",
            r.path,
            r.label,
            r.predicted,
            if r.correct { "ok   " } else { "WRONG" },
            r.windows,
            100.0 * r.window_accuracy,
            100.0 * r.unknown_rate
        );
    }
    print!("{}", summary(&ev));
    Ok(())
}
