//! `rigmon finetune`: retrain a model's output layer on a fraction of labelled measured
//! recordings and report whole-record figures before and after on the rest.

use crate::config::RigConfig;
use crate::manifest::{manifest_path, read_manifest};
use crate::model::{export, OnnxClassifier};
use crate::train::featurise::featurise_all;
use crate::train::finetune::{default_config, finetune};
use anyhow::Result;
use indicatif::ProgressBar;
use std::path::PathBuf;

/// Arguments of `rigmon finetune`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model to start from (written by `rigmon train`).
    #[arg(long)]
    pub model: PathBuf,
    /// Rig file of the measured recordings.
    #[arg(long)]
    pub rig: PathBuf,
    /// labels.csv (`path,label`) of measured recordings.
    #[arg(long)]
    pub manifest: PathBuf,
    /// Fraction of the recordings (whole recordings) used for fine-tuning.
    #[arg(long, default_value_t = 0.1)]
    pub fraction: f64,
    /// Seed for choosing the recordings and for training.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Epochs over the fine-tuning windows.
    #[arg(long, default_value_t = default_config(1).epochs)]
    pub epochs: usize,
    /// Output model file.
    #[arg(short = 'o', long)]
    pub output: PathBuf,
    /// Print one JSON object (report, before, after) instead of text.
    #[arg(long)]
    pub json: bool,
    /// Use a model trained for another rig on purpose (its rig id, axis, bearing orders or
    /// recipe differ from the rig file's); refused otherwise.
    #[arg(long)]
    pub allow_foreign_model: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(
        &[("-o", &args.output)],
        &[
            ("--model", &args.model),
            ("--rig", &args.rig),
            ("--manifest", &args.manifest),
        ],
    )?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let base = export::read(&args.model)?;
    OnnxClassifier::load(&args.model)?.check_identity(&rig, &args.rig, args.allow_foreign_model)?;
    let entries = read_manifest(&manifest_path(&args.manifest))?;
    let recs = featurise_all(&entries, &rig, &ProgressBar::hidden())?;
    let cfg = crate::train::trainer::TrainConfig {
        epochs: args.epochs,
        ..default_config(args.seed)
    };
    let (tuned, report, before, after) = finetune(&base, &recs, args.fraction, &cfg)?;
    export::write(&tuned, &args.output)?;
    if args.json {
        println!(
            "{}",
            serde_json::json!({"model": args.output, "report": report, "before": before, "after": after})
        );
        return Ok(());
    }
    println!(
        "fine-tuned the output layer on {} of {} recordings (fraction {}, seed {}):",
        report.finetune_records.len(),
        report.finetune_records.len() + report.held_out_records.len(),
        args.fraction,
        args.seed
    );
    for r in &report.finetune_records {
        println!("  fine-tune: {r}");
    }
    println!("held out: {}", report.held_out_records.join(", "));
    println!(
        "\nBEFORE (held-out recordings):\n{}",
        crate::evaluate::summary(&before)
    );
    println!(
        "AFTER (held-out recordings):\n{}",
        crate::evaluate::summary(&after)
    );
    println!("wrote {}", args.output.display());
    Ok(())
}
