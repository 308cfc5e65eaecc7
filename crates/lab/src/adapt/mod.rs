//! `rigmon adapt`: turn a rig file plus measured recordings of that machine into a diagnosis
//! for it. Measured data calibrates the simulator ([`crate::calibrate`]), shapes the plan
//! (labelled faults, [`shape`]) and is scored; it never trains the classifier. Steps:
//! check every input and the plan before any long work ([`preflight`]: files, spans, speeds,
//! a plan from the machine's speeds [`plan`], one simulated recording featurised) ->
//! calibrate, with the first runs of the zero-shot dataset (the plan on the uncalibrated rig)
//! simulated alongside on one thread -> shape the plan with the labelled faults -> simulate
//! with the plan's ranges spread around the calibration, and the rest of the zero-shot
//! dataset with it, each run's mechanics once where calibration left them alone -> train `seeds` models and the zero-shot
//! model in parallel (rayon), keep the best seed on simulated validation -> align the kept
//! model to the machine's healthy recordings ([`crate::model::align`]) -> score every
//! labelled recording with the zero-shot model, the adapted model and the rule, and check
//! that the adapted model misses no labelled fault ([`check`]) -> write the folder
//! ([`report`], with wall and CPU time per step: [`timing`]).

pub mod check;
pub mod plan;
pub(crate) mod preflight;
pub mod report;
pub(crate) mod shape;
pub(crate) mod timing;

use crate::calibrate::{fit as cal_fit, measured, plots as cal_plots, report as cal_report};
use crate::config::RigConfig;
use crate::evaluate::{score, Evaluation};
use crate::manifest::{read_manifest, ManifestEntry};
use crate::model::align::align_to_healthy;
use crate::model::classifier::TrainedModel;
use crate::model::rule::{EnvelopeRule, RuleSettings};
use crate::model::{export, OnnxClassifier};
use crate::sim::dataset::{generate, CalibratedDraws, DatasetSummary};
use crate::sim::dataset_pair::{
    generate_pair, simulate_ahead, Ahead, DatasetJob, AHEAD_MECHANICS_BYTES,
};
use crate::sim::plan::Plan;
use crate::train::dataset::RecordingFeatures;
use crate::train::featurise::featurise_all;
use crate::train::fit::{class_labels, fit, FitReport};
use crate::train::score::{model_outcomes, rule_labels, rule_outcomes};
use crate::train::trainer::TrainConfig;
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use preflight::LabelledSet;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
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
    /// Write `model.onnx` even when the self-check finds a missed labelled fault.
    pub accept_regression: bool,
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
    /// Seconds of each measured recording calibration analysed.
    pub calibration_seconds: f64,
    pub plan_source: String,
    /// Where the plan's speeds come from.
    pub plan_speeds: String,
    /// The plan the adapted model was trained on (the zero-shot plan plus the shaped cases).
    pub plan: Plan,
    /// What each labelled fault recording added to the plan.
    pub shaped: Vec<shape::ShapedFault>,
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
    /// Missed labelled faults, and where the model was written.
    pub self_check: check::SelfCheck,
    /// Wall and CPU seconds per step, with the load average.
    pub timings: Vec<StepTime>,
    /// What the checks let through with a warning (a healthy recording without a speed).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
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

/// Calibrate the rig on the measured rows whose speed was read, as `rigmon calibrate` does; writes the
/// calibrated rig file and the calibration report into `dir`. Returns the calibrated rig and
/// a summary for the adapt report.
fn calibrate_step(
    rig_path: &Path,
    rig: &RigConfig,
    measured: &[crate::manifest::ManifestEntry],
    seconds: f64,
    dir: &Path,
) -> Result<(RigConfig, serde_json::Value)> {
    let mut ops = measured::load_entries(rig, measured, seconds)?;
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
    Ok((s, featurise_dataset(rig, dir, o)?))
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
/// healthy-baseline gate; their feature windows from the checks); models are kept as
/// trained when none is labelled healthy.
/// Healthy recordings without a speed (`speed_free`: name, windows' kurtosis) add their
/// kurtosis to the speed-free part of the baseline, not to the spectral reference.
/// The speed-free health indicators' baseline comes from every measured row labelled
/// healthy, its speed read or not.
fn align_step(
    models: Vec<TrainedModel>,
    pre: &preflight::Checked,
    rig: &RigConfig,
) -> Result<(Vec<TrainedModel>, Option<serde_json::Value>)> {
    let (healthy, speed_free) = (&pre.healthy, &pre.speed_free);
    let healthy_rows: Vec<ManifestEntry> = pre
        .measured
        .entries
        .iter()
        .filter(|e| Condition::is_healthy(&e.label))
        .cloned()
        .collect();
    if healthy.is_empty() {
        tracing::warn!(
            "no measured recording is labelled healthy: the model is not aligned to the machine"
        );
        return Ok((models, None));
    }
    let views: Vec<_> = healthy.iter().map(|r| r.windows.view()).collect();
    let windows = ndarray::concatenate(ndarray::Axis(0), &views)?;
    let mut names: Vec<String> = healthy.iter().map(|r| r.path_text.clone()).collect();
    let mut kurtosis = healthy_kurtosis(healthy);
    for (name, k) in speed_free {
        names.push(format!("{name} (kurtosis only: no speed)"));
        kurtosis.extend_from_slice(k);
    }
    let baseline = healthy_indicator_baseline(&healthy_rows, rig)?;
    let aligned = models
        .iter()
        .map(|m| {
            let mut a = align_to_healthy(m, windows.view(), Some(&kurtosis), &names)?;
            store_healthy_indicators(&mut a, baseline)?;
            Ok(a)
        })
        .collect::<Result<Vec<_>>>()?;
    let info = serde_json::to_value(&aligned[0].meta.alignment)?;
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
    let kurtosis = healthy_kurtosis(&recs);
    let mut aligned = align_to_healthy(model, windows.view(), Some(&kurtosis), &names)?;
    let baseline = healthy_indicator_baseline(healthy, rig)?;
    store_healthy_indicators(&mut aligned, baseline)?;
    Ok(aligned)
}

/// Store the machine's healthy indicator baseline in `model`'s alignment
/// (`healthy_indicators`); None (too few sound windows to smooth once) stores nothing.
fn store_healthy_indicators(
    model: &mut TrainedModel,
    baseline: Option<crate::model::indicators::IndicatorBaseline>,
) -> Result<()> {
    let Some(b) = baseline else {
        return Ok(());
    };
    let Some(alignment) = model.meta.alignment.as_mut() else {
        anyhow::bail!(
            "the health indicators' baseline belongs to an aligned model; align it first"
        );
    };
    alignment.healthy_indicators = Some(b);
    Ok(())
}

/// The machine's healthy indicator baseline fitted on the windows of its `healthy`
/// recordings (each within its manifest span, in manifest and time order); None when they
/// hold too few sound windows to smooth once (the model then carries none).
fn healthy_indicator_baseline(
    healthy: &[ManifestEntry],
    rig: &RigConfig,
) -> Result<Option<crate::model::indicators::IndicatorBaseline>> {
    let mut windows = Vec::new();
    for e in healthy {
        let series = crate::model::indicator_series::indicator_series(
            &e.path,
            rig,
            &e.import_options(),
            |a, b| e.keeps_window(a, b),
        )
        .with_context(|| format!("health indicators of {}", e.path.display()))?;
        windows.extend(series.iter().filter_map(|w| w.indicators));
    }
    Ok(crate::model::departure::fit_baseline(
        &windows,
        crate::model::departure::MEDIAN_OF,
    ))
}

/// The healthy recordings' excess kurtosis per window, in the row order of their
/// concatenated feature windows.
fn healthy_kurtosis(recs: &[RecordingFeatures]) -> Vec<f32> {
    recs.iter()
        .flat_map(|r| r.kurtosis.iter().copied())
        .collect()
}

/// Score the zero-shot model, the adapted model and the rule on a labelled set (featurised
/// by the checks), through the code `rigmon evaluate` uses.
fn score_set(
    set: &LabelledSet,
    rig: &RigConfig,
    before: &OnnxClassifier,
    after: &OnnxClassifier,
) -> Result<SetScores> {
    let b = model_outcomes(before, &set.scored, rig)?;
    let a = model_outcomes(after, &set.scored, rig)?;
    let kept = a.scored(&set.scored);
    let labels = rule_labels(&a.labels, &kept);
    let rule = EnvelopeRule::for_rig(rig, RuleSettings::default());
    let r = rule_outcomes(&rule, &kept, &labels)?;
    Ok(SetScores {
        manifest: set.manifest.display().to_string(),
        before: score(&b.labels, &b.outcomes),
        after: score(&a.labels, &a.outcomes),
        rule: score(&labels, &r),
    })
}

/// One trained model with its training report and simulated validation.
type SeedRun = (TrainedModel, FitReport, Evaluation);

/// The trained models: every seed's (in seed order), the kept seed and the zero-shot model.
struct Trained {
    seeds: Vec<SeedResult>,
    models: Vec<TrainedModel>,
    chosen_seed: u64,
    zero_shot: Option<TrainedModel>,
}

/// Train the seeds on the calibrated dataset and, when `recs0` is given, the zero-shot
/// model (seed 1 on the uncalibrated rig's dataset), in parallel; keep the seed best on
/// simulated validation (whole-record balanced accuracy, then window accuracy; the first
/// seed wins ties).
fn train_step(
    recs: &[RecordingFeatures],
    recs0: Option<&[RecordingFeatures]>,
    (rig, cal_rig): (&RigConfig, &RigConfig),
    labels: &[String],
    o: &AdaptOptions,
) -> Result<Trained> {
    let n_jobs = o.seeds as usize + usize::from(recs0.is_some());
    let pb = file_bar(o.progress, n_jobs * o.epochs, "train");
    // job 0 is the zero-shot model, jobs 1.. the seeds
    let jobs: Vec<u64> = (u64::from(recs0.is_none())..=o.seeds).collect();
    let trained: Vec<(u64, Result<SeedRun>)> = jobs
        .par_iter()
        .map(|&job| {
            let r = match (job, recs0) {
                (0, Some(r0)) => train_seed(r0, rig, labels, 1, o.epochs, &pb),
                _ => train_seed(recs, cal_rig, labels, job, o.epochs, &pb),
            };
            (job, r)
        })
        .collect();
    pb.finish_and_clear();
    let mut out = Trained {
        seeds: Vec::new(),
        models: Vec::new(),
        chosen_seed: 1,
        zero_shot: None,
    };
    let mut best: Option<f64> = None;
    for (job, r) in trained {
        let (model, rep, ev) = r?;
        if job == 0 {
            out.zero_shot = Some(model);
            continue;
        }
        out.seeds.push(SeedResult {
            seed: job,
            validation_balanced_accuracy: ev.balanced_accuracy,
            validation_record_accuracy: ev.record_accuracy,
            validation_window_accuracy: ev.window_accuracy,
            epochs_run: rep.epochs_run,
            best_epoch: rep.best_epoch,
        });
        let key = ev.balanced_accuracy + 1e-3 * ev.window_accuracy;
        if best.is_none_or(|k| key > k) {
            best = Some(key);
            out.chosen_seed = job;
        }
        out.models.push(model);
    }
    Ok(out)
}

/// Write every seed's model (`seeds/seed<N>.onnx`), the kept one as `model.onnx` and the
/// zero-shot one as `before.onnx`; returns the adapted and the zero-shot classifier.
fn write_models(
    t: Trained,
    rig: &RigConfig,
    o: &AdaptOptions,
) -> Result<(OnnxClassifier, OnnxClassifier, String)> {
    let seed_dir = o.out.join("seeds");
    std::fs::create_dir_all(&seed_dir)
        .with_context(|| format!("cannot create {}", seed_dir.display()))?;
    for (s, m) in t.seeds.iter().zip(&t.models) {
        export::write(m, &seed_dir.join(format!("seed{}.onnx", s.seed)))?;
    }
    let model_path = o.out.join("model.onnx");
    let kept = t
        .seeds
        .iter()
        .position(|s| s.seed == t.chosen_seed)
        .expect("the kept seed was trained");
    export::write(&t.models[kept], &model_path)?;
    let after = OnnxClassifier::load(&model_path)?;
    after.check_rig(rig)?;
    let (before, before_name) = match (&o.baseline_model, t.zero_shot) {
        (Some(p), _) => (OnnxClassifier::load(p)?, p.display().to_string()),
        (None, Some(m0)) => {
            let p = o.out.join("before.onnx");
            export::write(&m0, &p)?;
            (
                OnnxClassifier::load(&p)?,
                "before.onnx (the plan without the shaped cases, on the uncalibrated rig file, seed 1, not aligned)"
                    .to_string(),
            )
        }
        (None, None) => bail!("internal: no zero-shot model was trained"),
    };
    before.check_rig(rig)?;
    Ok((after, before, before_name))
}

/// Score the labelled sets and run the self-check ([`check`]); a failed check moves
/// `model.onnx` to [`check::REJECTED_MODEL`] unless `--accept-regression`.
fn score_and_check(
    pre: &preflight::Checked,
    before: &OnnxClassifier,
    after: &OnnxClassifier,
    o: &AdaptOptions,
) -> Result<(SetScores, Option<SetScores>, check::SelfCheck)> {
    let measured_scores = score_set(&pre.measured, &pre.rig, before, after)?;
    let holdout_scores = match &pre.holdout {
        Some(h) => Some(score_set(h, &pre.rig, before, after)?),
        None => None,
    };
    let (mut regressions, mut checked, mut faulty) =
        check::regressions("measured", &measured_scores);
    if let Some(h) = &holdout_scores {
        let (r, c, f) = check::regressions("held out", h);
        regressions.extend(r);
        checked += c;
        faulty += f;
    }
    let mut model_file = "model.onnx".to_string();
    if !regressions.is_empty() && !o.accept_regression {
        let (from, to) = (o.out.join("model.onnx"), o.out.join(check::REJECTED_MODEL));
        std::fs::rename(&from, &to)
            .with_context(|| format!("moving {} to {}", from.display(), to.display()))?;
        model_file = check::REJECTED_MODEL.to_string();
    }
    for r in &regressions {
        eprintln!("SELF-CHECK FAILED: {}", r.line());
    }
    Ok((
        measured_scores,
        holdout_scores,
        check::SelfCheck {
            regressions,
            checked,
            faulty,
            accepted_by_flag: o.accept_regression,
            model_file,
        },
    ))
}

/// Featurise the dataset `generate` or `generate_pair` wrote into `dir`.
fn featurise_dataset(
    rig: &RigConfig,
    dir: &Path,
    o: &AdaptOptions,
) -> Result<Vec<RecordingFeatures>> {
    let entries = read_manifest(&dir.join("labels.csv"))?;
    let pb = file_bar(o.progress, entries.len(), "features");
    let recs = featurise_all(&entries, rig, &pb)?;
    pb.finish_and_clear();
    Ok(recs)
}

/// The calibrated dataset and, without a baseline model, the zero-shot one (the plan
/// before shaping on the uncalibrated rig), simulated together so that the runs whose
/// mechanics calibration did not change run them once ([`generate_pair`]; the zero-shot
/// runs in `ahead` were simulated while the calibration ran). Returns the
/// calibrated dataset's summary and features, the zero-shot features and how many runs
/// shared their mechanics.
fn simulate_datasets(
    (zero_job, cal_rig, plan): (DatasetJob, &RigConfig, &Plan),
    ahead: Ahead,
    work: &Path,
    o: &AdaptOptions,
) -> Result<SimulatedDatasets> {
    let cal_dir = work.join("calibrated");
    if o.baseline_model.is_some() {
        let (summary, recs) = simulate_and_featurise(cal_rig, plan, &cal_dir, o)?;
        return Ok(SimulatedDatasets {
            summary,
            recs,
            recs0: None,
            shared_runs: 0,
        });
    }
    let jobs = [
        zero_job,
        DatasetJob {
            rig: cal_rig,
            plan,
            dir: &cal_dir,
        },
    ];
    let pair = generate_pair(
        jobs,
        ahead,
        "mcap",
        o.threads,
        o.progress,
        CalibratedDraws::Spread,
    )?;
    Ok(SimulatedDatasets {
        summary: pair.second,
        recs: featurise_dataset(cal_rig, &cal_dir, o)?,
        recs0: Some(featurise_dataset(zero_job.rig, zero_job.dir, o)?),
        shared_runs: pair.shared_runs,
    })
}

/// What [`simulate_datasets`] gives.
struct SimulatedDatasets {
    summary: DatasetSummary,
    recs: Vec<RecordingFeatures>,
    recs0: Option<Vec<RecordingFeatures>>,
    shared_runs: usize,
}

/// Calibrate, with the zero-shot dataset's first runs simulated alongside on one thread
/// until the calibration ends ([`simulate_ahead`]; none with a baseline model).
fn calibrate_with_zero_shot_ahead(
    pre: &preflight::Checked,
    zero_job: DatasetJob,
    o: &AdaptOptions,
) -> Result<(RigConfig, serde_json::Value, Ahead)> {
    let stop = AtomicBool::new(false);
    let (cal, ahead) = std::thread::scope(|s| {
        let ahead = o.baseline_model.is_none().then(|| {
            s.spawn(|| {
                simulate_ahead(
                    zero_job,
                    "mcap",
                    CalibratedDraws::Spread,
                    (&stop, AHEAD_MECHANICS_BYTES),
                )
            })
        });
        let cal = calibrate_step(
            &o.rig,
            &pre.rig,
            &pre.calibrated,
            pre.calibration_seconds,
            &o.out,
        );
        stop.store(true, Ordering::Relaxed);
        let ahead = ahead.map(|h| h.join().expect("the zero-shot simulation panicked"));
        (cal, ahead)
    });
    let (cal_rig, calibration) = cal?;
    Ok((cal_rig, calibration, ahead.transpose()?.unwrap_or_default()))
}

/// Shape a derived plan with the labelled faults (a given `--plan` stays as it is); writes
/// `plan.toml` (and `plan-zero-shot.toml` when shaped).
fn shape_step(
    pre: &preflight::Checked,
    cal_rig: &RigConfig,
    o: &AdaptOptions,
) -> Result<(Plan, Vec<shape::ShapedFault>)> {
    let (the_plan, shaped) = if o.plan.is_none() {
        let faults: Vec<(String, String, f64, &crate::recording::Recording)> = pre
            .recordings
            .iter()
            .map(|(n, l, r, rec)| (n.clone(), l.clone(), *r, rec))
            .collect();
        shape::shape(&pre.plan, cal_rig, &faults)?
    } else {
        (pre.plan.clone(), Vec::new())
    };
    std::fs::write(o.out.join("plan.toml"), toml::to_string(&the_plan)?)?;
    if !shaped.is_empty() {
        std::fs::write(
            o.out.join("plan-zero-shot.toml"),
            toml::to_string(&pre.plan)?,
        )?;
    }
    Ok((the_plan, shaped))
}

/// The calibrate step's line in the report's times.
fn calibrate_lap(ahead: &Ahead) -> String {
    format!(
        "calibrate (with {} zero-shot runs simulated alongside, {} keeping their mechanics)",
        ahead.len(),
        ahead.mechanics_kept()
    )
}

/// Run the whole adaptation; writes `o.out` and returns what the report holds.
pub fn adapt(o: &AdaptOptions) -> Result<AdaptOutcome> {
    let mut clock = Stopwatch::start();
    let steps = step_bar(o.progress, 7);
    steps.set_message("checking the inputs and the plan");
    let pre = preflight::check(o)?;
    std::fs::create_dir_all(&o.out)
        .with_context(|| format!("cannot create output folder {}", o.out.display()))?;
    let rig = &pre.rig;
    clock.lap("check inputs and plan (featurise the labelled recordings, simulate one)");
    steps.inc(1);

    steps.set_message("calibrating; simulating the zero-shot dataset ahead alongside");
    let work = o.out.join("datasets");
    let zero_dir = work.join("uncalibrated");
    let zero_job = DatasetJob {
        rig,
        plan: &pre.plan,
        dir: &zero_dir,
    };
    let (cal_rig, calibration, ahead) = calibrate_with_zero_shot_ahead(&pre, zero_job, o)?;
    clock.lap(&calibrate_lap(&ahead));
    steps.inc(1);

    steps.set_message("shaping the plan with the labelled faults");
    let (the_plan, shaped) = shape_step(&pre, &cal_rig, o)?;
    clock.lap("shape the plan with the labelled faults");
    steps.inc(1);

    steps.set_message("simulating the calibrated rig (and the zero-shot dataset)");
    let sims = simulate_datasets((zero_job, &cal_rig, &the_plan), ahead, &work, o)?;
    let (summary, recs, recs0) = (sims.summary, sims.recs, sims.recs0);
    clock.lap(&if recs0.is_some() {
        format!(
            "simulate the calibrated and the zero-shot dataset ({} of {} runs share their mechanics), featurise both",
            sims.shared_runs, summary.recordings
        )
    } else {
        "simulate (calibrated rig), featurise".to_string()
    });
    steps.inc(1);

    steps.set_message(format!(
        "training {} seeds and the zero-shot model",
        o.seeds
    ));
    let labels = class_labels(pre.range.labels.iter().any(|l| l == "ball"));
    let trained = train_step(&recs, recs0.as_deref(), (rig, &cal_rig), &labels, o)?;
    let n_models = o.seeds as usize + usize::from(recs0.is_some());
    clock.lap(&format!(
        "train ({n_models} models in parallel, {} threads)",
        rayon::current_num_threads()
    ));
    steps.inc(1);

    steps.set_message("aligning the model to the machine's healthy recordings");
    let (seeds, chosen_seed) = (trained.seeds.clone(), trained.chosen_seed);
    let (models, alignment) = align_step(trained.models, &pre, rig)?;
    let trained = Trained { models, ..trained };
    let (after, before, before_name) = write_models(trained, rig, o)?;
    clock.lap("align and write");
    steps.inc(1);

    steps.set_message("scoring the labelled recordings and checking the adapted model");
    let (measured_scores, holdout_scores, self_check) = score_and_check(&pre, &before, &after, o)?;
    clock.lap("score and self-check");
    steps.inc(1);
    steps.finish_and_clear();
    if !o.keep_datasets {
        let _ = std::fs::remove_dir_all(&work);
    }
    let outcome = AdaptOutcome {
        rig: o.rig.display().to_string(),
        rig_id: rig.machine.id.clone(),
        measured: o.measured.display().to_string(),
        calibration,
        measured_range: pre.range.clone(),
        calibration_seconds: pre.calibration_seconds,
        plan_source: pre.plan_source.clone(),
        plan_speeds: pre.plan_speeds.clone(),
        plan: the_plan,
        shaped,
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
        self_check,
        total_s: clock.steps.iter().map(|t| t.wall_s).sum(),
        total_cpu_s: clock.steps.iter().map(|t| t.cpu_s).sum(),
        timings: clock.steps,
        warnings: pre.warnings.clone(),
    };
    report::write(&o.out, &outcome)?;
    Ok(outcome)
}
