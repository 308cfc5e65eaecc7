//! The alarm that holds (issue 35, items 3-4) on a synthetic run to failure built from the
//! physics of a bearing on the FEMTO rig (`config/femto.toml`: 13 balls of 3.5 mm on a 25.6
//! mm pitch, 1800 rpm, 0.1 s captures at 25.6 kHz every 10 s): shaft lines and broadband
//! noise, a run-in (the first captures louder, settling), a slow drift of the noise level,
//! one capture twenty times as loud, and from capture [`ONSET`] on an outer-race defect whose
//! impacts, at the ball-pass frequency, ring a 4 kHz structural resonance and grow. Checked
//! through `rigmon trend` and the daemon's path (`rigmon align` on the healthy part, then
//! `rigmon replay` of the whole life): no alarm in the baseline nor from the run-in, the loud
//! capture or the drift; an alarm after the onset, the state a fault from it to the end.

use std::path::Path;

const FS: f64 = 25_600.0;
const N: usize = 2560;
/// Captures in the life, in the baseline (the first fifth), the defect's first one and the
/// loud one.
const CAPTURES: usize = 200;
const BASELINE: usize = 40;
const ONSET: usize = 100;
const LOUD: usize = 70;

/// A deterministic Gaussian-like noise sample (sum of 4 uniform hashes, unit variance).
fn noise(i: usize, k: usize) -> f64 {
    let mut s = 0.0;
    for j in 0..4usize {
        let h = (i.wrapping_mul(2_654_435_761) ^ k.wrapping_mul(40_503) ^ j.wrapping_mul(97_531))
            .wrapping_mul(0x9E37_79B9)
            % 1_000_003;
        s += h as f64 / 1_000_003.0 - 0.5;
    }
    s * (12.0f64 / 4.0).sqrt()
}

/// Capture `k`'s horizontal signal, g (with or without the defect).
fn capture(k: usize, with_defect: bool) -> Vec<f64> {
    let tau = 2.0 * std::f64::consts::PI;
    let shaft = 30.0; // 1800 rpm
    let bpfo = shaft * 6.5 * (1.0 - 3.5 / 25.6); // 168 Hz
    let run_in = 1.0 + 0.6 * (-(k as f64) / 8.0).exp();
    let drift = 1.0 + 0.0004 * k as f64;
    let loud = if k == LOUD { 20.0 } else { 1.0 };
    let defect = if with_defect && k >= ONSET {
        0.15 * (k - ONSET + 1) as f64
    } else {
        0.0
    };
    (0..N)
        .map(|i| {
            let t = (k as f64 * 10.0) + i as f64 / FS;
            let lines = 0.2 * (tau * shaft * t).sin() + 0.05 * (tau * 2.0 * shaft * t).sin();
            // the last impact before t rings the 4 kHz resonance (damping 3 %)
            let since = t % (1.0 / bpfo);
            let ring = (-0.03 * tau * 4000.0 * since).exp() * (tau * 4000.0 * since).sin();
            loud * (run_in * drift * (lines + 0.3 * noise(i, k)) + defect * ring)
        })
        .collect()
}

/// The life as a FEMTO folder: headerless CSVs with the capture clock.
fn life(dir: &Path, with_defect: bool) {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..CAPTURES {
        let secs = 8 * 3600 + 10 * k;
        let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
        let mut text = String::with_capacity(N * 32);
        for (i, x) in capture(k, with_defect).into_iter().enumerate() {
            let us = i as f64 * 39.0625;
            text.push_str(&format!("{h},{m},{s},{us:e},{x:.4},{:.4}\n", 0.5 * x));
        }
        std::fs::write(dir.join(format!("acc_{:05}.csv", k + 1)), text).unwrap();
    }
}

fn rigmon(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.success(), text(&out.stdout), text(&out.stderr))
}

/// Capture index of a time on the capture clock (s since the first capture).
fn capture_at(t: f64) -> usize {
    (t / 10.0).floor() as usize
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
    let manifest = tmp.join("healthy.csv");
    let end = BASELINE as f64 * 10.0;
    std::fs::write(
        &manifest,
        format!("path,label,rpm,start_s,end_s\n{d},healthy,1800,0,{end}\n"),
    )
    .unwrap();
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
