//! `rigmon adapt` end to end on a small case: measured-like recordings of the LUT rig from
//! the independent generator (`tests/python/measured_like.py`, not rigmon's simulator) with
//! one undeclared effect (slip), draw 1 to adapt on and draw 2 held out. Checks the folder
//! (model, calibrated rig file, reports, PNGs), the model with onnxruntime and the ONNX
//! checker, the report's before/after/rule scores and calibration errors, and that
//! `rigmon evaluate` then uses the folder's model and rig file like any other.

use crate::common::rigmon;
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

/// `rigmon adapt` with `args`: (exit status success, stdout, stderr).
fn rigmon_status(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string(),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

/// Everything adapt can know is wrong is refused before any long work: the output folder is
/// not even created, and the error names what is wrong and where.
#[test]
fn adapt_refuses_a_standing_shaft_a_missing_file_and_a_too_short_recording_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    generate(&data, "baseline", "1");
    let rig = repo().join("config/lut-rig.toml");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let refuse = |measured: &Path, plan: Option<&Path>, out: &Path| -> String {
        let mut args = vec![
            "adapt".to_string(),
            "--rig".into(),
            s(&rig),
            "--measured".into(),
            s(measured),
            "-o".into(),
            s(out),
            "--quiet".into(),
        ];
        if let Some(p) = plan {
            args.extend(["--plan".into(), s(p)]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (ok, _, err) = rigmon_status(&args);
        assert!(!ok, "adapt accepted {args:?}");
        assert!(!out.exists(), "adapt started work before refusing: {err}");
        err
    };

    // a plan that would simulate a standing shaft
    let plan = dir.path().join("standing.toml");
    std::fs::write(
        &plan,
        "name = \"standing\"\ndescription = \"a case at 0 rpm\"\nseed = 1\nseconds = 2.0\n\n\
         [[case]]\nfaults = \"healthy\"\nrpm = 600.0\nrecordings = 2\n\n\
         [[case]]\nfaults = \"outer_race\"\nrpm = 0.0\nrecordings = 2\n",
    )
    .unwrap();
    let err = refuse(
        &data.join("labels.csv"),
        Some(&plan),
        &dir.path().join("o1"),
    );
    assert!(
        err.contains("0.0 rpm") && err.contains("turning shaft"),
        "{err}"
    );

    // a plan without a class the model predicts (training would stop on it at the end)
    let plan = dir.path().join("healthy-only.toml");
    std::fs::write(
        &plan,
        "name = \"healthy-only\"\ndescription = \"no fault class\"\nseed = 1\nseconds = 2.0\n\n\
         [[case]]\nfaults = \"healthy\"\nrpm = 600.0\nrecordings = 2\n",
    )
    .unwrap();
    let err = refuse(
        &data.join("labels.csv"),
        Some(&plan),
        &dir.path().join("o4"),
    );
    assert!(
        err.contains("simulates no") && err.contains("outer_race"),
        "{err}"
    );

    // a listed file that does not exist
    let missing = dir.path().join("missing.csv");
    std::fs::write(
        &missing,
        format!(
            "path,label\n{},healthy\n{}/gone.csv,outer_race\n",
            s(&data.join("healthy-600rpm.csv")),
            s(&data)
        ),
    )
    .unwrap();
    let err = refuse(&missing, None, &dir.path().join("o2"));
    assert!(
        err.contains("gone.csv") && err.contains("does not exist") && err.contains(":3"),
        "{err}"
    );

    // a recording far too short for a feature window or a speed (0.05 s)
    let full = std::fs::read_to_string(data.join("healthy-1200rpm.csv")).unwrap();
    let short: Vec<&str> = full.lines().take(501).collect();
    let short_csv = dir.path().join("short-1200rpm.csv");
    std::fs::write(&short_csv, short.join("\n") + "\n").unwrap();
    let short_manifest = dir.path().join("short.csv");
    std::fs::write(
        &short_manifest,
        format!(
            "path,label\n{},healthy\n{},healthy\n",
            s(&data.join("healthy-600rpm.csv")),
            s(&short_csv)
        ),
    )
    .unwrap();
    let err = refuse(&short_manifest, None, &dir.path().join("o3"));
    assert!(err.contains("short-1200rpm.csv"), "{err}");
}

/// Adapt checks itself: handed labelled race faults, with a plan whose fault classes carry
/// no defect to learn from (a 1 um scratch, and louder sensor noise: the model learns the
/// noise, not the fault), it misses them, says so on stderr and in the report, keeps the
/// model out of `model.onnx` and exits non-zero; `--accept-regression` writes it as
/// `model.onnx`, still saying so. Only fault recordings are given, so no healthy-baseline
/// gate stands in for the classifier.
#[test]
fn adapt_that_misses_a_labelled_fault_says_so_and_exits_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    generate(&data, "baseline", "1");
    let rig = repo().join("config/lut-rig.toml");
    let plan = dir.path().join("no-defects.toml");
    // fault classes whose defect is a 1 um scratch: they look healthy
    let mut toml = String::from(
        "name = \"no-defects\"\ndescription = \"fault classes without a defect\"\nseed = 7\nseconds = 2.0\n\n\
         [random]\nrpm = [580.0, 1220.0]\n",
    );
    for class in ["healthy", "outer_race", "inner_race"] {
        toml += &format!("\n[[case]]\nfaults = \"{class}\"\nrecordings = 10\n");
        if class != "healthy" {
            toml += "[case.overrides]\ndefect_width_mm = 0.001\ndefect_depth_mm = 0.0001\nnoise_rms_m_s2 = 30.0\n";
        }
    }
    std::fs::write(&plan, toml).unwrap();
    let labels = std::fs::read_to_string(data.join("labels.csv")).unwrap();
    let faults: Vec<&str> = labels.lines().filter(|l| !l.contains("healthy")).collect();
    assert_eq!(faults.len(), 5, "header and four race-fault recordings");
    let manifest = data.join("faults.csv");
    std::fs::write(&manifest, faults.join("\n") + "\n").unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let run = |out: &Path, accept: bool| {
        let mut args = vec![
            "adapt".to_string(),
            "--rig".into(),
            s(&rig),
            "--measured".into(),
            s(&manifest),
            "--plan".into(),
            s(&plan),
            "-o".into(),
            s(out),
            "--seeds".into(),
            "1".into(),
            "--epochs".into(),
            "40".into(),
            "--quiet".into(),
        ];
        if accept {
            args.push("--accept-regression".into());
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        rigmon_status(&args)
    };

    let out = dir.path().join("refused");
    let (ok, _, err) = run(&out, false);
    assert!(
        !ok,
        "adapt exited 0 with a model that misses labelled faults:\n{err}"
    );
    assert!(err.contains("SELF-CHECK FAILED"), "{err}");
    assert!(
        err.contains("outer_race") || err.contains("inner_race"),
        "the missed recording is not named: {err}"
    );
    assert!(
        !out.join("model.onnx").exists(),
        "the failing model was written as model.onnx"
    );
    assert!(out.join("model.rejected.onnx").is_file());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("SELF-CHECK FAILED") && md.contains("NOT written"),
        "{md}"
    );
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let missed = report["self_check"]["regressions"].as_array().unwrap();
    assert!(!missed.is_empty());
    // each regression is a labelled fault the adapted model's own score counts as missed
    for r in missed {
        let rec = report["measured_scores"]["after"]["records"]
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["path"] == r["recording"])
            .unwrap();
        assert_eq!(rec["missed_alarm"], true, "{rec}");
        assert_ne!(rec["label"], "healthy");
    }

    let out = dir.path().join("accepted");
    let (ok, _, err) = run(&out, true);
    assert!(ok, "--accept-regression still failed:\n{err}");
    assert!(err.contains("SELF-CHECK FAILED"), "{err}");
    assert!(out.join("model.onnx").is_file());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("--accept-regression"), "{md}");
}
