//! The alarm that holds (issue 35, items 3-4) on a synthetic run to failure
//! ([`crate::femto_life`]: a FEMTO-rig bearing with a run-in, a drift, one loud capture and an
//! outer-race defect growing from capture [`ONSET`]). Checked through `rigmon trend` and the
//! daemon's path (`rigmon align` on the healthy part, then `rigmon replay` of the whole life):
//! no alarm in the baseline nor from the run-in, the loud capture or the drift; an alarm after
//! the onset, the state a fault from it to the end. (`adapt` on the same life: the heavy tier.)

use crate::femto_life::{baseline_manifest, capture_at, life, BASELINE, CAPTURES, ONSET};
use std::path::Path;

fn rigmon(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.success(), text(&out.stdout), text(&out.stderr))
}

#[test]
fn a_defect_that_grows_alarms_and_holds_and_nothing_else_does() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing9_9");
    life(&dir, true);
    let d = dir.to_str().unwrap();
    let v = trend(d);
    let g = &v["rigmon"];
    assert_eq!(g["alarms_in_baseline"], 0, "{g}");
    let alarm = g["alarm_s"]
        .as_f64()
        .unwrap_or_else(|| panic!("no alarm: {g}"));
    // after the onset (the loud capture, the run-in and the drift alone never alarm), and
    // within the median's (16 windows) and the persistence's (30) reach of it
    let at = capture_at(alarm);
    assert!(
        (ONSET + 45..ONSET + 75).contains(&at),
        "alarm at capture {at}: {g}"
    );
    assert!(g["beyond_after"].as_f64().unwrap() >= 0.9, "{g}");
    // the same life without the defect (run-in, drift, the loud capture): no alarm at all
    let healthy = tmp.path().join("Bearing9_8");
    life(&healthy, false);
    let v = trend(healthy.to_str().unwrap());
    assert!(v["rigmon"]["alarm_s"].is_null(), "{v}");
    assert!(v["rigmon"]["baseline"]["windows"] == BASELINE, "{v}");
    replay_holds_the_alarm(tmp.path(), d, alarm);
}

/// `rigmon trend --json` of a folder with the first [`BASELINE`] captures as the baseline.
fn trend(d: &str) -> serde_json::Value {
    let frac = format!("{}", BASELINE as f64 / CAPTURES as f64);
    let (ok, out, err) = rigmon(&[
        "trend",
        d,
        "--rig",
        "config/femto.toml",
        "--baseline-fraction",
        &frac,
        "--json",
    ]);
    assert!(ok, "{err}");
    serde_json::from_str(out.trim()).unwrap()
}

/// `rigmon align` on the first captures, then `rigmon replay` of the whole life: the
/// daemon's state machine departs where the trend did, and the state is a fault from there on.
fn replay_holds_the_alarm(tmp: &Path, d: &str, trend_alarm: f64) {
    let manifest = baseline_manifest(tmp, d);
    let model = tmp.join("aligned.onnx");
    let (ok, out, err) = rigmon(&[
        "align",
        "--model",
        "models/cwru-de.onnx",
        "--rig",
        "config/femto.toml",
        "--healthy",
        manifest.to_str().unwrap(),
        "-o",
        model.to_str().unwrap(),
        "--allow-foreign-model",
    ]);
    assert!(ok && out.contains("healthy_indicators"), "{out}{err}");
    let (ok, out, err) = rigmon(&[
        "replay",
        d,
        "--rig",
        "config/femto.toml",
        "--rpm",
        "1800",
        "--model",
        model.to_str().unwrap(),
        "--allow-foreign-model",
        "--json",
    ]);
    assert!(ok, "{err}");
    let msgs: Vec<serde_json::Value> = out
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(msgs.len(), CAPTURES);
    let departed =
        |m: &serde_json::Value| !m["indicators"]["departure"]["departed_since_s"].is_null();
    let first = msgs.iter().position(departed).expect("the replay departs");
    let t = msgs[first]["window"]["end_s"].as_f64().unwrap();
    assert!(
        (t - trend_alarm).abs() < 1e-6,
        "replay {t} s, trend {trend_alarm} s"
    );
    assert!(msgs[..first].iter().all(|m| !departed(m)));
    for m in &msgs[first..] {
        let s = m["state"].as_str().unwrap();
        assert!(departed(m) && s != "healthy" && s != "unknown", "{m}");
        assert!(m["indicators"]["values"]["kurtosis"].is_number(), "{m}");
    }
}
