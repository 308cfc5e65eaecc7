//! Training and serving compute the same features: for every speed source (tacho, edges,
//! fixed, recording, estimate), one recording gives bit-identical feature vectors through
//! `rigmon features --json` (the batch path training uses) and through the daemon's pipeline
//! (`rigmon replay --record`, then the `/features` channel of the recorded MCAP). Both run
//! the built binary on a synthetic lut-rig recording written as rigmon MCAP. The served path
//! also shows that no window waited for signal past its end: the replay's 100 ms blocks end
//! on the 0.5 s window ends, so the daemon's largest `after_end_ms` must be 0 for every
//! speed source (a lookahead of even one sample would show). Last, what not waiting costs: a
//! tacho's speed extrapolated past the window's last edge, against the speed from every edge.

use rigmon::dsp::synthetic::Synthetic;
use rigmon::dsp::FeatureWindow;
use rigmon::recording::{Channel, Provenance, Recording, Tacho};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// How the recording carries its tacho.
#[derive(Clone, Copy)]
enum TachoForm {
    Analog,
    Edges,
    /// None.
    None,
}

/// A lut-rig recording: the synthetic bearing signal (plus `shaft` times its first five
/// shaft harmonics, so the speed can be estimated) on "vertical", noise on the other axes.
fn recording(syn: &Synthetic, shaft: f64, tacho: TachoForm, rpm: Option<f64>) -> Recording {
    let run = syn.generate();
    let fs = syn.sample_rate;
    let vertical: Vec<f32> = run
        .vibration
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let theta = syn.angle(i as f64 / fs);
            let h: f64 = (1..=5)
                .map(|k| (2.0 * std::f64::consts::PI * k as f64 * theta + k as f64).sin())
                .sum();
            v + (shaft * h) as f32
        })
        .collect();
    let noise = |k: usize| -> Vec<f32> {
        (0..run.vibration.len())
            .map(|i| 0.01 * (((i * 7919 + k * 104729) % 1000) as f32 / 500.0 - 1.0))
            .collect()
    };
    let ch = |name: &str, samples: Vec<f32>| Channel {
        name: name.into(),
        axis: name.into(),
        unit: "m/s^2".into(),
        samples,
    };
    let tacho = match tacho {
        TachoForm::Edges => Some(Tacho::Edges {
            times_s: rigmon::dsp::tacho::detect_edges(&run.tacho, fs, 2.5, 0.5),
        }),
        TachoForm::Analog => Some(Tacho::Analog {
            samples: run.tacho.clone(),
            unit: "V".into(),
        }),
        TachoForm::None => None,
    };
    Recording {
        sample_rate: fs,
        start_time_ns: 0,
        channels: vec![
            ch("axial", noise(1)),
            ch("vertical", vertical),
            ch("horizontal", noise(2)),
        ],
        tacho,
        rpm,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: "synthetic".into(),
            format: "simulated".into(),
            notes: vec![],
        },
        metadata: BTreeMap::new(),
    }
}

/// config/lut-rig.toml with its `[speed]` section replaced.
fn rig_file(dir: &Path, speed: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("config/lut-rig.toml")).unwrap();
    let a = text
        .find("\n[speed]")
        .expect("lut-rig.toml has a [speed] section");
    let b = a + 1 + text[a + 1..].find("\n[").unwrap();
    let rig = format!("{}\n[speed]\n{speed}\n{}", &text[..a], &text[b..]);
    let p = dir.join("rig.toml");
    std::fs::write(&p, rig).unwrap();
    p
}

fn run(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .current_dir(repo())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rigmon {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Batch: `rigmon features --json`.
fn batch(rec: &Path, rig: &Path) -> Vec<FeatureWindow> {
    let out = run(&[
        "features".as_ref(),
        rec.as_os_str(),
        "--rig".as_ref(),
        rig.as_os_str(),
        "--json".as_ref(),
    ]);
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Serving: `rigmon replay --record`, then the recorded `/features` messages in log order,
/// and the run's summary (`--summary-json`).
fn served(rec: &Path, rig: &Path, dir: &Path) -> (Vec<FeatureWindow>, serde_json::Value) {
    let rec_dir = dir.join("served");
    let out = run(&[
        "replay".as_ref(),
        rec.as_os_str(),
        "--rig".as_ref(),
        rig.as_os_str(),
        "--model".as_ref(),
        repo().join("models/lut-rig.onnx").as_os_str(),
        "--quiet".as_ref(),
        "--summary-json".as_ref(),
        "--record".as_ref(),
        rec_dir.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let summary = stderr
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .expect("rigmon replay --summary-json prints the summary on stderr");
    let mut msgs = Vec::new();
    for f in std::fs::read_dir(&rec_dir).unwrap() {
        let f = f.unwrap().path();
        if f.extension().is_none_or(|x| x != "mcap") {
            continue;
        }
        let bytes = std::fs::read(&f).unwrap();
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            if m.channel.topic == "/features" {
                let w: FeatureWindow = serde_json::from_slice(&m.data).unwrap();
                msgs.push((m.log_time, w));
            }
        }
    }
    msgs.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.t_start.total_cmp(&b.1.t_start)));
    (msgs.into_iter().map(|(_, w)| w).collect(), summary)
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Both paths, every window, every channel, every bin: the same f32 bits.
fn assert_identical(name: &str, speed: &str, rec: &Recording, want_source: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("rec.mcap");
    rigmon::recording::mcap::write_recording(&path, rec).unwrap();
    let rig = rig_file(tmp.path(), speed);
    let a = batch(&path, &rig);
    let (b, summary) = served(&path, &rig, tmp.path());
    let expected = ((rec.duration_s() - 1.0) / 0.5).floor() as usize + 1;
    assert_eq!(a.len(), expected, "{name}: batch windows");
    assert_eq!(b.len(), a.len(), "{name}: served windows vs batch windows");
    assert_eq!(summary["windows"], expected, "{name}: {summary}");
    assert_eq!(
        summary["after_end_ms_max"], 0.0,
        "{name}: a window waited for signal past its end: {summary}"
    );
    for (x, y) in a.iter().zip(&b) {
        let at = format!("{name}: window at {} s", x.t_start);
        assert_eq!(x.t_start.to_bits(), y.t_start.to_bits(), "{at}");
        assert_eq!(x.t_end.to_bits(), y.t_end.to_bits(), "{at}");
        assert_eq!(
            x.rpm.to_bits(),
            y.rpm.to_bits(),
            "{at}: rpm {} vs {}",
            x.rpm,
            y.rpm
        );
        assert_eq!(x.speed_source.as_str(), want_source, "{at}");
        assert_eq!(y.speed_source, x.speed_source, "{at}");
        assert_eq!(x.quality, y.quality, "{at}");
        assert_eq!(
            x.features.keys().collect::<Vec<_>>(),
            ["axial", "horizontal", "vertical"],
            "{at}"
        );
        assert_eq!(
            x.features.keys().collect::<Vec<_>>(),
            y.features.keys().collect::<Vec<_>>(),
            "{at}"
        );
        for (ch, f) in &x.features {
            assert_eq!(f.len(), 100, "{at}: {ch}");
            assert!(f.iter().any(|v| *v > 0.0), "{at}: {ch} all zero");
            assert_eq!(bits(f), bits(&y.features[ch]), "{at}: channel {ch}");
        }
    }
}

#[test]
fn tacho_features_are_bit_identical_in_training_and_serving() {
    let syn = Synthetic {
        missing_pulses: vec![20, 55],
        extra_pulses: vec![3.0311],
        ..Synthetic::default()
    };
    let rec = recording(&syn, 0.0, TachoForm::Analog, None);
    let speed = "source = \"tacho\"\nchannel = \"tacho\"\npulses_per_rev = 1\nthreshold = 2.5\nhysteresis = 0.5\n";
    assert_identical("tacho", speed, &rec, "tacho");
}

#[test]
fn edges_features_are_bit_identical_in_training_and_serving() {
    let rec = recording(&Synthetic::default(), 0.0, TachoForm::Edges, None);
    assert_identical(
        "edges",
        "source = \"edges\"\npulses_per_rev = 1\n",
        &rec,
        "edges",
    );
}

#[test]
fn fixed_features_are_bit_identical_in_training_and_serving() {
    let rec = recording(&Synthetic::default(), 0.0, TachoForm::None, None);
    assert_identical("fixed", "source = \"fixed\"\nrpm = 600.0\n", &rec, "fixed");
    // The recorder keeps the analog tacho the source delivers though `[speed]` ignores it.
    let rec = recording(&Synthetic::default(), 0.0, TachoForm::Analog, None);
    let speed = "source = \"fixed\"\nrpm = 600.0\n";
    assert_identical("fixed-analog", speed, &rec, "fixed");
}

#[test]
fn recording_features_are_bit_identical_in_training_and_serving() {
    // The stored rpm, and without one the fallback to the recorded tacho edges.
    let rec = recording(&Synthetic::default(), 0.0, TachoForm::Edges, Some(600.0));
    assert_identical("recording", "source = \"recording\"\n", &rec, "recording");
    let rec = recording(&Synthetic::default(), 0.0, TachoForm::Edges, None);
    assert_identical("recording-edges", "source = \"recording\"\n", &rec, "edges");
}

#[test]
fn estimate_features_are_bit_identical_in_training_and_serving() {
    // 1 s windows resolve the 1x line down to 1200 rpm; the shaft turns at 1500 rpm.
    let syn = Synthetic {
        f_start: 25.0,
        f_end: 25.0,
        seconds: 6.0,
        ..Synthetic::default()
    };
    // With an analog tacho in the recording, which the recorder keeps.
    let rec = recording(&syn, 0.5, TachoForm::Analog, None);
    assert_identical(
        "estimate",
        "source = \"estimate\"\nmin_rpm = 1200.0\nmax_rpm = 3000.0\n",
        &rec,
        "estimate",
    );
}

/// Relative L2 difference of two feature vectors.
fn rel_diff(a: &[f32], b: &[f32]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    let n: f64 = b.iter().map(|y| (*y as f64).powi(2)).sum();
    (d / n).sqrt()
}

/// (mean, max) relative difference of the classifier channel's features, window by window,
/// between the served windows (`extract_recording`: the tacho speed extrapolated past the
/// last edge inside each window) and the same windows along `track`, with the number of
/// windows whose predicted class differs.
fn extrapolation_cost(
    rec: &Recording,
    rig: &rigmon::config::RigConfig,
    track: &rigmon::dsp::SpeedTrack,
    model: &rigmon::model::onnx::OnnxClassifier,
) -> (f64, f64, usize, usize) {
    let served = rigmon::analysis::extract_recording(rec, rig).unwrap();
    let along = rigmon::analysis::extract_with_speed(rec, rig, track).unwrap();
    assert_eq!(served.len(), along.len());
    let ch = &rig.features.classifier_axis;
    let d: Vec<f64> = served
        .iter()
        .zip(&along)
        .map(|(a, b)| rel_diff(&a.features[ch], &b.features[ch]))
        .collect();
    let class = |w: &FeatureWindow| model.predict(&w.features[ch]).unwrap().class;
    let flips = served
        .iter()
        .zip(&along)
        .filter(|(a, b)| class(a) != class(b))
        .count();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    (mean, d.iter().copied().fold(0.0, f64::max), flips, d.len())
}

/// No window waits for the tacho edge after its end: its speed is extrapolated past the last
/// edge inside it. Against the speed from every edge of the recording (interpolated there),
/// that costs next to nothing at the rig's constant speeds (the six shipped replays: no
/// window's class changes) and little on an 8 -> 12 Hz run-up (the synthetic default, with
/// three missing pulses and a spurious one, whose repair costs more than the extrapolation).
#[test]
fn extrapolating_the_tacho_past_the_window_end_costs_little() {
    let rig = rigmon::config::RigConfig::load(&repo().join("config/lut-rig.toml")).unwrap();
    let model =
        rigmon::model::onnx::OnnxClassifier::load(&repo().join("models/lut-rig.onnx")).unwrap();
    for f in ["healthy", "outer_race", "inner_race"] {
        for rpm in [588, 1188] {
            let path = repo().join(format!("replay/lut-{f}-{rpm}rpm.mcap"));
            let rec = rigmon::recording::mcap::read_recording(&path).unwrap();
            let track = rigmon::analysis::whole_recording(&rec, &rig).unwrap();
            let (mean, max, flips, n) = extrapolation_cost(&rec, &rig, &track, &model);
            println!(
                "FIGURE extrapolated tacho vs all edges, {f} {rpm} rpm: mean {mean:.1e}, max {max:.1e} relative difference, {flips}/{n} classes changed"
            );
            assert!(max < 1e-3, "{f} {rpm} rpm: max {max}");
            assert_eq!(flips, 0, "{f} {rpm} rpm");
        }
    }
    for (name, syn) in [
        ("run-up 8 -> 12 Hz", Synthetic::default()),
        (
            "run-up 8 -> 12 Hz, 3 missing + 1 spurious pulse",
            Synthetic {
                missing_pulses: vec![20, 55, 77],
                extra_pulses: vec![3.0311],
                ..Synthetic::default()
            },
        ),
    ] {
        let rec = recording(&syn, 0.0, TachoForm::Analog, None);
        let truth = rigmon::dsp::SpeedTrack::from_edges(
            &syn.generate().edges,
            1,
            rigmon::vocabulary::SpeedSourceKind::Tacho,
        )
        .unwrap();
        let (mean, max, flips, n) = extrapolation_cost(&rec, &rig, &truth, &model);
        println!(
            "FIGURE extrapolated tacho vs the true shaft angle, {name}: mean {mean:.1e}, max {max:.1e} relative difference, {flips}/{n} classes changed"
        );
        assert!(mean < 5e-3 && max < 0.05, "{name}: mean {mean}, max {max}");
    }
}
