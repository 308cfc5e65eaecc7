//! `rigmon align`: move a simulation-trained model onto one machine with that machine's
//! healthy recordings only (the reference levels of [`crate::model::align`]); nothing is
//! trained, the network and its labels stay.

use crate::adapt::align_to_recordings;
use crate::config::RigConfig;
use crate::manifest::{manifest_path, read_manifest};
use crate::model::{export, OnnxClassifier};
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use indicatif::ProgressBar;
use std::path::PathBuf;

/// Arguments of `rigmon align`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model to align (written by `rigmon train`).
    #[arg(long)]
    pub model: PathBuf,
    /// Rig file of the machine.
    #[arg(long)]
    pub rig: PathBuf,
    /// labels.csv (`path,label`) of the machine's recordings; only rows labelled `healthy`
    /// are used.
    #[arg(long)]
    pub healthy: PathBuf,
    /// Output model file.
    #[arg(short = 'o', long)]
    pub output: PathBuf,
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
            ("--healthy", &args.healthy),
        ],
    )?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    OnnxClassifier::load(&args.model)?.check_identity(&rig, &args.rig, args.allow_foreign_model)?;
    let base = export::read(&args.model)?;
    let csv = manifest_path(&args.healthy);
    let entries: Vec<_> = read_manifest(&csv)?
        .into_iter()
        .filter(|e| Condition::is_healthy(&e.label))
        .collect();
    if entries.is_empty() {
        bail!(
            "{}: no row is labelled `healthy`; alignment needs recordings of the machine in good condition",
            csv.display()
        );
    }
    let aligned = align_to_recordings(&base, &entries, &rig, &ProgressBar::hidden())?;
    export::write(&aligned, &args.output)?;
    println!(
        "aligned {} to {} healthy recording(s): {}",
        args.model.display(),
        entries.len(),
        aligned
            .meta
            .alignment
            .as_ref()
            .map(|a| a.to_text())
            .unwrap_or_default()
    );
    println!("wrote {}", args.output.display());
    Ok(())
}
