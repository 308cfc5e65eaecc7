//! A folder of periodic captures read as one recording (issue 35, items 1 and 2): FEMTO
//! PRONOSTIA's headerless CSV captures written here (clock columns, `;` in some files, a clock
//! that jumps by hours, temperature files beside) and a folder of CSV captures with a header and
//! no clock. Checks that each capture becomes exactly its own windows at its own time (none
//! straddles two, nothing counted lost), that the 0.1 s windows say their order resolution,
//! that the stream reads one capture at a time, that a manifest span picks captures by time,
//! and that `rigmon replay` and `rigmon import` take the folder.

use rigmon::config::RigConfig;
use rigmon::importers::{self, ImportOptions};
use rigmon::recording::captures;
use std::path::{Path, PathBuf};

const FS: f64 = 25_600.0;
const N: usize = 2560;

fn femto_rig() -> RigConfig {
    RigConfig::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/femto.toml")).unwrap()
}

/// Capture `k`: a 3 kHz carrier modulated at the 1800 rpm shaft rate (a line at order 1 in
/// the envelope) and a little deterministic noise, `level` g.
fn capture(k: usize, level: f64) -> Vec<(f64, f64)> {
    (0..N)
        .map(|i| {
            let t = i as f64 / FS;
            let noise = (((i * 7919 + k * 104_729) % 1000) as f64 / 1000.0 - 0.5) * 0.2;
            let tau = 2.0 * std::f64::consts::PI;
            let x = level * (1.0 + 0.5 * (tau * 30.0 * t).sin()) * (tau * 3000.0 * t).sin() + noise;
            (x, 0.5 * x - noise)
        })
        .collect()
}

/// A FEMTO-like bearing folder: `n` captures every 10 s from 09:39:39, capture `jump`'s
/// clock set back by six hours, files 3 and 4 with `;`, two temperature files.
fn femto_folder(dir: &Path, n: usize, jump: usize) {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..n {
        let mut secs = 9 * 3600 + 39 * 60 + 39 + 10 * k;
        if k == jump {
            secs -= 6 * 3600;
        }
        let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
        let sep = if k == 3 || k == 4 { ";" } else { "," };
        let mut text = String::new();
        for (i, (x, y)) in capture(k, 1.0 + k as f64).into_iter().enumerate() {
            let us = 65_664.0 + i as f64 * 39.0625;
            text.push_str(&format!(
                "{h}{sep}{m}{sep}{s}{sep}{us:e}{sep}{x:.3}{sep}{y:.3}\n"
            ));
        }
        std::fs::write(dir.join(format!("acc_{:05}.csv", k + 1)), text).unwrap();
    }
    for k in 1..=2 {
        std::fs::write(dir.join(format!("temp_{k:05}.csv")), "9;39;40;5;70.4\n").unwrap();
    }
}

fn rpm(r: f64) -> ImportOptions {
    ImportOptions {
        rpm: Some(r),
        ..Default::default()
    }
}

#[test]
fn a_femto_folder_is_a_recording_of_captures_each_its_own_window() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing1_1");
    femto_folder(&dir, 12, 8);
    let rig = femto_rig();
    let rec = importers::load(&dir, &rig, &rpm(1800.0)).unwrap();
    assert_eq!(rec.len(), 12 * N);
    assert_eq!(rec.sample_rate, FS);
    let notes = rec.provenance.notes.join("\n");
    for want in [
        "2 temperature file(s)",
        "12 captures of 2560 samples (0.100 s) every 10 s",
        "clock jumps at 2 file(s): acc_00009.csv",
    ] {
        assert!(notes.contains(want), "{want:?} not in {notes}");
    }
    // The first value of capture 4 (a `;` file), scaled as written.
    let h = rec.channel("horizontal").unwrap();
    assert!((h.samples[3 * N] - capture(3, 4.0)[0].0 as f32).abs() < 1e-3);
    let wins = rigmon::analysis::extract_recording(&rec, &rig).unwrap();
    let starts: Vec<f64> = wins.iter().map(|w| w.t_start).collect();
    // One window per capture, at its time: the jumped captures one interval after the last.
    let want: Vec<f64> = (0..12).map(|k| 10.0 * k as f64).collect();
    assert_eq!(starts.len(), 12, "{starts:?}");
    for (got, want) in starts.iter().zip(&want) {
        assert!((got - want).abs() < 1e-6, "{starts:?}");
    }
    for w in &wins {
        assert!(w.quality.is_clean(), "{:?}", w.quality.flags());
        assert!(
            (w.quality.revolutions - 3.0).abs() < 0.01,
            "{}",
            w.quality.revolutions
        );
        assert!((w.quality.order_resolution - 1.0 / 3.0).abs() < 0.01);
    }
    // Each window holds one capture only: its level grows capture by capture.
    let rms: Vec<f32> = wins
        .iter()
        .map(|w| {
            w.channel_features("horizontal")
                .iter()
                .map(|x| x * x)
                .sum::<f32>()
        })
        .collect();
    assert!(rms.windows(2).all(|p| p[1] > p[0]), "{rms:?}");
}

#[test]
fn the_stream_reads_one_capture_at_a_time_and_loses_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    femto_folder(&dir, 6, 99);
    let rig = femto_rig();
    let mut s = importers::open(&dir, &rig, &rpm(1800.0)).unwrap();
    assert!(captures::is_capture_series(&s.info().metadata));
    let first = s.next_block().unwrap().unwrap();
    assert_eq!((first.first_sample, first.len()), (0, N));
    // Capture 5 damaged after the stream opened: only reading it fails, naming it.
    std::fs::write(dir.join("acc_00005.csv"), "1,2,3,4,x,0\n").unwrap();
    let mut firsts = vec![first.first_sample];
    let err = loop {
        match s.next_block() {
            Ok(Some(b)) => firsts.push(b.first_sample),
            Ok(None) => panic!("the damaged capture was read"),
            Err(e) => break format!("{e:#}"),
        }
    };
    assert_eq!(firsts, vec![0, 256_000, 512_000, 768_000]);
    assert!(err.contains("acc_00005.csv: line 1, column 5"), "{err}");
    assert!(s.losses().is_empty());
}

#[test]
fn csv_captures_without_a_clock_need_the_stated_interval() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("snaps");
    std::fs::create_dir_all(&dir).unwrap();
    for k in [1, 2, 10] {
        let mut text = String::from("horizontal,vertical\n");
        for (x, y) in capture(k, 1.0) {
            text.push_str(&format!("{x},{y}\n"));
        }
        std::fs::write(dir.join(format!("snap_{k}.csv")), text).unwrap();
    }
    let mut rig = femto_rig();
    rig.acquisition.capture_interval_s = None;
    let e = format!(
        "{:#}",
        importers::load(&dir, &rig, &rpm(1800.0)).unwrap_err()
    );
    assert!(e.contains("set acquisition.capture_interval_s"), "{e}");
    rig.acquisition.capture_interval_s = Some(60.0);
    let rec = importers::load(&dir, &rig, &rpm(1800.0)).unwrap();
    let wins = rigmon::analysis::extract_recording(&rec, &rig).unwrap();
    // Natural order: snap_10 is the third capture, at 120 s.
    let starts: Vec<f64> = wins.iter().map(|w| w.t_start).collect();
    assert_eq!(starts, vec![0.0, 60.0, 120.0]);
    // A folder mixing types is refused by name.
    std::fs::write(dir.join("x.wav"), b"RIFF").unwrap();
    let e = format!(
        "{:#}",
        importers::load(&dir, &rig, &rpm(1800.0)).unwrap_err()
    );
    assert!(e.contains("mixes capture types (3 .csv, 1 .wav)"), "{e}");
}

#[test]
fn a_manifest_span_over_a_folder_keeps_the_captures_inside_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing1_1");
    femto_folder(&dir, 10, 99);
    let csv = tmp.path().join("labels.csv");
    std::fs::write(
        &csv,
        "path,label,start_s,end_s,rpm\nBearing1_1,healthy,0,45,1800\n",
    )
    .unwrap();
    let entries = rigmon::manifest::read_manifest(&csv).unwrap();
    let f = rigmon::train::score::analyze_entry(&entries[0], &femto_rig()).unwrap();
    // Captures at 0, 10, 20, 30 and 40 s lie inside [0, 45 s].
    assert_eq!(f.windows.len(), 5);
    assert!((f.rpm() - 1800.0).abs() < 1e-6, "{}", f.rpm());
    assert_eq!(f.sha256.len(), 64);
}

fn rigmon_cmd(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.success(), text(&out.stdout), text(&out.stderr))
}

#[test]
fn replay_and_import_take_the_folder_and_count_captures_not_losses() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing1_1");
    femto_folder(&dir, 8, 99);
    let d = dir.to_str().unwrap();
    let common = ["--rig", "config/femto.toml", "--rpm", "1800"];
    let mut args = vec![
        "replay",
        d,
        "--speed",
        "max",
        "--model",
        "models/cwru-de.onnx",
    ];
    args.extend(common);
    args.push("--allow-foreign-model");
    let (ok, out, err) = rigmon_cmd(&args);
    assert!(ok, "{err}");
    for want in [
        "8 windows from file",
        "0 lost on the sample clock",
        "captures: 8",
        "order resolution: 0.333-0.333 orders",
    ] {
        assert!(
            out.contains(want) || err.contains(want),
            "{want:?} not in {out}{err}"
        );
    }
    assert!(out.contains("res 0.33 ord"), "{out}");
    // Imported to MCAP and read back whole: the same 8 captures, nothing lost.
    let mcap: PathBuf = tmp.path().join("b.mcap");
    let mut args = vec!["import", d, "-o", mcap.to_str().unwrap()];
    args.extend(common);
    let (ok, _, err) = rigmon_cmd(&args);
    assert!(ok, "{err}");
    let (rec, losses) = importers::load_with_losses(&mcap, &femto_rig(), &rpm(1800.0)).unwrap();
    assert!(losses.is_empty(), "{losses:?}");
    assert_eq!(rec.len(), 8 * N);
    let wins = rigmon::analysis::extract_recording(&rec, &femto_rig()).unwrap();
    assert_eq!(wins.len(), 8);
    assert!((wins[7].t_start - 70.0).abs() < 1e-6);
}

#[test]
fn trend_draws_the_rms_and_the_rules_alarm_over_a_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("Bearing1_1");
    femto_folder(&dir, 12, 99);
    let png = tmp.path().join("trend.png");
    let (d, p) = (dir.to_str().unwrap(), png.to_str().unwrap());
    let args = [
        "trend",
        d,
        "--rig",
        "config/femto.toml",
        "--baseline-fraction",
        "0.25",
    ];
    let (ok, out, err) = rigmon_cmd(&[&args[..], &["--png", p, "--json"]].concat());
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    // Levels 1..12 g: a baseline of 3 windows, mean + 3 sd of their RMS crossed for good later.
    assert_eq!(v["windows"], 12);
    assert_eq!(v["rule"]["baseline_windows"], 3);
    let alarm = v["alarm_s"].as_f64().unwrap();
    assert!(alarm > 20.0 && alarm < 110.0, "{v}");
    assert!(
        (v["lead_s"].as_f64().unwrap() - (110.1 - alarm)).abs() < 1e-6,
        "{v}"
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    let (ok, out, _) = rigmon_cmd(&args);
    assert!(ok && out.contains("RMS 3-sigma rule: alarm at"), "{out}");
}
