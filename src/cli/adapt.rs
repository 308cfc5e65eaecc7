//! `rigmon adapt`: a rig file plus measured recordings of that machine -> calibrated rig
//! file, a classifier trained on the calibrated simulation, and a report scoring the labelled
//! recordings before and after, beside the rule baseline. See [`crate::adapt`].

use crate::adapt::{adapt, AdaptOptions};
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `rigmon adapt`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file of the machine, with a [simulation] section.
    #[arg(long)]
    pub rig: PathBuf,
    /// labels.csv (`path,label`) of measured recordings of this machine; healthy-only is the
    /// normal case. They calibrate the simulator and are scored; they never train.
    #[arg(long)]
    pub measured: PathBuf,
    /// Output folder: model.onnx, rig.toml, report.md, report.json, *.png.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Dataset plan to use instead of the one derived from the rig and the recordings.
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// Training seeds; the model best on simulated validation is kept.
    #[arg(long, default_value_t = 3)]
    pub seeds: u64,
    /// Seconds of each measured recording used by calibration.
    #[arg(long, default_value_t = 2.0)]
    pub seconds: f64,
    /// Simulated recordings per class (derived plan).
    #[arg(long, default_value_t = 100)]
    pub recordings: usize,
    /// Seconds per simulated recording (derived plan).
    #[arg(long, default_value_t = 2.0)]
    pub sim_seconds: f64,
    /// Maximum training epochs per seed.
    #[arg(long, default_value_t = 200)]
    pub epochs: usize,
    /// Zero-shot model to compare with (default: train one from the uncalibrated rig file
    /// with the same plan).
    #[arg(long)]
    pub baseline_model: Option<PathBuf>,
    /// More labelled recordings of the machine to score (never used to calibrate).
    #[arg(long)]
    pub holdout: Option<PathBuf>,
    /// Keep the simulated datasets in <output>/datasets.
    #[arg(long)]
    pub keep_datasets: bool,
    /// Worker threads for simulation (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bars.
    #[arg(long, short)]
    pub quiet: bool,
    /// Print report.json on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write model.onnx even when the adapted model misses a labelled fault (the self-check
    /// still reports it); without it such a model is written as model.rejected.onnx and
    /// adapt exits with a non-zero status.
    #[arg(long)]
    pub accept_regression: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(a: &Args) -> Result<()> {
    let inputs: Vec<(&str, &std::path::Path)> = [
        ("--rig", a.rig.as_path()),
        ("--measured", a.measured.as_path()),
    ]
    .into_iter()
    .chain(a.plan.iter().map(|p| ("--plan", p.as_path())))
    .chain(
        a.baseline_model
            .iter()
            .map(|p| ("--baseline-model", p.as_path())),
    )
    .chain(a.holdout.iter().map(|p| ("--holdout", p.as_path())))
    .collect();
    super::same_file::refuse_output_naming_input(&[("-o", &a.output)], &inputs)?;
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    let o = AdaptOptions {
        rig: a.rig,
        measured: a.measured,
        out: a.output.clone(),
        plan: a.plan,
        seeds: a.seeds,
        seconds: a.seconds,
        recordings: a.recordings,
        sim_seconds: a.sim_seconds,
        epochs: a.epochs,
        baseline_model: a.baseline_model,
        holdout: a.holdout,
        keep_datasets: a.keep_datasets,
        threads: a.threads,
        progress: !a.quiet,
        accept_regression: a.accept_regression,
    };
    let r = adapt(&o)?;
    if a.json {
        println!("{}", serde_json::to_string(&r)?);
    } else {
        print_summary(&r, &a.output);
    }
    let c = &r.self_check;
    if !c.passed() {
        let what = format!(
            "SELF-CHECK FAILED: the adapted model misses {} of the {} labelled faults it was given (report.md, section Self-check)",
            c.regressions.len(),
            c.faulty
        );
        if !c.accepted_by_flag {
            anyhow::bail!(
                "{what}; it was written as {}, not model.onnx (--accept-regression ships it anyway)",
                c.model_file
            );
        }
        eprintln!("{what}; written as model.onnx anyway (--accept-regression)");
    }
    Ok(())
}

fn print_summary(r: &crate::adapt::AdaptOutcome, output: &std::path::Path) {
    let show = |name: &str, s: &crate::adapt::SetScores| {
        println!("{name} ({}):", s.manifest);
        for (k, e) in [
            ("before", &s.before),
            ("after", &s.after),
            ("rule", &s.rule),
        ] {
            println!(
                "  {k:<7} balanced (records) {:>6.1} %   records {:>3}   missed alarms {}   false alarms {}",
                100.0 * e.balanced_accuracy,
                e.n_records,
                e.missed_alarms,
                e.false_alarms
            );
        }
    };
    println!(
        "calibration {}: error {:.3} -> {:.3}",
        r.calibration["id"].as_str().unwrap_or(""),
        r.calibration["error_before"].as_f64().unwrap_or(f64::NAN),
        r.calibration["error_after"].as_f64().unwrap_or(f64::NAN)
    );
    for s in &r.seeds {
        println!(
            "seed {}: simulated validation balanced {:.1} %{}",
            s.seed,
            100.0 * s.validation_balanced_accuracy,
            if s.seed == r.chosen_seed {
                "  (kept)"
            } else {
                ""
            }
        );
    }
    show("measured", &r.measured_scores);
    if let Some(h) = &r.holdout_scores {
        show("held out", h);
    }
    println!(
        "wrote {} ({}, rig.toml, report.md, report.json, *.png) in {:.1} s wall, {:.1} s CPU",
        output.display(),
        r.self_check.model_file,
        r.total_s,
        r.total_cpu_s
    );
}
