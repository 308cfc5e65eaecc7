//! `rigmon train`: featurise a labelled (simulated) dataset, train the classifier with a split
//! by recording, check the exported ONNX with tract, and write it.

use crate::config::RigConfig;
use crate::manifest::{manifest_path, read_manifest};
use crate::model::{export, OnnxClassifier};
use crate::train::featurise::featurise_all;
use crate::train::fit::{class_labels, fit};
use crate::train::trainer::TrainConfig;
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// Arguments of `rigmon train`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file (feature layout and metadata).
    #[arg(long)]
    pub rig: PathBuf,
    /// Dataset folder (with labels.csv) or a labels.csv manifest (`path,label`).
    #[arg(long)]
    pub data: PathBuf,
    /// Output model file (.onnx).
    #[arg(short = 'o', long)]
    pub output: PathBuf,
    /// Seed for the split, initialisation, shuffling, dropout and augmentation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Maximum number of epochs (early stopping usually ends sooner).
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// Also learn the ball-fault class.
    #[arg(long)]
    pub ball: bool,
    /// Fraction of each class's recordings held out for validation.
    #[arg(long, default_value_t = 0.1)]
    pub val_fraction: f64,
    /// Strength of the spectral augmentation during training (0 = off).
    #[arg(long, default_value_t = TrainConfig::default().augment)]
    pub augment: f32,
    /// Dropout rate after each hidden layer.
    #[arg(long, default_value_t = TrainConfig::default().dropout)]
    pub dropout: f32,
    /// Print the training report as JSON on stdout instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(
        &[("-o", &args.output)],
        &[("--rig", &args.rig), ("--data", &args.data)],
    )?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let csv = manifest_path(&args.data);
    let entries = read_manifest(&csv)?;
    let style = ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed}")
        .expect("valid template")
        .progress_chars("=> ");
    let pb = ProgressBar::new(entries.len() as u64)
        .with_style(style.clone())
        .with_message("features");
    let recs = featurise_all(&entries, &rig, &pb)?;
    pb.finish();
    let cfg = TrainConfig {
        seed: args.seed,
        epochs: args.epochs,
        augment: args.augment,
        dropout: args.dropout,
        ..TrainConfig::default()
    };
    let labels = class_labels(args.ball);
    let pb = ProgressBar::new(cfg.epochs as u64).with_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} epochs {elapsed} {prefix}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_message("training");
    let (model, report, ev) = fit(&recs, &rig, &labels, &cfg, args.val_fraction, |st| {
        pb.set_prefix(format!(
            "train loss {:.4}  val loss {:.4}  val acc {:.3}",
            st.train_loss, st.val_loss, st.val_window_accuracy
        ));
        pb.inc(1);
    })?;
    pb.finish();
    export::write(&model, &args.output)?;
    // Independent check: the file as tract runs it gives what the in-memory model gives.
    let clf = OnnxClassifier::load(&args.output)?;
    let probe = recs
        .iter()
        .find(|r| labels.contains(&r.label))
        .context("no recording to probe")?;
    let reference = model.predict(probe.windows.view());
    let mut max_diff = 0.0f32;
    for (i, row) in probe.windows.rows().into_iter().enumerate().take(32) {
        let p = clf.predict(row.as_slice().unwrap_or(&row.to_vec()))?;
        for (a, b) in p.probs.iter().zip(reference.probs.row(i)) {
            max_diff = max_diff.max((a - b).abs());
        }
        max_diff = max_diff
            .max((p.novelty - reference.novelty[i]).abs() / reference.novelty[i].abs().max(1.0));
    }
    if args.json {
        println!(
            "{}",
            serde_json::json!({"model": args.output, "sha256": clf.meta().sha256, "report": report, "validation": ev, "tract_max_diff": max_diff})
        );
        return Ok(());
    }
    println!(
        "model: {} ({} bytes, sha256 {})",
        args.output.display(),
        std::fs::metadata(&args.output)?.len(),
        clf.meta().sha256
    );
    println!(
        "classes: {}   data hash: {}",
        labels.join(", "),
        model.meta.data_hash
    );
    println!("split by recording (seed {}): {} train recordings ({} windows), {} validation recordings ({} windows)", cfg.seed, report.train_records.len(), report.train_windows, report.validation_records.len(), report.validation_windows);
    for r in &report.validation_records {
        println!("  validation: {r}");
    }
    if !report.skipped_records.is_empty() {
        println!(
            "skipped {} recordings with labels the model does not learn",
            report.skipped_records.len()
        );
    }
    println!(
        "epochs run: {} (best {})   novelty threshold: {:.3}",
        report.epochs_run, report.best_epoch, report.novelty_threshold
    );
    println!(
        "validation (held-out recordings):\n{}",
        crate::evaluate::summary(&ev)
    );
    println!("tract vs in-memory max difference: {max_diff:.2e}");
    Ok(())
}
