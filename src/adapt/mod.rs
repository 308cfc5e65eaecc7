//! `rigmon adapt`: turn a rig file plus measured recordings of that machine into a diagnosis
//! for it. Measured data calibrates the simulator ([`crate::calibrate`]) and is scored; it
//! never trains the classifier. Steps: calibrate -> derive the dataset plan ([`plan`]) ->
//! simulate with the plan's ranges spread around the calibration (and the uncalibrated rig
//! for the zero-shot model) -> train `seeds` models and the zero-shot model in parallel
//! (rayon), keep the best seed on simulated validation -> score the labelled recordings
//! before (the zero-shot model) and after, with the rule baseline beside -> write the folder
//! ([`report`], with wall and CPU time per step: [`timing`]). Before it is written, the kept model is aligned to the machine's healthy
//! recordings ([`crate::model::align`]: reference levels and the healthy-baseline gate).

pub mod plan;
pub mod report;
pub mod timing;

use crate::calibrate::{fit as cal_fit, measured, plots as cal_plots, report as cal_report};
use crate::config::RigConfig;
use crate::evaluate::{score, Evaluation};
use crate::manifest::{read_manifest, ManifestEntry};
use crate::model::align::align_to_healthy;
use crate::model::classifier::TrainedModel;
use crate::model::rule::{EnvelopeRule, RuleSettings};
use crate::model::{export, OnnxClassifier};
use crate::sim::dataset::{generate, CalibratedDraws, DatasetSummary};
use crate::sim::plan::Plan;
use crate::train::dataset::RecordingFeatures;
use crate::train::featurise::featurise_all;
use crate::train::fit::{class_labels, fit, FitReport};
use crate::train::score::{analyse_all, model_outcomes, rule_labels, rule_outcomes};
use crate::train::trainer::TrainConfig;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use timing::{StepTime, Stopwatch};

/// What `rigmon adapt` is asked to do.
#[derive(Debug, Clone)]
pub struct AdaptOptions {
    pub rig: PathBuf,
    /// labels.csv of the measured recordings of this machine (`path,label`).
    pub measured: PathBuf,
    /// Output folder.
    pub out: PathBuf,
    /// A dataset plan instead of the derived one.
    pub plan: Option<PathBuf>,
    /// Training seeds (1..=seeds); the best on simulated validation is kept.
    pub seeds: u64,
    /// Seconds of each measured recording used by calibration.
    pub seconds: f64,
    /// Simulated recordings per class of the derived plan.
    pub recordings: usize,
    /// Seconds per simulated recording of the derived plan.
    pub sim_seconds: f64,
    /// Maximum training epochs.
    pub epochs: usize,
    /// The zero-shot model to compare with; else one is trained from the uncalibrated rig.
    pub baseline_model: Option<PathBuf>,
    /// Further labelled recordings of the machine, scored only (never calibrate).
    pub holdout: Option<PathBuf>,
    /// Keep the simulated datasets in `<out>/datasets`.
    pub keep_datasets: bool,
    pub threads: Option<usize>,
    pub progress: bool,
}

/// One training seed on the calibrated simulation.
#[derive(Debug, Clone, Serialize)]
pub struct SeedResult {
    pub seed: u64,
    pub validation_balanced_accuracy: f64,
    pub validation_record_accuracy: f64,
    pub validation_window_accuracy: f64,
    pub epochs_run: usize,
    pub best_epoch: usize,
}

/// Scores of one set of labelled recordings: before, after, rule.
#[derive(Debug, Clone, Serialize)]
pub struct SetScores {
    pub manifest: String,
    pub before: Evaluation,
    pub after: Evaluation,
    pub rule: Evaluation,
}

/// Everything the report holds.
#[derive(Debug, Clone, Serialize)]
pub struct AdaptOutcome {
    pub rig: String,
    pub rig_id: String,
    pub measured: String,
    pub calibration: serde_json::Value,
    pub measured_range: plan::MeasuredRange,
    pub plan_source: String,
    pub plan: Plan,
    pub dataset_recordings: usize,
    pub dataset_seconds: f64,
    pub labels: Vec<String>,
    pub seeds: Vec<SeedResult>,
    pub chosen_seed: u64,
    pub selection: String,
    pub before_model: String,
    pub model_sha256: String,
    /// The alignment to the machine's healthy recordings (none when none is labelled healthy).
    pub alignment: Option<serde_json::Value>,
    pub measured_scores: SetScores,
    pub holdout_scores: Option<SetScores>,
    /// Wall and CPU seconds per step, with the load average.
    pub timings: Vec<StepTime>,
    pub total_s: f64,
    pub total_cpu_s: f64,
}

fn step_bar(progress: bool, n: u64) -> ProgressBar {
    if !progress {
        return ProgressBar::hidden();
    }
    ProgressBar::new(n).with_style(
        ProgressStyle::with_template("adapt {bar:30} {pos}/{len} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    )
}

fn file_bar(progress: bool, n: usize, what: &str) -> ProgressBar {
    if !progress {
        return ProgressBar::hidden();
    }
    ProgressBar::new(n as u64)
        .with_style(
            ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        )
        .with_message(what.to_string())
}

/// Calibrate the rig on the measured recordings, as `rigmon calibrate` does; writes the
/// calibrated rig file and the calibration report into `dir`. Returns the calibrated rig and
/// a summary for the adapt report.
fn calibrate_step(
    rig_path: &Path,
    rig: &RigConfig,
    measured_csv: &Path,
    seconds: f64,
    dir: &Path,
) -> Result<(RigConfig, serde_json::Value)> {
    let mut ops = measured::load(rig, &[measured_csv.to_path_buf()], seconds)?;
    if ops.len() == 1 {
        ops = measured::split_single(&ops[0], rig)?;
    }
    let part = measured::checkerboard(&ops);
    let outcome = cal_fit::calibrate(rig, &ops, part)?;
    let id = cal_report::calibration_id(&outcome, &ops);
    let cal_dir = dir.join("calibration");
    std::fs::create_dir_all(&cal_dir)
        .with_context(|| format!("cannot create {}", cal_dir.display()))?;
    let rig_out = dir.join("rig.toml");
    cal_report::write_rig(rig_path, &rig_out, &outcome, &id)?;
    let j = cal_report::json(rig, &outcome, &ops, &id);
    std::fs::write(
        cal_dir.join("report.json"),
        serde_json::to_string_pretty(&j)?,
    )?;
    std::fs::write(
        cal_dir.join("report.md"),
        cal_report::markdown(rig, &outcome, &ops, &id),
    )?;
    if !ops.is_empty() {
        cal_plots::spectra(
            &dir.join("calibration_spectra.png"),
            &ops[0].name,
            &outcome.measured_views[0],
            &outcome.views_before[0],
            &outcome.views_after[0],
        )?;
    }
    let summary = serde_json::json!({
        "id": id,
        "error_before": outcome.before.total,
        "error_after": outcome.after.total,
        "effects": outcome.accepted.iter().map(|t| serde_json::json!({"name": t.name, "params": t.params})).collect::<Vec<_>>(),
        "unexplained": outcome.unexplained.len(),
        "split": ops.iter().zip(&outcome.fit_part).map(|(m, p)| serde_json::json!({"recording": m.name, "label": m.label, "rpm": m.rpm, "part": if *p {"fit"} else {"held out"}})).collect::<Vec<_>>(),
        "report": "calibration/report.md",
    });
    let calibrated = RigConfig::load(&rig_out)?;
    Ok((calibrated, summary))
}

/// Simulate `plan` on `rig` into `dir` and featurise the result.
fn simulate_and_featurise(
    rig: &RigConfig,
    plan: &Plan,
    dir: &Path,
    o: &AdaptOptions,
) -> Result<(DatasetSummary, Vec<RecordingFeatures>)> {
    let s = generate(
        rig,
        plan,
        dir,
        "mcap",
        o.threads,
        o.progress,
        CalibratedDraws::Spread,
    )?;
    let entries = read_manifest(&dir.join("labels.csv"))?;
    let pb = file_bar(o.progress, entries.len(), "features");
    let recs = featurise_all(&entries, rig, &pb)?;
    pb.finish_and_clear();
    Ok((s, recs))
}

/// Train one seed (epochs counted on the shared bar `pb`).
fn train_seed(
    recs: &[RecordingFeatures],
    rig: &RigConfig,
    labels: &[String],
    seed: u64,
    epochs: usize,
    pb: &ProgressBar,
) -> Result<(TrainedModel, FitReport, Evaluation)> {
    let cfg = TrainConfig {
        seed,
        epochs,
        ..TrainConfig::default()
    };
    fit(recs, rig, labels, &cfg, 0.1, |_| pb.inc(1))
}

/// Align models to the machine's healthy measured recordings (reference levels and the
/// healthy-baseline gate; the recordings are featurised once); models are kept as trained
/// when none is labelled healthy.
fn align_step(
    models: Vec<TrainedModel>,
    entries: &[ManifestEntry],
    rig: &RigConfig,
    progress: bool,
) -> Result<(Vec<TrainedModel>, Option<serde_json::Value>)> {
    let healthy: Vec<ManifestEntry> = entries
        .iter()
        .filter(|e| e.label == "healthy")
        .cloned()
        .collect();
    if healthy.is_empty() {
        tracing::warn!(
            "no measured recording is labelled healthy: the model is not aligned to the machine"
        );
        return Ok((models, None));
    }
    let pb = file_bar(progress, healthy.len(), "align");
    let recs = featurise_all(&healthy, rig, &pb)?;
    pb.finish_and_clear();
    let views: Vec<_> = recs.iter().map(|r| r.windows.view()).collect();
    let windows = ndarray::concatenate(ndarray::Axis(0), &views)?;
    let names: Vec<String> = recs.iter().map(|r| r.path_text.clone()).collect();
    let aligned = models
        .iter()
        .map(|m| align_to_healthy(m, windows.view(), &names))
        .collect::<Result<Vec<_>>>()?;
    let info = serde_json::from_str(&aligned[0].meta.alignment)?;
    Ok((aligned, Some(info)))
}

/// `model` aligned to the feature windows of `healthy` recordings of one machine (all of
/// them, whatever their label; `rigmon align` and `adapt` pass the healthy rows).
pub fn align_to_recordings(
    model: &TrainedModel,
    healthy: &[ManifestEntry],
    rig: &RigConfig,
    progress: &ProgressBar,
) -> Result<TrainedModel> {
    let recs = featurise_all(healthy, rig, progress)?;
    let views: Vec<_> = recs.iter().map(|r| r.windows.view()).collect();
    let windows = ndarray::concatenate(ndarray::Axis(0), &views)?;
    let names: Vec<String> = recs.iter().map(|r| r.path_text.clone()).collect();
    align_to_healthy(model, windows.view(), &names)
}

/// Score a model file and the rule on labelled recordings of the machine.
fn score_set(
    manifest: &Path,
    rig: &RigConfig,
    before: &OnnxClassifier,
    after: &OnnxClassifier,
    progress: bool,
) -> Result<SetScores> {
    let entries: Vec<ManifestEntry> = read_manifest(manifest)?;
    let pb = file_bar(progress, entries.len(), "score");
    let recs = analyse_all(&entries, rig, &pb)?;
    pb.finish_and_clear();
    let b = model_outcomes(before, &recs, rig)?;
    let a = model_outcomes(after, &recs, rig)?;
    let kept = a.scored(&recs);
    let labels = rule_labels(&a.labels, &kept);
    let rule = EnvelopeRule::for_rig(rig, RuleSettings::default());
    let r = rule_outcomes(&rule, &kept, &labels)?;
    Ok(SetScores {
        manifest: manifest.display().to_string(),
        before: score(&b.labels, &b.outcomes),
        after: score(&a.labels, &a.outcomes),
        rule: score(&labels, &r),
    })
}

/// Run the whole adaptation; writes `o.out` and returns what the report holds.
pub fn adapt(o: &AdaptOptions) -> Result<AdaptOutcome> {
    let mut clock = Stopwatch::start();
    if o.seeds == 0 {
        bail!("--seeds 0: give at least 1");
    }
    let rig = RigConfig::load(&o.rig)?;
    crate::sim::rig_simulation(&rig)?;
    std::fs::create_dir_all(&o.out)
        .with_context(|| format!("cannot create output folder {}", o.out.display()))?;
    let entries = read_manifest(&o.measured)?;
    if entries.is_empty() {
        bail!(
            "{}: no recordings listed; give at least one measured recording of the machine",
            o.measured.display()
        );
    }
    let steps = step_bar(o.progress, 6);

    // 1. calibrate
    steps.set_message("calibrating the simulator on the measured recordings");
    let (cal_rig, calibration) = calibrate_step(&o.rig, &rig, &o.measured, o.seconds, &o.out)?;
    clock.lap("calibrate");
    steps.inc(1);

    // 2. plan
    steps.set_message("deriving the dataset plan");
    let mut items = Vec::new();
    for e in &entries {
        let rec = crate::importers::load(&e.path, &rig, &Default::default())
            .with_context(|| format!("loading {}", e.path.display()))?;
        let rpm = measured::mean_rpm(&rec, &rig)?;
        items.push((rpm, rec.sample_rate, e.label.clone()));
    }
    let range = plan::MeasuredRange::of(&items)?;
    let (the_plan, plan_source) = match &o.plan {
        Some(p) => (Plan::load(p)?, p.display().to_string()),
        None => (
            plan::derive(&cal_rig, &range, o.recordings, o.sim_seconds)?,
            "derived".to_string(),
        ),
    };
    std::fs::write(o.out.join("plan.toml"), toml::to_string(&the_plan)?)?;
    clock.lap("plan");
    steps.inc(1);

    // 3. simulate the calibrated rig, and the uncalibrated one for the zero-shot model
    steps.set_message("simulating the calibrated rig");
    let work = o.out.join("datasets");
    let (summary, recs) = simulate_and_featurise(&cal_rig, &the_plan, &work.join("calibrated"), o)?;
    clock.lap("simulate (calibrated rig)");
    let recs0 = match &o.baseline_model {
        Some(_) => None,
        None => {
            steps.set_message("simulating the uncalibrated rig (zero-shot model)");
            let (_, r) = simulate_and_featurise(&rig, &the_plan, &work.join("uncalibrated"), o)?;
            clock.lap("simulate (uncalibrated rig, zero-shot)");
            Some(r)
        }
    };
    steps.inc(1);

    // 4. train the seeds and the zero-shot model in parallel; keep the best seed on
    // simulated validation
    steps.set_message(format!(
        "training {} seeds{}",
        o.seeds,
        if recs0.is_some() {
            " and the zero-shot model"
        } else {
            ""
        }
    ));
    let labels = class_labels(range.labels.iter().any(|l| l == "ball"));
    let n_jobs = o.seeds as usize + usize::from(recs0.is_some());
    let pb = file_bar(o.progress, n_jobs * o.epochs, "train");
    // job 0 is the zero-shot model (seed 1 on the uncalibrated rig), jobs 1.. the seeds
    let jobs: Vec<u64> = (u64::from(recs0.is_none())..=o.seeds).collect();
    let trained: Vec<(u64, Result<(TrainedModel, FitReport, Evaluation)>)> = jobs
        .par_iter()
        .map(|&job| {
            let r = match (job, &recs0) {
                (0, Some(r0)) => train_seed(r0, &rig, &labels, 1, o.epochs, &pb),
                _ => train_seed(&recs, &cal_rig, &labels, job, o.epochs, &pb),
            };
            (job, r)
        })
        .collect();
    pb.finish_and_clear();
    let mut seeds = Vec::new();
    let mut models = Vec::new();
    let mut best: Option<(f64, u64)> = None;
    let mut zero_shot = None;
    for (job, r) in trained {
        let (model, rep, ev) = r?;
        if job == 0 {
            zero_shot = Some(model);
            continue;
        }
        seeds.push(SeedResult {
            seed: job,
            validation_balanced_accuracy: ev.balanced_accuracy,
            validation_record_accuracy: ev.record_accuracy,
            validation_window_accuracy: ev.window_accuracy,
            epochs_run: rep.epochs_run,
            best_epoch: rep.best_epoch,
        });
        // whole-record balanced accuracy, then window accuracy; the first seed wins ties
        let key = ev.balanced_accuracy + 1e-3 * ev.window_accuracy;
        if best.is_none_or(|(k, _)| key > k) {
            best = Some((key, job));
        }
        models.push(model);
    }
    let (_, chosen_seed) = best.expect("at least one seed");
    clock.lap(&format!(
        "train ({n_jobs} models in parallel, {} threads)",
        rayon::current_num_threads()
    ));
    steps.inc(1);

    // 5. align the kept model to the machine's healthy recordings; write both models
    steps.set_message("aligning the model to the machine's healthy recordings");
    let (models, alignment) = align_step(models, &entries, &rig, o.progress)?;
    // every seed's model, aligned the same way, so real-data scores of all seeds can be had
    let seed_dir = o.out.join("seeds");
    std::fs::create_dir_all(&seed_dir)
        .with_context(|| format!("cannot create {}", seed_dir.display()))?;
    for (s, m) in seeds.iter().zip(&models) {
        export::write(m, &seed_dir.join(format!("seed{}.onnx", s.seed)))?;
    }
    let model_path = o.out.join("model.onnx");
    let kept = seeds
        .iter()
        .position(|s| s.seed == chosen_seed)
        .expect("the kept seed was trained");
    export::write(&models[kept], &model_path)?;
    let after = OnnxClassifier::load(&model_path)?;
    after.check_rig(&rig)?;
    let (before, before_name) = match (&o.baseline_model, zero_shot) {
        (Some(p), _) => (OnnxClassifier::load(p)?, p.display().to_string()),
        (None, Some(m0)) => {
            let p = o.out.join("before.onnx");
            export::write(&m0, &p)?;
            (
                OnnxClassifier::load(&p)?,
                "before.onnx (same plan on the uncalibrated rig file, seed 1, not aligned)"
                    .to_string(),
            )
        }
        (None, None) => bail!("internal: no zero-shot model was trained"),
    };
    before.check_rig(&rig)?;
    clock.lap("align and write");
    steps.inc(1);

    // 6. score
    steps.set_message("scoring the labelled recordings");
    let measured_scores = score_set(&o.measured, &rig, &before, &after, o.progress)?;
    let holdout_scores = match &o.holdout {
        Some(h) => Some(score_set(h, &rig, &before, &after, o.progress)?),
        None => None,
    };
    clock.lap("score");
    steps.inc(1);
    steps.finish_and_clear();
    if !o.keep_datasets {
        let _ = std::fs::remove_dir_all(&work);
    }
    let total_s = clock.steps.iter().map(|t| t.wall_s).sum();
    let total_cpu_s = clock.steps.iter().map(|t| t.cpu_s).sum();
    let outcome = AdaptOutcome {
        rig: o.rig.display().to_string(),
        rig_id: rig.machine.id.clone(),
        measured: o.measured.display().to_string(),
        calibration,
        measured_range: range,
        plan_source,
        plan: the_plan,
        dataset_recordings: summary.recordings,
        dataset_seconds: summary.seconds,
        labels,
        selection: format!(
            "best of {} training seeds on simulated validation (whole-record balanced accuracy, then window accuracy); not an ensemble",
            o.seeds
        ),
        seeds,
        chosen_seed,
        before_model: before_name,
        model_sha256: after.meta().sha256.clone(),
        alignment,
        measured_scores,
        holdout_scores,
        timings: clock.steps,
        total_s,
        total_cpu_s,
    };
    report::write(&o.out, &outcome)?;
    Ok(outcome)
}
