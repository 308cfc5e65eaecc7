//! Dataset generation: a plan's scenarios simulated in parallel (rayon, all cores) with a
//! progress bar, written as `<dir>/<stem>.mcap` (or `.wav`) plus `<dir>/labels.csv`
//! (`path,label`, paths relative to the CSV; the manifest `train`, `evaluate` and `finetune`
//! read).

use super::plan::{calibrated_keys, Plan, PlannedRun};
use crate::config::{CalibrationStamp, RigConfig};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::path::Path;

/// Summary of a generated dataset.
#[derive(Debug, Clone)]
pub struct DatasetSummary {
    pub recordings: usize,
    pub seconds: f64,
    pub wall_s: f64,
}

/// What a plan may do to the parameters a calibrated rig file has fitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum CalibratedDraws {
    /// Every recording keeps the fitted values: the plan's draws of them are dropped.
    #[default]
    Fixed,
    /// The plan's ranges of them are moved onto the fitted values, keeping their spread
    /// (width, or ratio for scale-like parameters); effects no plan key draws stay fixed.
    Spread,
}

/// Expand the plan for a rig: a plan must not undo a calibration, so the calibrated effects
/// keep their fitted values ([`CalibratedDraws::Fixed`]) or the plan's ranges are centred on
/// them ([`CalibratedDraws::Spread`]). Logs what it changed.
fn apply_calibration(
    stamp: Option<&CalibrationStamp>,
    plan: &Plan,
    calibrated: CalibratedDraws,
) -> Result<Vec<PlannedRun>> {
    let Some(stamp) = stamp else {
        return plan.expand();
    };
    let mut plan = plan.clone();
    let mut fixed: Vec<&str> = Vec::new();
    for effect in &stamp.effects {
        let name = effect.get("name").and_then(|n| n.as_str()).unwrap_or("");
        let keys = calibrated_keys(effect);
        if calibrated == CalibratedDraws::Fixed || keys.is_empty() {
            fixed.push(name);
            continue;
        }
        for (key, value, how) in keys {
            if let Some([lo, hi]) = plan.recentre(key, value, how) {
                tracing::info!(
                    "calibration {}: the plan's {key} drawn from [{lo:.4}, {hi:.4}] around the fitted {value:.4}",
                    stamp.id
                );
            }
        }
    }
    let mut runs = plan.expand()?;
    let mut dropped = std::collections::BTreeSet::new();
    for r in &mut runs {
        dropped.extend(r.keep_calibrated(&fixed));
    }
    if !dropped.is_empty() {
        tracing::info!(
            "calibration {}: the plan's {:?} ignored (calibrated effects keep their values)",
            stamp.id,
            dropped
        );
    }
    Ok(runs)
}

/// The runs of `plan` on `rig`, its calibration kept as `calibrated` says (checks that the
/// rig has a simulation section).
pub fn expand_for(
    rig: &RigConfig,
    plan: &Plan,
    calibrated: CalibratedDraws,
) -> Result<Vec<PlannedRun>> {
    super::rig_simulation(rig)?;
    apply_calibration(rig.calibration.as_ref(), plan, calibrated)
}

/// The progress bar of a dataset's recordings (hidden without `progress`).
pub fn recordings_bar(progress: bool, n: u64) -> ProgressBar {
    let bar = if progress {
        ProgressBar::new(n)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:40} {pos}/{len} recordings, {elapsed} elapsed, eta {eta} {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Write `<dir>/labels.csv` from (file name, label) rows, sorted.
pub fn write_labels(dir: &Path, rows: &mut [(String, String)]) -> Result<()> {
    rows.sort();
    let mut csv = String::from("path,label\n");
    for (p, l) in rows.iter() {
        csv.push_str(&format!("{p},{l}\n"));
    }
    let labels = dir.join("labels.csv");
    std::fs::write(&labels, csv).with_context(|| format!("cannot write {}", labels.display()))
}

/// Simulate one planned run on its own and write it as `<dir>/<stem>.<ext>`; returns its
/// labels.csv row (file name, label).
pub fn simulate_run(
    rig: &RigConfig,
    run: &PlannedRun,
    dir: &Path,
    ext: &str,
) -> Result<(String, String)> {
    let rec =
        super::simulate(rig, &run.scenario).with_context(|| format!("simulating {}", run.stem))?;
    let name = format!("{}.{ext}", run.stem);
    super::output::write(&dir.join(&name), &rec, rig)?;
    Ok((name, run.scenario.label().to_string()))
}

/// Generate a dataset (library entry point, also used by the benchmark).
pub fn generate(
    rig: &RigConfig,
    plan: &Plan,
    dir: &Path,
    ext: &str,
    threads: Option<usize>,
    progress: bool,
    calibrated: CalibratedDraws,
) -> Result<DatasetSummary> {
    let runs = expand_for(rig, plan, calibrated)?;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create output directory {}", dir.display()))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()?;
    let bar = recordings_bar(progress, runs.len() as u64);
    let t0 = std::time::Instant::now();
    let results: Vec<Result<(String, String)>> = pool.install(|| {
        runs.par_iter()
            .map(|run| {
                let row = simulate_run(rig, run, dir, ext)?;
                bar.inc(1);
                Ok(row)
            })
            .collect()
    });
    bar.finish_and_clear();
    let mut rows = Vec::with_capacity(results.len());
    for r in results {
        rows.push(r?);
    }
    write_labels(dir, &mut rows)?;
    let (n, seconds) = plan.totals();
    Ok(DatasetSummary {
        recordings: n,
        seconds,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}
