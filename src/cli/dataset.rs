//! `rigmon dataset`: expand a plan into scenarios, simulate them on all cores and write
//! `<dir>/*.mcap` plus `<dir>/labels.csv` (`path,label`, paths relative to the CSV).

use crate::config::RigConfig;
use crate::sim::{
    dataset::{generate, CalibratedDraws},
    plan::Plan,
};
use anyhow::{bail, Result};
use std::path::PathBuf;

/// Arguments of `rigmon dataset`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file with a [simulation] section.
    #[arg(long)]
    pub rig: PathBuf,
    /// Dataset plan (e.g. config/plans/thesis.toml).
    #[arg(long)]
    pub plan: PathBuf,
    /// Output directory (created; existing recordings of the same name are overwritten).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write WAV instead of MCAP.
    #[arg(long)]
    pub wav: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// With a calibrated rig file: `fixed` keeps the fitted values in every recording (the
    /// plan's draws of them are dropped); `spread` centres the plan's ranges on them,
    /// keeping the plan's spread.
    #[arg(long, value_enum, default_value = "fixed")]
    pub calibrated: Calibrated,
}

/// `--calibrated`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Calibrated {
    Fixed,
    Spread,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(
        &[("-o", &args.output)],
        &[("--rig", &args.rig), ("--plan", &args.plan)],
    )?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let plan = Plan::load(&args.plan)?;
    if args.threads == Some(0) {
        bail!("--threads 0: give at least 1 (or leave it out for all cores)");
    }
    let ext = if args.wav { "wav" } else { "mcap" };
    let calibrated = match args.calibrated {
        Calibrated::Fixed => CalibratedDraws::Fixed,
        Calibrated::Spread => CalibratedDraws::Spread,
    };
    let s = generate(
        &rig,
        &plan,
        &args.output,
        ext,
        args.threads,
        !args.quiet,
        calibrated,
    )?;
    eprintln!(
        "plan {:?}: {} recordings, {:.0} s of signal in {:.1} s wall -> {}",
        plan.name,
        s.recordings,
        s.seconds,
        s.wall_s,
        args.output.join("labels.csv").display()
    );
    Ok(())
}
