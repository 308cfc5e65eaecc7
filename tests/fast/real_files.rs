//! Every real recording in `../shared/data` (CWRU drive end and fan end) imports without flags:
//! its sample rate and speed match CWRU's published values, its label is the condition of the
//! rig's monitored bearing, and `rigmon features` runs on it. Then the acceptance: one
//! manifest holding the 48 kHz normal baseline and every 12 kHz fan-end fault record runs
//! through `rigmon evaluate --rig config/cwru-fe.toml` with no other flag (with a small
//! simulation-only model trained here for that rig), also when the rig file names a default
//! rate of 12 kHz.
//!
//! The expected values below are not taken from rigmon's catalogue: rates and loads are CWRU's
//! tables (the Bearing Data Center's pages), sample counts and stored speeds were read from the
//! files with SciPy's `loadmat`.

use rigmon::importers::{self, ImportOptions};
use serde_json::Value;
use std::path::{Path, PathBuf};

use crate::common::rigmon;
use crate::common::{rig, shared_data};

/// CWRU's approximate motor speed per load (hp 0..3), rpm.
const NOMINAL_RPM: [f64; 4] = [1797.0, 1772.0, 1750.0, 1730.0];

/// One real file: path under ../shared/data, record number, sample rate (Hz), motor load (hp),
/// samples, stored speed (rpm), condition of the faulty bearing, which bearing is faulty.
struct Real {
    rel: &'static str,
    record: u32,
    fs: f64,
    load_hp: usize,
    samples: usize,
    rpm: f64,
    fault: &'static str,
    bearing: Option<&'static str>,
}

#[allow(clippy::too_many_arguments)] // one row of the table above, in its column order
const fn real(
    rel: &'static str,
    record: u32,
    fs: f64,
    load_hp: usize,
    samples: usize,
    rpm: f64,
    fault: &'static str,
    bearing: Option<&'static str>,
) -> Real {
    Real {
        rel,
        record,
        fs,
        load_hp,
        samples,
        rpm,
        fault,
        bearing,
    }
}

const DE: Option<&str> = Some("DE");
const FE: Option<&str> = Some("FE");

const REAL: &[Real] = &[
    real(
        "cwru/97_Normal_0.mat",
        97,
        48e3,
        0,
        243_938,
        1796.0,
        "healthy",
        None,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat",
        105,
        12e3,
        0,
        121_265,
        1797.0,
        "inner_race",
        DE,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/IR/021/209_0.mat",
        209,
        12e3,
        0,
        122_136,
        1797.0,
        "inner_race",
        DE,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/OR/007/@6/130@6_0.mat",
        130,
        12e3,
        0,
        121_991,
        1796.0,
        "outer_race",
        DE,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/OR/021/@6/234_0.mat",
        234,
        12e3,
        0,
        122_426,
        1796.0,
        "outer_race",
        DE,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/B/007/118_0.mat",
        118,
        12e3,
        0,
        122_571,
        1796.0,
        "ball",
        DE,
    ),
    real(
        "cwru/12k_Drive_End_Bearing_Fault_Data/B/021/222_0.mat",
        222,
        12e3,
        0,
        121_991,
        1796.0,
        "ball",
        DE,
    ),
    real(
        "cwru-fe/007/B007_0.mat",
        282,
        12e3,
        0,
        121_168,
        1798.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/007/B007_1.mat",
        283,
        12e3,
        1,
        120_801,
        1777.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/007/IR007_0.mat",
        278,
        12e3,
        0,
        121_535,
        1796.0,
        "inner_race",
        FE,
    ),
    // CWRU's file for 0.007 in IR at 1 hp stores 1732 rpm (published so; 1 hp is ~1772 rpm).
    real(
        "cwru-fe/007/IR007_1.mat",
        279,
        12e3,
        1,
        121_351,
        1732.0,
        "inner_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_centered_at_6_0.mat",
        294,
        12e3,
        0,
        121_168,
        1797.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_centered_at_6_1.mat",
        295,
        12e3,
        1,
        121_535,
        1776.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_opposite_at_12_0.mat",
        302,
        12e3,
        0,
        121_168,
        1797.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_opposite_at_12_1.mat",
        305,
        12e3,
        1,
        120_984,
        1775.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_orthogonal_at_3_0.mat",
        298,
        12e3,
        0,
        120_984,
        1797.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/007/OR007_orthogonal_at_3_1.mat",
        299,
        12e3,
        1,
        121_168,
        1776.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/014/B014_0.mat",
        286,
        12e3,
        0,
        122_086,
        1796.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/014/B014_1.mat",
        287,
        12e3,
        1,
        121_719,
        1775.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/014/IR014_0.mat",
        274,
        12e3,
        0,
        121_351,
        1796.0,
        "inner_race",
        FE,
    ),
    real(
        "cwru-fe/014/IR014_1.mat",
        275,
        12e3,
        1,
        121_351,
        1775.0,
        "inner_race",
        FE,
    ),
    real(
        "cwru-fe/014/OR014_centered_at_6_0.mat",
        313,
        12e3,
        0,
        120_984,
        1797.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/014/OR014_orthogonal_at_3_0.mat",
        310,
        12e3,
        0,
        121_535,
        1796.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/014/OR014_orthogonal_at_3_1.mat",
        309,
        12e3,
        1,
        121_168,
        1774.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/021/B021_0.mat",
        290,
        12e3,
        0,
        121_351,
        1796.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/021/B021_1.mat",
        291,
        12e3,
        1,
        121_351,
        1775.0,
        "ball",
        FE,
    ),
    real(
        "cwru-fe/021/IR021_0.mat",
        270,
        12e3,
        0,
        121_168,
        1796.0,
        "inner_race",
        FE,
    ),
    real(
        "cwru-fe/021/IR021_1.mat",
        271,
        12e3,
        1,
        121_168,
        1776.0,
        "inner_race",
        FE,
    ),
    real(
        "cwru-fe/021/OR021_centered_at_6_0.mat",
        315,
        12e3,
        0,
        120_617,
        1797.0,
        "outer_race",
        FE,
    ),
    real(
        "cwru-fe/021/OR021_orthogonal_at_3_1.mat",
        316,
        12e3,
        1,
        120_617,
        1773.0,
        "outer_race",
        FE,
    ),
];

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.mat` under a folder, sorted (relative to `root`).
fn mat_files(root: &Path, dir: &Path, out: &mut Vec<String>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            mat_files(root, &p, out);
        } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("mat")) {
            out.push(p.strip_prefix(root).unwrap().to_string_lossy().into_owned());
        }
    }
}

/// Which rig file watches the faulty bearing of a file's folder.
fn rig_name(rel: &str) -> &'static str {
    if rel.starts_with("cwru-fe/") {
        "cwru-fe.toml"
    } else {
        "cwru-de.toml"
    }
}

/// The label a rig gives: the fault when it is on the bearing the rig watches, else healthy.
fn label_for(r: &Real, watched: &str) -> &'static str {
    match r.bearing {
        Some(b) if b == watched => r.fault,
        _ => "healthy",
    }
}

#[test]
fn every_real_file_imports_with_its_published_rate_and_speed() {
    let data = shared_data();
    let mut found = Vec::new();
    for folder in ["cwru", "cwru-fe"] {
        mat_files(&data, &data.join(folder), &mut found);
    }
    found.sort();
    let mut listed: Vec<String> = REAL.iter().map(|r| r.rel.to_string()).collect();
    listed.sort();
    assert_eq!(
        found, listed,
        "the test's table must list every real file in ../shared/data"
    );
    let rigs = [("DE", rig("cwru-de.toml")), ("FE", rig("cwru-fe.toml"))];
    for r in REAL {
        let path = data.join(r.rel);
        // Both rigs read every file (the same motor): rate, speed and label per rig.
        for (watched, rig) in &rigs {
            let rec = importers::load(&path, rig, &ImportOptions::default())
                .unwrap_or_else(|e| panic!("{} with the {watched} rig: {e:#}", r.rel));
            assert_eq!(rec.sample_rate, r.fs, "{}: CWRU's rate", r.rel);
            assert_eq!(rec.len(), r.samples, "{}", r.rel);
            // The file's stored speed; where the vibration shows it clearly off (279 only),
            // the speed used is the vibration's and the stored one stays in the metadata.
            let stored = rec
                .metadata
                .get(importers::META_STORED_RPM)
                .map(|v| v.parse::<f64>().unwrap());
            assert_eq!(stored.or(rec.rpm), Some(r.rpm), "{}: stored speed", r.rel);
            assert_eq!(stored.is_some(), r.record == 279, "{}", r.rel);
            let used = rec.rpm.unwrap();
            assert!(
                (used - speed_used(r)).abs() <= speed_tolerance(r),
                "{}: speed used {used}",
                r.rel
            );
            assert_eq!(
                rec.metadata["cwru_record"],
                r.record.to_string(),
                "{}",
                r.rel
            );
            assert_eq!(
                rec.metadata["cwru_load_hp"],
                r.load_hp.to_string(),
                "{}",
                r.rel
            );
            assert_eq!(
                rec.label(),
                Some(label_for(r, watched)),
                "{} seen from {watched}",
                r.rel
            );
            let warnings: Vec<&String> = rec
                .provenance
                .notes
                .iter()
                .filter(|n| n.starts_with(importers::WARNING))
                .collect();
            if r.record == 279 {
                assert!(
                    warnings.len() == 1 && warnings[0].contains("stores 1732 rpm"),
                    "{}: {warnings:?}",
                    r.rel
                );
            } else {
                assert!(warnings.is_empty(), "{}: {warnings:?}", r.rel);
            }
            let fe = &rec.channel("FE").unwrap().samples;
            let rms =
                (fe.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / fe.len() as f64).sqrt();
            assert!(rms > 0.01 && rms < 5.0, "{}: FE rms {rms} g", r.rel);
        }
        // The stored speed is the published one for the load (within 6 rpm), except 279,
        // whose vibration turns at the other 1 hp records' speed.
        let nominal = NOMINAL_RPM[r.load_hp];
        if r.record == 279 {
            assert_eq!(r.rpm, 1732.0);
            assert!((speed_used(r) - nominal).abs() <= 6.0);
        } else {
            assert!(
                (r.rpm - nominal).abs() <= 6.0,
                "{}: {} rpm at {} hp",
                r.rel,
                r.rpm,
                r.load_hp
            );
        }
        // Duration: ~10 s at 12 kHz, ~5 s for the 48 kHz baseline.
        let dur = r.samples as f64 / r.fs;
        assert!((5.0..10.3).contains(&dur), "{}: {dur} s", r.rel);
    }
}

/// The speed rigmon uses for a real file: the stored one, but for 279 (stores 1732 rpm; its
/// 1x line, searched within +-5 % of that, is at ~1774 rpm on both the DE and FE channels).
fn speed_used(r: &Real) -> f64 {
    if r.record == 279 {
        1774.0
    } else {
        r.rpm
    }
}

/// How exactly [`speed_used`] is known: the stored speed exactly, the vibration's to 1 rpm.
fn speed_tolerance(r: &Real) -> f64 {
    if r.record == 279 {
        1.0
    } else {
        1e-6 * r.rpm
    }
}

/// `rigmon features` on every real file (the whole file), with the rig of its bearing: one JSON
/// line per window, the stored speed, 100 finite features on the classifier channel.
#[test]
fn rigmon_features_runs_on_every_real_file() {
    let data = shared_data();
    for r in REAL {
        let path = data.join(r.rel);
        let rig_path = repo().join("config").join(rig_name(r.rel));
        let out = rigmon(&[
            "features",
            path.to_str().unwrap(),
            "--rig",
            rig_path.to_str().unwrap(),
            "--json",
        ]);
        let windows: Vec<Value> = out
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        let dur = r.samples as f64 / r.fs;
        let expected = ((dur - 1.0) / 0.5).floor() as usize + 1;
        assert_eq!(windows.len(), expected, "{}: windows", r.rel);
        let classifier = if rig_name(r.rel) == "cwru-fe.toml" {
            "FE"
        } else {
            "DE"
        };
        for w in &windows {
            let rpm = w["rpm"].as_f64().unwrap();
            assert!(
                (rpm - speed_used(r)).abs() <= speed_tolerance(r),
                "{}: rpm {rpm}",
                r.rel
            );
            let f = w["features"][classifier].as_array().unwrap();
            assert_eq!(f.len(), 100, "{}", r.rel);
            assert!(
                f.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)),
                "{}",
                r.rel
            );
        }
    }
}

/// The acceptance: `rigmon evaluate --rig config/cwru-fe.toml` on one manifest holding
/// the 48 kHz normal baseline 97 and every 12 kHz fan-end file, no other flag; the same with a
/// rig file whose `acquisition.sample_rate_hz = 12000` (a default, not a contradiction). The
/// model is a small one trained here on the fan-end rig's simulator only.
#[test]
fn evaluate_one_manifest_mixing_48k_baseline_and_12k_fan_end_faults() {
    let data = shared_data();
    let dir = tempfile::tempdir().unwrap();
    let mut manifest = String::from("path,label\n");
    let mut n = 0;
    for r in REAL
        .iter()
        .filter(|r| r.rel.starts_with("cwru-fe/") || r.record == 97)
    {
        manifest.push_str(&format!(
            "{},{}\n",
            data.join(r.rel).canonicalize().unwrap().display(),
            label_for(r, "FE")
        ));
        n += 1;
    }
    assert_eq!(n, 24);
    let csv = dir.path().join("labels.csv");
    std::fs::write(&csv, &manifest).unwrap();

    // A small simulation-only model for the fan-end rig: 4 classes x 6 recordings x 2 s.
    let rig_fe = repo().join("config/cwru-fe.toml");
    let plan = dir.path().join("plan.toml");
    std::fs::write(
        &plan,
        "name = \"fe-tiny\"\nseed = 5\nseconds = 2.0\n[random]\nrpm = [1720.0, 1800.0]\n\
         noise_rms_m_s2 = [0.1, 0.5]\ndefect_width_mm = [0.18, 0.53]\n\
         [[case]]\nfaults = \"healthy\"\nrecordings = 6\n[[case]]\nfaults = \"outer_race\"\nrecordings = 6\n\
         [[case]]\nfaults = \"inner_race\"\nrecordings = 6\n[[case]]\nfaults = \"ball\"\nrecordings = 6\n",
    )
    .unwrap();
    let sim = dir.path().join("sim");
    let model = dir.path().join("fe.onnx");
    let (rig_s, sim_s, model_s) = (
        rig_fe.to_str().unwrap(),
        sim.to_str().unwrap(),
        model.to_str().unwrap(),
    );
    rigmon(&[
        "dataset",
        "--rig",
        rig_s,
        "--plan",
        plan.to_str().unwrap(),
        "-q",
        "-o",
        sim_s,
    ]);
    rigmon(&[
        "train", "--rig", rig_s, "--data", sim_s, "-o", model_s, "--epochs", "30", "--seed", "1",
        "--ball",
    ]);

    // A copy of the rig file that names 12 kHz as its acquisition rate.
    let rig12 = dir.path().join("cwru-fe-12k.toml");
    std::fs::write(
        &rig12,
        std::fs::read_to_string(&rig_fe).unwrap().replacen(
            "[[channels]]",
            "[acquisition]\nsample_rate_hz = 12000.0\n\n[[channels]]",
            1,
        ),
    )
    .unwrap();
    for rig_file in [rig_fe.clone(), rig12] {
        let text = rigmon(&[
            "evaluate",
            "--model",
            model_s,
            "--rig",
            rig_file.to_str().unwrap(),
            "--manifest",
            csv.to_str().unwrap(),
        ]);
        println!("{text}");
        let v: Value = serde_json::from_str(&rigmon(&[
            "evaluate",
            "--model",
            model_s,
            "--rig",
            rig_file.to_str().unwrap(),
            "--manifest",
            csv.to_str().unwrap(),
            "--json",
        ]))
        .unwrap();
        assert_eq!(v["n_records"], 24, "every record is scored: {v}");
        let recs = v["records"].as_array().unwrap();
        let r97 = recs
            .iter()
            .find(|r| r["path"].as_str().unwrap().ends_with("97_Normal_0.mat"))
            .unwrap();
        assert_eq!(r97["label"], "healthy");
        // 5.08 s at 48 kHz -> 9 windows (read at 12 kHz it would be 20 s and 39 windows).
        assert_eq!(r97["windows"], 9, "{r97}");
        for key in ["record_accuracy", "balanced_accuracy", "window_accuracy"] {
            let x = v[key].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&x), "{key} = {x}");
        }
    }
}

/// A manifest's `sample_rate_hz` column gives the rate of a file that carries none (a CSV
/// without a time column, a rig file without a rate); the same column against a WAV header
/// that says otherwise is an error naming both numbers and the manifest line.
#[test]
fn manifest_sample_rate_column_reaches_the_importers() {
    let dir = tempfile::tempdir().unwrap();
    let de = rig("cwru-de.toml");
    let mut csv = String::from("DE,FE\n");
    for i in 0..2400 {
        let t = i as f64 / 12_000.0;
        csv.push_str(&format!(
            "{:.5},{:.5}\n",
            (t * 900.0).sin(),
            (t * 400.0).cos()
        ));
    }
    std::fs::write(dir.path().join("plain.csv"), csv).unwrap();
    let spec = hound::WavSpec {
        channels: 3,
        sample_rate: 48_000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(dir.path().join("w.wav"), spec).unwrap();
    for i in 0..4800 {
        for k in 0..3 {
            w.write_sample(((i * (k + 1)) as f32 * 0.01).sin()).unwrap();
        }
    }
    w.finalize().unwrap();
    let labels = dir.path().join("labels.csv");
    std::fs::write(
        &labels,
        "path,label,sample_rate_hz\nplain.csv,healthy,12000\nw.wav,healthy,\nw.wav,healthy,12000\n",
    )
    .unwrap();
    let entries = rigmon::manifest::read_manifest(&labels).unwrap();
    let load = |k: usize| importers::load(&entries[k].path, &de, &entries[k].import_options());
    let r = load(0).unwrap();
    assert_eq!((r.sample_rate, r.len()), (12_000.0, 2400));
    assert!(r
        .provenance
        .notes
        .iter()
        .any(|n| n.contains("labels.csv line 2")));
    assert_eq!(load(1).unwrap().sample_rate, 48_000.0);
    let e = format!("{:#}", load(2).unwrap_err());
    for part in [
        "w.wav",
        "sample-rate mismatch",
        "WAV header",
        "48000",
        "12000",
        "labels.csv line 4",
    ] {
        assert!(e.contains(part), "{part:?} missing in: {e}");
    }
    // Without the column the CSV has no rate at all: the error says what to do.
    let e = format!(
        "{:#}",
        importers::load(&entries[0].path, &de, &ImportOptions::default()).unwrap_err()
    );
    assert!(e.contains("--sample-rate"), "{e}");
}

/// The spans a manifest names, cut sample for sample. 97 is recorded at 48 kHz and the
/// shipped rig simulates at 12 kHz, so calibration analyses it resampled; the cut itself is
/// checked on the same rig simulating at 48 kHz (nothing resampled), the resampled spans
/// after it ([`calibration_analyses_at_the_simulation_rate`]).
#[test]
fn calibration_reads_only_the_span_a_manifest_row_names() {
    let dir = tempfile::tempdir().unwrap();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cwru-de.toml"))
            .unwrap();
    assert!(text.contains("\nsample_rate_hz = 12000.0\n"));
    let de = rigmon::config::RigConfig::parse(&text.replace(
        "\nsample_rate_hz = 12000.0\n",
        "\nsample_rate_hz = 48000.0\n",
    ))
    .unwrap();
    let (labels, file) = three_spans_of_97(dir.path());
    let p = file.display();
    let load = |max_s: f64| {
        rigmon::calibrate::measured::load(&de, std::slice::from_ref(&labels), max_s).unwrap()
    };
    let m = load(f64::INFINITY);
    let fs = m[0].recording.sample_rate;
    let whole = m[0].recording.len();
    let at = (2.5 * fs) as usize;
    let lens: Vec<usize> = m.iter().map(|r| r.recording.len()).collect();
    assert_eq!(lens, vec![whole, at, whole - at], "fs {fs}");
    // The first half's samples are the whole file's first samples, the second half's start at 2.5 s.
    let ch = |k: usize| &m[k].recording.channels[0].samples;
    assert_eq!(ch(1)[..], ch(0)[..at]);
    assert_eq!(ch(2)[..100], ch(0)[at..at + 100]);
    // --seconds still caps each part.
    let one = load(1.0);
    let lens: Vec<usize> = one.iter().map(|r| r.recording.len()).collect();
    assert_eq!(lens, vec![fs as usize; 3]);
    // A span past the end of the file is an error that names the file and the fix.
    std::fs::write(
        &labels,
        format!("path,label,start_s,end_s\n{p},healthy,60,\n"),
    )
    .unwrap();
    let e = format!(
        "{:#}",
        rigmon::calibrate::measured::load(&de, std::slice::from_ref(&labels), f64::INFINITY)
            .unwrap_err()
    );
    assert!(
        e.contains("97_Normal_0.mat") && e.contains("widen the span"),
        "{e}"
    );
}

/// A manifest naming 97 three times: whole, 0-2.5 s and from 2.5 s. Returns it and 97's path.
fn three_spans_of_97(dir: &Path) -> (PathBuf, PathBuf) {
    let file = shared_data().join("cwru/97_Normal_0.mat");
    let labels = dir.join("labels.csv");
    let p = file.display();
    std::fs::write(
        &labels,
        format!("path,label,start_s,end_s\n{p},healthy,,\n{p},healthy,0,2.5\n{p},healthy,2.5,\n"),
    )
    .unwrap();
    (labels, file)
}

/// With the shipped 12 kHz rig the same spans of the 48 kHz record are analysed at 12 kHz:
/// the whole length the span names, a quarter of its samples (the rate is the ratio used,
/// never above 12 kHz), the recorded rate kept for the report, the speed unchanged.
#[test]
fn calibration_analyses_at_the_simulation_rate() {
    let dir = tempfile::tempdir().unwrap();
    let de = rig("cwru-de.toml");
    let (labels, _) = three_spans_of_97(dir.path());
    let m = rigmon::calibrate::measured::load(&de, std::slice::from_ref(&labels), f64::INFINITY)
        .unwrap();
    // 243,938 samples at 48 kHz: all, the first 120,000, the rest
    let recorded = [243_938usize, 120_000, 123_938];
    for (r, n) in m.iter().zip(recorded) {
        assert_eq!(r.recorded_sample_rate, 48_000.0);
        assert_eq!(r.recording.len(), n / 4, "{}", r.name);
        let fs = r.recording.sample_rate;
        assert_eq!(fs, 48_000.0 * (n / 4) as f64 / n as f64);
        // less than one sample per stretch below 12 kHz
        assert!(
            fs <= 12_000.0 && fs > 12_000.0 * (1.0 - 4.0 / n as f64),
            "{fs}"
        );
        assert!((r.recording.duration_s() - n as f64 / 48_000.0).abs() < 1e-9);
        assert!((r.rpm - 1796.0).abs() < 1e-9, "{}", r.rpm);
    }
}
