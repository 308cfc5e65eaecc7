//! `rigmon evaluate`: run a model file (through tract, as the daemon does) on labelled
//! recordings cut into the daemon's windows, every window through the daemon's own verdict
//! and health state machine, and score it whole-record; with `--baseline rule` the rule
//! baseline on the same windows in the same run (or the rule alone without `--model`).
//! Recordings the model was fine-tuned on are excluded; every other record is scored, a
//! class the model lacks as its own row.

use crate::config::RigConfig;
use crate::evaluate::{score, summary, Evaluation};
use crate::health::HealthPolicy;
use crate::manifest::{manifest_path, read_manifest};
use crate::model::rule::{EnvelopeRule, RuleSettings};
use crate::model::OnnxClassifier;
use crate::train::score::{
    analyze_all, model_outcomes_with, rule_labels, rule_outcomes, ModelOutcomes, ScoredRecording,
};
use anyhow::{bail, Context, Result};
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};

/// Arguments of `rigmon evaluate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model file (.onnx). Leave it out to score `--baseline rule` alone.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Rig file of the recordings.
    #[arg(long)]
    pub rig: PathBuf,
    /// labels.csv (`path,label`; relative paths are relative to the CSV) or a dataset folder.
    #[arg(long)]
    pub manifest: PathBuf,
    /// Also score a baseline on the same records: `rule` = the envelope-order rule (a window
    /// is faulty when the 0.5-order band at BPFO, BPFI or twice either stands 3x above the
    /// median band of its envelope order spectrum; majority of windows per record; no
    /// training).
    #[arg(long, value_enum)]
    pub baseline: Option<Baseline>,
    /// The `[health]` policy the daemon's verdict and state machine use for the model's
    /// records, as a TOML file with its keys (vote_n, vote_k, evidence_z, ...); default: the
    /// daemon's default policy.
    #[arg(long)]
    pub health: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Use a model trained for another rig on purpose (its rig id, axis, bearing orders or
    /// recipe differ from the rig file's); refused otherwise.
    #[arg(long)]
    pub allow_foreign_model: bool,
    /// Draw the whole-record and per-window confusion matrices to this PNG (the per-window one
    /// goes next to it as `<name>.windows.png`, the rule's as `<name>.rule.png`).
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// `--baseline`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum Baseline {
    Rule,
}

/// Both confusion matrices of `ev` to `png` and `<png>.windows.png`.
fn draw(png: &Path, ev: &Evaluation, name: &str) -> Result<()> {
    let (title, note) = ev.record_caption(name);
    crate::plots::confusion::draw(png, &ev.confusion, &title, &note)?;
    let (title, note) = ev.window_caption(name);
    let windows = png.with_extension("windows.png");
    crate::plots::confusion::draw(&windows, &ev.window_confusion, &title, &note)
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    if let Some(png) = &args.png {
        let mut inputs: Vec<(&str, &std::path::Path)> =
            vec![("--rig", &args.rig), ("--manifest", &args.manifest)];
        inputs.extend(args.model.iter().map(|p| ("--model", p.as_path())));
        inputs.extend(args.health.iter().map(|p| ("--health", p.as_path())));
        super::same_file::refuse_output_naming_input(&[("--png", png)], &inputs)?;
    }
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    if args.model.is_none() && args.baseline.is_none() {
        bail!("nothing to score: give --model <file.onnx>, --baseline rule, or both");
    }
    let rig = RigConfig::load(&args.rig)?;
    let entries = read_manifest(&manifest_path(&args.manifest))?;
    let clf = match &args.model {
        Some(path) => {
            let clf = OnnxClassifier::load(path)?;
            clf.check_identity(&rig, &args.rig, args.allow_foreign_model)?;
            Some(clf)
        }
        None => None,
    };
    let policy = match &args.health {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("--health {}: cannot read", p.display()))?;
            let policy: HealthPolicy =
                toml::from_str(&text).with_context(|| format!("--health {}", p.display()))?;
            policy
                .validate()
                .with_context(|| format!("--health {}", p.display()))?;
            policy
        }
        None => HealthPolicy::default(),
    };
    let recs = analyze_all(&entries, &rig, &ProgressBar::hidden())?;
    let mut scored = None;
    if let (Some(path), Some(clf)) = (&args.model, clf) {
        let mo = model_outcomes_with(&clf, &recs, &rig, &policy)?;
        let ev = score(&mo.labels, &mo.outcomes);
        scored = Some((path.clone(), clf, mo, ev));
    }
    let settings = RuleSettings::default();
    let rule_ev = match args.baseline {
        None => None,
        Some(Baseline::Rule) => {
            // the same records (and windows) the model is scored on, with its classes first
            let (first, kept): (Vec<String>, Vec<&ScoredRecording>) = match &scored {
                Some((_, _, mo, _)) => (mo.labels.clone(), mo.scored(&recs)),
                None => (Vec::new(), recs.iter().collect()),
            };
            let labels = rule_labels(&first, &kept);
            let rule = EnvelopeRule::for_rig(&rig, settings);
            let outcomes = rule_outcomes(&rule, &kept, &labels)?;
            Some(score(&labels, &outcomes))
        }
    };
    if let Some(png) = &args.png {
        match (&scored, &rule_ev) {
            (Some((path, ..)), r) => {
                let name = path
                    .file_name()
                    .map(|s| s.to_string_lossy().to_string())
                    .unwrap_or_default();
                draw(png, &scored.as_ref().expect("model").3, &name)?;
                if let Some(r) = r {
                    draw(&png.with_extension("rule.png"), r, "rule baseline")?;
                }
            }
            (None, Some(r)) => draw(png, r, "rule baseline")?,
            (None, None) => {}
        }
    }
    let rule_json = |ev: &Evaluation| -> Result<serde_json::Value> {
        let mut v = serde_json::to_value(ev)?;
        v["name"] = "rule".into();
        v["settings"] = serde_json::to_value(settings)?;
        Ok(v)
    };
    if args.json {
        let v = match &scored {
            Some((path, clf, mo, ev)) => {
                let meta = clf.meta();
                let mut v = serde_json::to_value(ev)?;
                v["model"] = serde_json::json!({"path": path, "sha256": meta.sha256, "labels": meta.labels, "rig_id": meta.rig_id});
                v["split"] = split_json(meta, mo);
                if let Some(r) = &rule_ev {
                    v["baseline"] = rule_json(r)?;
                }
                v
            }
            None => {
                let r = rule_ev.as_ref().expect("checked above");
                let mut v = serde_json::to_value(r)?;
                v["model"] = serde_json::json!({"kind": "rule", "settings": settings});
                v
            }
        };
        println!("{v}");
        return Ok(());
    }
    match &scored {
        Some((path, clf, mo, ev)) => {
            let meta = clf.meta();
            println!(
                "model {} (rig {}, trained on data {}, calibration {})",
                path.display(),
                meta.rig_id,
                &meta.data_hash[..meta.data_hash.len().min(12)],
                meta.calibration_id
            );
            if !mo.excluded.is_empty() {
                println!(
                    "excluded (the model was fine-tuned on them): {}",
                    mo.excluded.join(", ")
                );
            }
            let extra = mo.labels_not_in_model(&meta.labels);
            if !extra.is_empty() {
                println!(
                    "classes the model lacks, scored as their own rows (an alarm or a miss): {}",
                    extra.join(", ")
                );
            }
            print_records(ev, rule_ev.as_ref());
            print!("{}", summary(ev));
            if let Some(r) = &rule_ev {
                println!("rule baseline on the same records:");
                print!("{}", summary(r));
                println!(
                    "model vs rule: balanced (records) {:.1} % vs {:.1} %   missed alarms {} vs {}   false alarms {} vs {}",
                    100.0 * ev.balanced_accuracy,
                    100.0 * r.balanced_accuracy,
                    ev.missed_alarms,
                    r.missed_alarms,
                    ev.false_alarms,
                    r.false_alarms
                );
            }
        }
        None => {
            let r = rule_ev.as_ref().expect("checked above");
            println!(
                "rule baseline (a {}-order band at BPFO, 2xBPFO, BPFI or 2xBPFI >= {}x the median band; no ball class)",
                settings.band_width_order,
                settings.threshold
            );
            print_records(r, None);
            print!("{}", summary(r));
        }
    }
    Ok(())
}

fn split_json(meta: &crate::model::ModelMeta, mo: &ModelOutcomes) -> serde_json::Value {
    serde_json::json!({
        "model_trained_on_data_hash": meta.data_hash,
        "model_calibration_id": meta.calibration_id,
        "excluded_finetune_records": mo.excluded,
        "skipped_unknown_label_records": Vec::<String>::new(),
        "labels_not_in_model": mo.labels_not_in_model(&meta.labels),
    })
}

/// One line per record; with a rule evaluation of the same records, its verdict beside.
fn print_records(ev: &Evaluation, rule: Option<&Evaluation>) {
    for (i, r) in ev.records.iter().enumerate() {
        let beside = rule
            .and_then(|e| e.records.get(i).filter(|x| x.path == r.path))
            .map(|x| {
                format!(
                    "  rule -> {:<11} {}",
                    x.predicted,
                    if x.correct { "ok" } else { "WRONG" }
                )
            })
            .unwrap_or_default();
        println!(
            "  {:<60} {:>11} -> {:<11} {} windows {:>4}  window acc {:>5.1} %  unknown {:>5.1} %{beside}",
            r.path,
            r.label,
            r.predicted,
            if r.correct { "ok   " } else { "WRONG" },
            r.windows,
            100.0 * r.window_accuracy,
            100.0 * r.unknown_rate
        );
    }
}
