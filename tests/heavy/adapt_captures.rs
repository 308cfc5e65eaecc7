//! `rigmon adapt` on a series of captures (issue 35): the first captures of a synthetic run to
//! failure ([`crate::femto_life`], FEMTO's rig file) as the healthy-only measured set. adapt
//! calibrates the FEMTO rig's simulator on the captures (each capture a segment of its own),
//! trains on the calibrated simulation and stores the healthy indicator baseline with the
//! alignment; the replay of the whole life with the adapted model then departs after the
//! defect's onset, never in the baseline, and holds a fault state to the end.

use crate::common::rigmon;
use crate::femto_life::{baseline_manifest, capture_at, life, BASELINE, CAPTURES, ONSET};
use serde_json::Value;

#[test]
fn adapt_on_the_first_captures_of_a_life_keeps_the_alarm_that_holds() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing9_7");
    life(&dir, true);
    let d = dir.to_str().unwrap();
    let manifest = baseline_manifest(tmp.path(), d);
    let out = tmp.path().join("adapted");
    let repo = env!("CARGO_MANIFEST_DIR");
    rigmon(&[
        "adapt",
        "-q",
        "--rig",
        &format!("{repo}/config/femto.toml"),
        "--measured",
        manifest.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--recordings",
        "20",
        "--seeds",
        "1",
        "--json",
    ]);
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let cal = &report["calibration"];
    let err = |k: &str| {
        cal[k]
            .as_f64()
            .unwrap_or_else(|| panic!("calibration.{k}: {cal}"))
    };
    assert!(err("error_after") < err("error_before"), "{cal}");
    let model = rigmon::model::OnnxClassifier::load(&out.join("model.onnx")).unwrap();
    let alignment = model.meta().alignment.as_ref().expect("an aligned model");
    assert!(
        alignment.indicators().is_some(),
        "adapt stored no healthy indicator baseline: {alignment:?}"
    );

    let replay = rigmon(&[
        "replay",
        d,
        "--rig",
        out.join("rig.toml").to_str().unwrap(),
        "--rpm",
        "1800",
        "--model",
        out.join("model.onnx").to_str().unwrap(),
        "--json",
    ]);
    let msgs: Vec<Value> = replay
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(msgs.len(), CAPTURES);
    let departed = |m: &Value| !m["indicators"]["departure"]["departed_since_s"].is_null();
    let first = msgs.iter().position(departed).expect("the replay departs");
    let at = capture_at(msgs[first]["window"]["end_s"].as_f64().unwrap());
    assert!(
        (ONSET + 45..ONSET + 75).contains(&at),
        "departed at capture {at}"
    );
    for m in &msgs[..BASELINE] {
        let s = m["state"].as_str().unwrap();
        assert!(
            s == "healthy" || s == "unknown",
            "a fault in the baseline: {m}"
        );
    }
    for m in &msgs[first..] {
        let s = m["state"].as_str().unwrap();
        assert!(departed(m) && s != "healthy" && s != "unknown", "{m}");
    }
}
