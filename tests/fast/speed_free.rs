//! Alarms never wait for a speed (issue 34, item 4): on a machine without a tacho whose
//! vibration shows no shaft line, every window's speed is uncertain, and a bearing sending
//! impacts through the structure must still end in an alarm, while a quiet healthy record of
//! the same machine raises none. The signals are made here from that description alone (the
//! impulsive test's generator: white sensor noise, impacts at random times ringing down
//! through a 2.9 kHz resonance; here without any shaft line). The model is the shipped
//! fan-end model aligned to a healthy recording whose speed is stated; the scored records are
//! read by the same rig with `[speed] source = "estimate"`, so their speed can come only
//! from their vibration, which holds none.

use crate::common::rigmon;
use crate::impulsive::{manifest_dir, record, write_record_lines, RPM};
use serde_json::Value;
use std::path::Path;

/// The fan-end rig file with its speed read from the vibration (1200-2400 rpm).
fn estimate_rig(path: &Path) {
    let s = std::fs::read_to_string(manifest_dir().join("config/cwru-fe.toml")).unwrap();
    let old = "[speed]\nsource = \"recording\"\n";
    assert!(s.contains(old), "config/cwru-fe.toml changed its [speed]");
    let s = s.replace(
        old,
        "[speed]\nsource = \"estimate\"\nmin_rpm = 1200.0\nmax_rpm = 2400.0\n",
    );
    std::fs::write(path, s).unwrap();
}

#[test]
fn impacts_without_a_speed_end_in_an_alarm_and_a_quiet_machine_in_none() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // the healthy reference: shaft lines, speed stated
    write_record_lines(&d.join("healthy-a.csv"), 1, 12.0, (0.0, 0.0), None, 1.0);
    // no shaft line at all: noise alone, and noise with three impacts a second of 0.5 g
    // (seventeen times the noise RMS) at random times
    write_record_lines(&d.join("quiet.csv"), 5, 12.0, (0.0, 0.0), None, 0.0);
    write_record_lines(&d.join("impacts.csv"), 6, 12.0, (3.0, 0.5), None, 0.0);
    std::fs::write(
        d.join("healthy.csv"),
        format!("path,label,rpm\nhealthy-a.csv,healthy,{RPM}\n"),
    )
    .unwrap();
    std::fs::write(
        d.join("score.csv"),
        "path,label\nquiet.csv,healthy\nimpacts.csv,inner_race\n",
    )
    .unwrap();
    let s = |p: &Path| p.display().to_string();
    let aligned = d.join("aligned.onnx");
    rigmon(&[
        "align",
        "--model",
        &s(&manifest_dir().join("models/cwru-fe.onnx")),
        "--rig",
        &s(&manifest_dir().join("config/cwru-fe.toml")),
        "--healthy",
        &s(&d.join("healthy.csv")),
        "-o",
        &s(&aligned),
    ]);
    let rig = d.join("estimate.toml");
    estimate_rig(&rig);
    let v: Value = serde_json::from_str(&rigmon(&[
        "evaluate",
        "--model",
        &s(&aligned),
        "--rig",
        &s(&rig),
        "--manifest",
        &s(&d.join("score.csv")),
        "--json",
    ]))
    .unwrap();
    for r in v["records"].as_array().unwrap() {
        eprintln!(
            "speed-free: {} -> state {}, window states {}, impulsive windows {}, bad-quality windows {}",
            r["path"], r["state"], r["window_states"], r["impulsive_windows"], r["bad_quality_windows"]
        );
    }
    // the impacts: an alarm (a fault state, not unknown), decided by the impulsiveness on
    // windows whose speed the vibration does not give
    let i = record(&v, "impacts");
    assert_eq!(i["missed_alarm"], false, "{v}");
    let state = i["state"].as_str().unwrap();
    assert!(state != "unknown" && state != "healthy", "{v}");
    assert!(i["impulsive_windows"].as_u64().unwrap() > 0, "{v}");
    // the quiet machine: no alarm
    let q = record(&v, "quiet");
    assert_eq!(q["false_alarm"], false, "{v}");
    assert_eq!(q["impulsive_windows"], 0, "{v}");
    assert_eq!(v["false_alarms"], 0, "{v}");
}
