//! The `rigmon adapt` report folder: `report.json` (everything in [`AdaptOutcome`]),
//! `report.md` (the self-check first, then calibration error before/after, the plan's speeds
//! and the cases the labelled faults shaped, simulated validation per seed, every labelled
//! recording's diagnosis before/after/rule, wall and CPU time per step) and confusion-matrix
//! PNGs (`confusion_{before,after,rule}.png`, with a `holdout_` prefix for the held-out set).

use super::{AdaptOutcome, SetScores};
use crate::evaluate::Evaluation;
use anyhow::{Context, Result};
use std::fmt::Write;
use std::path::Path;

/// Write report.json, report.md and the PNGs into `dir`.
pub fn write(dir: &Path, o: &AdaptOutcome) -> Result<()> {
    let json = dir.join("report.json");
    std::fs::write(&json, serde_json::to_string_pretty(o)?)
        .with_context(|| format!("cannot write {}", json.display()))?;
    std::fs::write(dir.join("report.md"), markdown(o))?;
    draw_set(dir, "", &o.measured_scores)?;
    if let Some(h) = &o.holdout_scores {
        draw_set(dir, "holdout_", h)?;
    }
    Ok(())
}

fn draw_set(dir: &Path, prefix: &str, s: &SetScores) -> Result<()> {
    for (name, ev) in [
        ("before", &s.before),
        ("after", &s.after),
        ("rule", &s.rule),
    ] {
        let (title, note) = ev.record_caption(&format!("{prefix}{name}"));
        let png = dir.join(format!("{prefix}confusion_{name}.png"));
        crate::plots::confusion::draw(&png, &ev.confusion, &title, &note)?;
    }
    Ok(())
}

fn pct(v: f64) -> String {
    if v.is_nan() {
        "n/a".into()
    } else {
        format!("{:.1} %", 100.0 * v)
    }
}

fn line(name: &str, e: &Evaluation) -> String {
    format!(
        "| {name} | {}/{} | {} | {} | {} | {} | {} |\n",
        e.confusion
            .matrix
            .iter()
            .enumerate()
            .map(|(i, r)| r[i])
            .sum::<usize>(),
        e.n_records,
        pct(e.balanced_accuracy),
        pct(e.window_accuracy),
        e.missed_alarms,
        e.false_alarms,
        pct(e.unknown_rate)
    )
}

fn set_md(title: &str, s: &SetScores) -> String {
    let mut m = format!("## {title}\n\n`{}`\n\n", s.manifest);
    m += "| classifier | records right | balanced (records) | windows | missed alarms | false alarms | unknown (windows) |\n|---|---|---|---|---|---|---|\n";
    m += &line("before (zero-shot)", &s.before);
    m += &line("after (adapted)", &s.after);
    m += &line("rule baseline", &s.rule);
    m += "\n| recording | label | before | after | rule |\n|---|---|---|---|---|\n";
    for (i, a) in s.after.records.iter().enumerate() {
        let find = |e: &Evaluation| {
            e.records
                .get(i)
                .filter(|r| r.path == a.path)
                .or_else(|| e.records.iter().find(|r| r.path == a.path))
                .map(|r| {
                    let share = 100.0 * r.votes.iter().copied().max().unwrap_or(0) as f64
                        / r.windows.max(1) as f64;
                    // windows the physics decided against the network, where any did
                    let physics = [
                        (r.evidence_windows, "by the fault-family evidence"),
                        (r.impulsive_windows, "impulsive"),
                    ]
                    .into_iter()
                    .filter_map(|(n, what)| Some(format!("; {} {what}", n.filter(|&n| n > 0)?)))
                    .collect::<String>();
                    format!("{} ({share:.0} % of windows{physics})", r.predicted)
                })
                .unwrap_or_else(|| "-".into())
        };
        let _ = writeln!(
            m,
            "| {} | {} | {} | {} | {} |",
            a.path,
            a.label,
            find(&s.before),
            find(&s.after),
            find(&s.rule)
        );
    }
    m + "\n"
}

/// The self-check section: loud when the adapted model misses a labelled fault.
/// The self-check, then what the checks let through with a warning.
fn self_check_md(c: &super::check::SelfCheck, warnings: &[String]) -> String {
    let mut out = self_check_only(c);
    for w in warnings {
        let _ = writeln!(out, "Warning: {w}\n");
    }
    out
}

fn self_check_only(c: &super::check::SelfCheck) -> String {
    if c.passed() {
        return format!(
            "## Self-check: passed\n\nThe adapted model misses none of the {} labelled faults among the {} labelled recordings it was given (measured and held out); written as `{}`.\n\n",
            c.faulty, c.checked, c.model_file
        );
    }
    let mut m = format!(
        "## SELF-CHECK FAILED: the adapted model misses {} of the {} labelled faults it was given\n\n",
        c.regressions.len(),
        c.faulty
    );
    m += if c.accepted_by_flag {
        "**Written as `model.onnx` anyway, because `--accept-regression` was given.**\n\n"
    } else {
        "**The model was NOT written as `model.onnx`: it is `model.rejected.onnx`, and adapt exited with a non-zero status. `--accept-regression` ships it anyway.**\n\n"
    };
    for r in &c.regressions {
        let _ = writeln!(m, "- **{}**", r.line());
    }
    m + "\n"
}

/// The plan's speeds and what the labelled faults added.
fn plan_md(o: &AdaptOutcome) -> String {
    let mut m = format!(
        "Speeds from {}. Calibration analysed {:.2} s of each measured recording.\n\n",
        o.plan_speeds, o.calibration_seconds
    );
    if o.shaped.is_empty() {
        return m;
    }
    m += "Cases shaped by the labelled faults (the zero-shot model's plan has none: `plan-zero-shot.toml`):\n\n\
| recording | label | rpm | family band / median (measured) | fitted defect width | twin's band / median | case (recordings) |\n|---|---|---|---|---|---|---|\n";
    for s in &o.shaped {
        let _ = writeln!(
            m,
            "| {} | {} | {:.0} | {:.2} | {} | {} | {} ({}) |",
            s.recording,
            s.label,
            s.rpm,
            s.measured_ratio,
            s.fitted_width_mm.map_or_else(
                || "not fitted (no band stands 3x above the median)".to_string(),
                |w| format!(
                    "{w:.3} mm{}",
                    if s.at_grid_edge { " (grid edge)" } else { "" }
                )
            ),
            s.simulated_ratio
                .map_or_else(|| "-".to_string(), |r| format!("{r:.2}")),
            s.case,
            s.recordings
        );
    }
    m + "\n"
}

/// The Markdown report.
pub fn markdown(o: &AdaptOutcome) -> String {
    let mut m = format!(
        "# rigmon adapt: {}\n\nRig file `{}`, measured recordings `{}` ({} to {:.0} rpm, sample rates {:?} Hz, labels {:?}). \
Measured data calibrated the simulator, shaped the plan and is scored below; it did not train the classifier.\n\n",
        o.rig_id,
        o.rig,
        o.measured,
        format_args!("{:.0}", o.measured_range.rpm_min),
        o.measured_range.rpm_max,
        o.measured_range.sample_rates_hz,
        o.measured_range.labels
    );
    m += &self_check_md(&o.self_check, &o.warnings);
    let c = &o.calibration;
    let _ = write!(
        m,
        "## Calibration\n\nid `{}`: error {:.3} before -> {:.3} after; effects accepted: {}; unexplained residuals: {}. \
Calibrated rig file: `rig.toml`; full report: `calibration/report.md`.\n\n",
        c["id"].as_str().unwrap_or(""),
        c["error_before"].as_f64().unwrap_or(f64::NAN),
        c["error_after"].as_f64().unwrap_or(f64::NAN),
        c["effects"]
            .as_array()
            .map(|a| {
                if a.is_empty() {
                    "none".to_string()
                } else {
                    a.iter()
                        .map(|e| format!("{} {}", e["name"].as_str().unwrap_or(""), e["params"]))
                        .collect::<Vec<_>>()
                        .join("; ")
                }
            })
            .unwrap_or_default(),
        c["unexplained"]
    );
    let _ = write!(
        m,
        "## Simulation and training\n\nPlan: {} (`plan.toml`), {} recordings, {:.0} s of signal, classes {}. {}.\n\n",
        o.plan_source,
        o.dataset_recordings,
        o.dataset_seconds,
        o.labels.join(", "),
        o.selection
    );
    m += &plan_md(o);
    m += "| seed | simulated validation, balanced (records) | records | windows | epochs (best) |\n|---|---|---|---|---|\n";
    for s in &o.seeds {
        let _ = writeln!(
            m,
            "| {}{} | {} | {} | {} | {} ({}) |",
            s.seed,
            if s.seed == o.chosen_seed {
                " (kept)"
            } else {
                ""
            },
            pct(s.validation_balanced_accuracy),
            pct(s.validation_record_accuracy),
            pct(s.validation_window_accuracy),
            s.epochs_run,
            s.best_epoch
        );
    }
    let v: Vec<f64> = o
        .seeds
        .iter()
        .map(|s| s.validation_balanced_accuracy)
        .collect();
    let _ = write!(
        m,
        "\nMean {}, worst {} over {} seeds. Model: `model.onnx` (sha256 {}); every seed's model, aligned the same way: `seeds/seed<N>.onnx`. Zero-shot model compared with: {}.\n\n",
        pct(v.iter().sum::<f64>() / v.len().max(1) as f64),
        pct(v.iter().copied().fold(f64::INFINITY, f64::min)),
        v.len(),
        o.model_sha256,
        o.before_model
    );
    match &o.alignment {
        Some(a) => {
            let _ = write!(
                m,
                "Aligned to the machine's healthy recordings ({} windows of {}): reference levels moved by {:.2} (RMS, natural log) and a healthy-baseline gate at distance {:.2}; a window farther from the healthy windows is never called healthy.\n\n",
                a["windows"],
                a["records"].as_array().map_or(0, |r| r.len()),
                a["shift_rms"].as_f64().unwrap_or(f64::NAN),
                a["baseline_threshold"].as_f64().unwrap_or(f64::NAN)
            );
        }
        None => m += "Not aligned: no measured recording is labelled healthy.\n\n",
    }
    m += &set_md(
        "Measured recordings (these also calibrated the simulator)",
        &o.measured_scores,
    );
    if let Some(h) = &o.holdout_scores {
        m += &set_md("Held-out recordings (never used to calibrate)", h);
    }
    m += "Missed alarm: a faulty record called healthy. False alarm: a healthy record called faulty. \
The rule has no ball class; a ball record it calls a race fault is an alarm, not a miss.\n\n## Time\n\n";
    m += "| step | wall (s) | CPU (s) | load average (1 min) |\n|---|---|---|---|\n";
    let load = |l: Option<f64>| l.map_or_else(|| "-".to_string(), |l| format!("{l:.1}"));
    for t in &o.timings {
        let _ = writeln!(
            m,
            "| {} | {:.1} | {:.1} | {} |",
            t.step,
            t.wall_s,
            t.cpu_s,
            load(t.load_1min)
        );
    }
    let _ = writeln!(
        m,
        "| total | {:.1} | {:.1} | |\n\nCPU time is this process's (user + system, all threads); the wall time depends on what else ran on the machine (load average).",
        o.total_s, o.total_cpu_s
    );
    m
}
