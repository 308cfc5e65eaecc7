//! `rigmon calibrate`: fit the simulator to measured recordings and write the calibrated rig
//! file, a report folder (Markdown, JSON, PNGs) and, with `--json`, the report on stdout.

use crate::calibrate::{fit, measured, plots, report};
use crate::config::RigConfig;
use anyhow::{Context, Result};
use clap::Parser;
use std::path::PathBuf;

#[derive(Parser, Debug)]
pub struct Args {
    /// Rig file with a [simulation] section.
    #[arg(long)]
    pub rig: PathBuf,
    /// Measured recordings: a labels.csv manifest (or its folder), or recording files
    /// (label from their metadata, else healthy).
    #[arg(long, required = true, num_args = 1..)]
    pub measured: Vec<PathBuf>,
    /// Calibrated rig file to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Report folder (report.md, report.json, spectra.png, residual.png, looseness.png).
    #[arg(long)]
    pub report: PathBuf,
    /// Seconds of each recording analysed (from its start); default: the whole recording
    /// (slow effects such as a speed fluctuation of period T need 2 T or more).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Print the report as one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Search `looseness_impacts` (a loose housing's landings) whatever the recordings show;
    /// without this flag it is searched where they show the landings (a half-order comb of
    /// the envelope against the model: docs/calibration.md).
    #[arg(long)]
    pub looseness_impacts: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(a: &Args) -> Result<()> {
    let inputs: Vec<(&str, &std::path::Path)> = std::iter::once(("--rig", a.rig.as_path()))
        .chain(a.measured.iter().map(|p| ("--measured", p.as_path())))
        .collect();
    super::same_file::refuse_output_naming_input(
        &[("-o", &a.output), ("--report", &a.report)],
        &inputs,
    )?;
    Ok(())
}

/// The recordings as loaded, on stderr: how long loading took, and each one's split.
fn print_split(ops: &[measured::Measured], part: &[bool], load_s: f64) {
    eprintln!("loaded {} recordings in {load_s:.1} s", ops.len());
    for (m, p) in ops.iter().zip(part) {
        eprintln!(
            "split: {:<32} {:<11} {:7.1} rpm  {:6.2} s at {:.3} Hz (recorded at {} Hz)  {}",
            m.name,
            m.label,
            m.rpm,
            m.recording.duration_s(),
            m.recording.sample_rate,
            m.recorded_sample_rate,
            if *p { "fit" } else { "held out" }
        );
    }
}

pub fn run(a: Args) -> Result<()> {
    let rig = RigConfig::load(&a.rig)?;
    let t_load = std::time::Instant::now();
    let mut ops = measured::load(&rig, &a.measured, a.seconds.unwrap_or(f64::INFINITY))?;
    if ops.len() == 1 {
        ops = measured::split_single(&ops[0], &rig)?;
    }
    let part = measured::checkerboard(&ops);
    print_split(&ops, &part, t_load.elapsed().as_secs_f64());
    let t0 = std::time::Instant::now();
    let options = fit::Options {
        looseness_impacts: a.looseness_impacts,
        ..fit::Options::default()
    };
    let outcome = fit::calibrate_with(&rig, &ops, part, options)?;
    eprintln!(
        "calibrated in {:.1} s; time per stage (summed over threads): {}",
        t0.elapsed().as_secs_f64(),
        outcome
            .timings
            .iter()
            .map(|t| format!("{} {:.1} s ({} calls)", t.stage, t.seconds, t.calls))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let t_report = std::time::Instant::now();
    let id = report::calibration_id(&outcome, &ops);
    std::fs::create_dir_all(&a.report)
        .with_context(|| format!("cannot create report folder {}", a.report.display()))?;
    report::write_rig(&a.rig, &a.output, &outcome, &id)?;
    let j = report::json(&rig, &outcome, &ops, &id);
    std::fs::write(
        a.report.join("report.json"),
        serde_json::to_string_pretty(&j)?,
    )?;
    std::fs::write(
        a.report.join("report.md"),
        report::markdown(&rig, &outcome, &ops, &id),
    )?;
    let dump: Vec<serde_json::Value> = (0..ops.len())
        .map(|i| {
            let v = |w: &crate::calibrate::views::Views| {
                serde_json::json!({"rpm": w.rpm, "env": w.env, "lines": w.lines, "bands": w.bands, "band_lo_hz": w.band_lo_hz, "speed": w.speed,
                    "fault_peaks": w.fault_peaks, "shaft_orders": {"amplitude": w.shaft.amplitude, "floor": w.shaft.floor},
                    "mode": {"hz": w.mode.hz, "prominent": w.mode.prominent},
                    "fractional": w.fractional, "half_orders": {"orders": crate::calibrate::half_orders::ORDERS, "amplitude": w.half_orders.amplitude, "floor": w.half_orders.floor},
                    "impacts": w.impacts, "seconds": w.seconds, "segments": w.segments})
            };
            serde_json::json!({"recording": ops[i].name, "measured": v(&outcome.measured_views[i]),
                "before": v(&outcome.views_before[i]), "after": v(&outcome.views_after[i])})
        })
        .collect();
    std::fs::write(a.report.join("views.json"), serde_json::to_string(&dump)?)?;
    // plots for the recording with the largest error before calibration
    let worst = (0..ops.len())
        .max_by(|x, y| {
            let e = |i: usize| {
                crate::calibrate::error::pair(&outcome.measured_views[i], &outcome.views_before[i])
                    .total
            };
            e(*x).total_cmp(&e(*y))
        })
        .unwrap_or(0);
    let names: Vec<&str> = ops.iter().map(|m| m.name.as_str()).collect();
    let views = (&outcome.measured_views, &outcome.views_before);
    plots::all(
        &a.report,
        &names,
        worst,
        (views.0, views.1, &outcome.views_after),
    )?;
    let report_s = t_report.elapsed().as_secs_f64();
    eprintln!("report and plots written in {report_s:.1} s");
    eprintln!(
        "calibration {id}: error {:.3} -> {:.3}; effects: [{}]; unexplained: {}; wrote {} and {}",
        outcome.before.total,
        outcome.after.total,
        outcome
            .accepted
            .iter()
            .map(|t| t.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        outcome.unexplained.len(),
        a.output.display(),
        a.report.display()
    );
    if a.json {
        println!("{}", serde_json::to_string(&j)?);
    }
    Ok(())
}
