//! `rigmon adapt` end to end on a small case: measured-like recordings of the LUT rig from
//! the independent generator (`tests/python/measured_like.py`, not rigmon's simulator) with
//! one undeclared effect (slip), draw 1 to adapt on and draw 2 held out. Checks the folder
//! (model, calibrated rig file, reports, PNGs), the model with onnxruntime and the ONNX
//! checker, the report's before/after/rule scores and calibration errors, and that
//! `rigmon evaluate` then uses the folder's model and rig file like any other.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn generate(dir: &Path, case: &str, seed: &str) {
    let out = Command::new("python3")
        .arg(repo().join("tests/python/measured_like.py"))
        .arg("--out")
        .arg(dir)
        .args(["--case", case, "--seed", seed, "--seconds", "3"])
        .output()
        .expect("python3 with numpy is needed (tests/python/requirements.txt)");
    assert!(
        out.status.success(),
        "measured_like.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn rigmon(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rigmon {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

fn num(v: &Value, what: &str) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"))
}

#[test]
fn adapt_writes_a_model_and_report_that_evaluate_uses() {
    let dir = tempfile::tempdir().unwrap();
    let (draw1, draw2, out) = (
        dir.path().join("draw1"),
        dir.path().join("draw2"),
        dir.path().join("adapted"),
    );
    generate(&draw1, "slip", "1");
    generate(&draw2, "slip", "2");
    let rig = repo().join("config/lut-rig.toml");
    let t0 = std::time::Instant::now();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let report: Value = serde_json::from_str(&rigmon(&[
        "adapt",
        "--rig",
        &s(&rig),
        "--measured",
        &s(&draw1.join("labels.csv")),
        "--holdout",
        &s(&draw2.join("labels.csv")),
        "-o",
        &s(&out),
        "--seeds",
        "2",
        "--recordings",
        "24",
        "--epochs",
        "60",
        "--quiet",
        "--json",
    ]))
    .unwrap();
    eprintln!(
        "adapt: {:.1} s; steps {}",
        t0.elapsed().as_secs_f64(),
        report["timings"]
    );
    for f in [
        "model.onnx",
        "rig.toml",
        "report.md",
        "report.json",
        "plan.toml",
        "confusion_after.png",
        "confusion_before.png",
        "confusion_rule.png",
        "holdout_confusion_after.png",
        "calibration_spectra.png",
        "calibration/report.md",
        "seeds/seed1.onnx",
        "seeds/seed2.onnx",
    ] {
        assert!(out.join(f).is_file(), "adapt wrote no {f}");
    }
    assert!(
        !out.join("datasets").exists(),
        "simulated data is removed unless --keep-datasets"
    );
    let on_disk: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(on_disk["chosen_seed"], report["chosen_seed"]);

    // calibration: error before and after, and the slip the generator injected is named
    let cal = &report["calibration"];
    let (before, after) = (
        num(&cal["error_before"], "error_before"),
        num(&cal["error_after"], "error_after"),
    );
    assert!(after <= before, "calibration made the error worse: {cal}");
    let effects: Vec<&str> = cal["effects"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["name"].as_str())
        .collect();
    assert!(effects.contains(&"slip"), "slip not found: {cal}");

    // training: every seed reported, the kept one is the best on simulated validation
    let seeds = report["seeds"].as_array().unwrap();
    assert_eq!(seeds.len(), 2);
    let best = seeds
        .iter()
        .map(|s| num(&s["validation_balanced_accuracy"], "val"))
        .fold(0.0, f64::max);
    let kept = seeds
        .iter()
        .find(|s| s["seed"] == report["chosen_seed"])
        .unwrap();
    assert_eq!(num(&kept["validation_balanced_accuracy"], "kept"), best);

    // before / after / rule on the six measured and the six held-out recordings
    for set in ["measured_scores", "holdout_scores"] {
        for k in ["before", "after", "rule"] {
            let e = &report[set][k];
            assert_eq!(e["n_records"], 6, "{set}.{k}: {e}");
            for key in ["missed_alarms", "false_alarms"] {
                assert!(e[key].is_u64(), "{set}.{k}.{key} missing");
            }
        }
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for needle in [
        "before (zero-shot)",
        "after (adapted)",
        "rule baseline",
        "error",
    ] {
        assert!(md.contains(needle), "report.md lacks {needle:?}");
    }

    // the model file: the reference checker and onnxruntime accept it; it carries the
    // calibration id of the rig file it came from
    let chk = Command::new("python3")
        .arg(repo().join("tests/python/check_onnx.py"))
        .arg(out.join("model.onnx"))
        .output()
        .unwrap();
    assert!(
        chk.status.success(),
        "check_onnx.py: {}",
        String::from_utf8_lossy(&chk.stderr)
    );
    let model = rigmon_model_meta(&out.join("model.onnx"));
    assert_eq!(model, cal["id"].as_str().unwrap());

    // rigmon evaluate uses the folder like any model, with the rule beside it
    let ev: Value = serde_json::from_str(&rigmon(&[
        "evaluate",
        "--model",
        &s(&out.join("model.onnx")),
        "--rig",
        &s(&out.join("rig.toml")),
        "--manifest",
        &s(&draw2.join("labels.csv")),
        "--baseline",
        "rule",
        "--json",
    ]))
    .unwrap();
    assert_eq!(ev["n_records"], 6);
    assert_eq!(ev["baseline"]["n_records"], 6);
    assert_eq!(
        ev["balanced_accuracy"], report["holdout_scores"]["after"]["balanced_accuracy"],
        "evaluate and adapt's report disagree"
    );
}

/// The calibration id in a model's metadata (tract, as the daemon loads it).
fn rigmon_model_meta(p: &Path) -> String {
    rigmon::model::OnnxClassifier::load(p)
        .unwrap()
        .meta()
        .calibration_id
        .clone()
}
