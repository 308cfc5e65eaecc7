//! A fault far stronger than anything simulated must raise an alarm, not `unknown`. The
//! shipped fan-end model (simulation only) is aligned to the CWRU normal baseline's first
//! 2.5 s (`rigmon align`), then the real 0.014 in and 0.021 in outer-race faults at 6 o'clock
//! seen from the fan end are replayed through the daemon's pipeline: every window lies beyond
//! the machine's healthy baseline and is novel to the network (its novelty score is above the
//! model's threshold). The health state must be `outer_race`, with the window flagged
//! `alarm_despite = novelty`; the normal record must stay `healthy` with no flag. `rigmon
//! evaluate` must say the same per record (`state`) and count no missed alarm.

use serde_json::Value;
use std::path::{Path, PathBuf};

use crate::common::rigmon;
use crate::common::shared_data;

fn repo(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .display()
        .to_string()
}

/// The shipped fan-end model aligned on the first half of the normal baseline.
fn aligned(dir: &Path) -> PathBuf {
    let data = shared_data();
    let csv = dir.join("healthy.csv");
    std::fs::write(
        &csv,
        format!(
            "path,label,start_s,end_s\n{},healthy,0,2.5\n",
            data.join("cwru/97_Normal_0.mat").display()
        ),
    )
    .unwrap();
    let out = dir.join("aligned.onnx");
    rigmon(&[
        "align",
        "--model",
        &repo("models/cwru-fe.onnx"),
        "--rig",
        &repo("config/cwru-fe.toml"),
        "--healthy",
        csv.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    out
}

/// Health messages of a replay.
fn replay(model: &Path, file: &Path) -> Vec<Value> {
    rigmon(&[
        "replay",
        "--rig",
        &repo("config/cwru-fe.toml"),
        "--model",
        model.to_str().unwrap(),
        "--json",
        file.to_str().unwrap(),
    ])
    .lines()
    .map(|l| serde_json::from_str(l).unwrap())
    .collect()
}

#[test]
fn strong_real_faults_beyond_the_simulation_raise_an_alarm_and_healthy_stays_healthy() {
    let data = shared_data();
    let dir = tempfile::tempdir().unwrap();
    let model = aligned(dir.path());
    for rel in [
        "cwru-fe/014/OR014_centered_at_6_0.mat",
        "cwru-fe/021/OR021_centered_at_6_0.mat",
    ] {
        let msgs = replay(&model, &data.join(rel));
        assert!(msgs.len() >= 10, "{rel}: {} windows", msgs.len());
        // The premise: these windows are novel to the network and beyond the baseline.
        let novel = msgs
            .iter()
            .filter(|m| m["novelty"].as_f64() > m["novelty_threshold"].as_f64())
            .count();
        assert!(novel * 2 > msgs.len(), "{rel}: only {novel} novel windows");
        assert!(
            msgs.iter().all(|m| m["beyond_baseline"] == true),
            "{rel}: a window within the healthy baseline"
        );
        let last = msgs.last().unwrap();
        assert_eq!(last["state"], "outer_race", "{rel}: {last}");
        let flagged = msgs
            .iter()
            .filter(|m| m["alarm_despite"] == "novelty")
            .count();
        assert_eq!(
            flagged, novel,
            "{rel}: every novel window is a flagged alarm"
        );
        assert!(msgs.iter().all(|m| m["window_state"] != "unknown"), "{rel}");
    }
    let normal = replay(&model, &data.join("cwru/97_Normal_0.mat"));
    for m in &normal {
        assert_eq!(m["beyond_baseline"], false, "{m}");
        assert!(m.get("alarm_despite").is_none(), "{m}");
        assert!(m["state"] == "healthy" || m["state"] == "unknown", "{m}");
    }
    assert_eq!(normal.last().unwrap()["state"], "healthy");

    // evaluate scores what the daemon says, per record.
    let manifest = dir.path().join("score.csv");
    std::fs::write(
        &manifest,
        format!(
            "path,label,start_s,end_s\n{},healthy,2.5,\n{},outer_race,,\n{},outer_race,,\n",
            data.join("cwru/97_Normal_0.mat").display(),
            data.join("cwru-fe/014/OR014_centered_at_6_0.mat").display(),
            data.join("cwru-fe/021/OR021_centered_at_6_0.mat").display(),
        ),
    )
    .unwrap();
    let ev: Value = serde_json::from_str(&rigmon(&[
        "evaluate",
        "--model",
        model.to_str().unwrap(),
        "--rig",
        &repo("config/cwru-fe.toml"),
        "--manifest",
        manifest.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let states: Vec<&str> = ev["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["state"].as_str().unwrap())
        .collect();
    assert_eq!(states, ["healthy", "outer_race", "outer_race"], "{ev}");
    assert_eq!(ev["missed_alarms"], 0, "{ev}");
    assert_eq!(ev["false_alarms"], 0, "{ev}");
    assert_eq!(ev["unknown_states"], 0, "{ev}");
}
