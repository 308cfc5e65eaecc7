//! Simulator tests: fault signatures at the theoretical orders (with the model's own contact
//! angle), IR load-zone sidebands, clean healthy spectra, the first bending modes (Table 3),
//! determinism, a long bounded run, and the WAV / dataset outputs.

use rigmon::config::RigConfig;
use rigmon::recording::{Recording, Tacho};
use rigmon::sim::{self, signature::envelope_spectrum, Scenario};
use rigmon::vocabulary::Condition;
use std::path::Path;

fn rig(name: &str) -> RigConfig {
    RigConfig::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config")
            .join(name),
    )
    .unwrap()
}

/// The one recording `plan` makes for `rig`, written as MCAP and read back, with the
/// calibrated effects' draws fixed and spread.
pub fn planned_recordings(
    rig: &RigConfig,
    plan: &sim::plan::Plan,
) -> Vec<(sim::dataset::CalibratedDraws, Recording)> {
    use sim::dataset::{generate, CalibratedDraws};
    [CalibratedDraws::Fixed, CalibratedDraws::Spread]
        .into_iter()
        .map(|mode| {
            let dir = tempfile::tempdir().unwrap();
            generate(rig, plan, dir.path(), "mcap", Some(1), false, mode).unwrap();
            let path = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().path())
                .find(|p| p.extension().is_some_and(|x| x == "mcap"))
                .unwrap();
            (
                mode,
                rigmon::recording::mcap::read_recording(&path).unwrap(),
            )
        })
        .collect()
}

fn vertical(rec: &Recording) -> &[f32] {
    &rec.channel("vertical").expect("vertical channel").samples
}

/// Envelope spectrum of the classifier channel, thesis recipe (low-pass 4 kHz).
fn env_spec(rec: &Recording, ch: &str) -> sim::signature::EnvelopeSpectrum {
    envelope_spectrum(
        &rec.channel(ch).unwrap().samples,
        rec.sample_rate,
        0.0,
        4000.0,
        4,
    )
}

#[test]
fn first_bending_modes_match_table3() {
    let r = rig("lut-rig.toml");
    let ([v, h], all) = sim::bending_modes(&r, r.simulation.as_ref().unwrap()).unwrap();
    assert!(
        (v / 31.25 - 1.0).abs() < 0.10,
        "vertical {v} Hz, all {all:?}"
    );
    assert!(
        (h / 33.75 - 1.0).abs() < 0.10,
        "horizontal {h} Hz, all {all:?}"
    );
    assert!(
        v < h,
        "vertical {v} should be below lateral {h} like the rig"
    );
}

fn check_fault_line(fault: Condition, fr: f64, seconds: f64) {
    let r = rig("lut-rig.toml");
    let rec = sim::simulate(&r, &Scenario::constant(&[fault], fr * 60.0, seconds, 11)).unwrap();
    let orders = sim::model_fault_orders(&r, r.simulation.as_ref().unwrap());
    let f0 = match fault {
        Condition::OuterRace => orders.bpfo,
        Condition::InnerRace => orders.bpfi,
        Condition::Ball => orders.two_bsf,
        Condition::Healthy => unreachable!("a fault line of a healthy bearing"),
    } * fr;
    let s = env_spec(&rec, "vertical");
    let (f, a) = s.peak_near(f0, 0.03);
    let floor = s.median(0.5 * fr, 50.0 * fr);
    eprintln!("{fault:?} at {fr} Hz: theory {f0:.3} Hz, peak {f:.3} Hz ({:+.3} %), amplitude {a:.4} / floor {floor:.4}", (f / f0 - 1.0) * 100.0);
    assert!(
        (f / f0 - 1.0).abs() < 0.005,
        "{fault:?} at {fr} Hz: peak {f} Hz vs theory {f0} Hz"
    );
    assert!(
        a > 8.0 * floor,
        "{fault:?} at {fr} Hz: line {a} not clearly above the floor {floor}"
    );
}

#[test]
fn outer_race_line_at_bpfo() {
    check_fault_line(Condition::OuterRace, 9.8, 6.0);
    check_fault_line(Condition::OuterRace, 19.8, 4.0);
}

#[test]
fn inner_race_line_at_bpfi_with_sidebands() {
    check_fault_line(Condition::InnerRace, 9.8, 6.0);
    check_fault_line(Condition::InnerRace, 19.8, 4.0);
    // load-zone modulation: BPFI +- 1x
    let r = rig("lut-rig.toml");
    let fr = 19.8;
    let rec = sim::simulate(
        &r,
        &Scenario::constant(&[Condition::InnerRace], fr * 60.0, 4.0, 5),
    )
    .unwrap();
    let bpfi = sim::model_fault_orders(&r, r.simulation.as_ref().unwrap()).bpfi * fr;
    let s = env_spec(&rec, "vertical");
    let floor = s.median(0.5 * fr, 50.0 * fr);
    for f in [bpfi - fr, bpfi + fr] {
        let (fp, a) = s.peak_near(f, 0.01);
        eprintln!("sideband {f:.2} Hz: peak {fp:.2} Hz amplitude {a:.4} / floor {floor:.4}");
        assert!(
            (fp - f).abs() < 0.01 * f,
            "sideband at {fp} Hz, expected {f}"
        );
        assert!(a > 4.0 * floor, "sideband at {f} Hz: {a} vs floor {floor}");
    }
}

#[test]
fn contact_angle_moves_the_lines() {
    // thesis MBD: alpha ~28.9 deg raises BPFO by ~2.4 %; the model follows its own angle
    let r = rig("lut-rig.toml");
    let fr = 19.8;
    let mut sc = Scenario::constant(&[Condition::OuterRace], fr * 60.0, 4.0, 3);
    sc.overrides.contact_angle_deg = Some(28.87);
    sc.overrides.radial_clearance_mm = Some(0.0);
    let rec = sim::simulate(&r, &sc).unwrap();
    let cfg = sc.overrides.apply(r.simulation.as_ref().unwrap());
    let f0 = sim::model_fault_orders(&r, &cfg).bpfo * fr;
    let f_zero = r.bearing.with_contact_angle(0.0).fault_orders().bpfo * fr;
    let (f, _) = env_spec(&rec, "vertical").peak_near(f0, 0.02);
    assert!((f / f0 - 1.0).abs() < 0.005, "peak {f} vs {f0}");
    assert!(
        (f / f_zero - 1.0) > 0.015,
        "the contact angle must raise BPFO ({f} vs {f_zero})"
    );
}

#[test]
fn healthy_has_no_fault_lines() {
    let r = rig("lut-rig.toml");
    let o = sim::model_fault_orders(&r, r.simulation.as_ref().unwrap());
    for fr in [9.8, 19.8] {
        let rec = sim::simulate(&r, &Scenario::constant(&[], fr * 60.0, 4.0, 21)).unwrap();
        let s = env_spec(&rec, "vertical");
        let floor = s.median(0.5 * fr, 50.0 * fr);
        for (name, ord) in [("BPFO", o.bpfo), ("BPFI", o.bpfi), ("2xBSF", o.two_bsf)] {
            let (_, a) = s.peak_near(ord * fr, 0.01);
            eprintln!("healthy {fr} Hz {name}: {a:.5} vs floor {floor:.5}");
            assert!(
                a < 4.0 * floor,
                "healthy at {fr} Hz shows {name}: {a} vs floor {floor}"
            );
        }
    }
}

#[test]
fn same_seed_same_output_and_bounded_long_run() {
    let r = rig("lut-rig.toml");
    let sc = Scenario::constant(
        &[Condition::InnerRace, Condition::OuterRace],
        900.0,
        0.5,
        77,
    );
    let a = sim::simulate(&r, &sc).unwrap();
    let b = sim::simulate(&r, &sc).unwrap();
    assert_eq!(a, b);
    let mut other = sc.clone();
    other.seed = 78;
    assert_ne!(vertical(&a), vertical(&sim::simulate(&r, &other).unwrap()));
    assert_eq!(a.label(), Some("inner_race"));
    assert_eq!(a.metadata["faults"], "inner_race,outer_race");

    // 60 s at 19.8 Hz stays bounded and stationary
    let long = sim::simulate(
        &r,
        &Scenario::constant(&[Condition::InnerRace], 1188.0, 60.0, 9),
    )
    .unwrap();
    let v = vertical(&long);
    assert!(
        v.iter().all(|x| x.is_finite() && x.abs() < 1e3),
        "unbounded samples"
    );
    let rms =
        |s: &[f32]| (s.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / s.len() as f64).sqrt();
    let (first, last) = (rms(&v[..50_000]), rms(&v[v.len() - 50_000..]));
    assert!(
        last < 1.5 * first && last > first / 1.5,
        "rms drifted from {first} to {last}"
    );
}

#[test]
fn tacho_and_wav_layout() {
    let r = rig("lut-rig.toml");
    let rec = sim::simulate(
        &r,
        &Scenario::constant(&[Condition::OuterRace], 1188.0, 1.0, 1),
    )
    .unwrap();
    let Some(Tacho::Analog { samples, unit }) = &rec.tacho else {
        panic!("no analog tacho")
    };
    assert_eq!(unit, "V");
    let rising = samples
        .windows(2)
        .filter(|w| w[0] < 2.5 && w[1] >= 2.5)
        .count();
    assert!(
        (19..=20).contains(&rising),
        "{rising} pulses in 1 s at 19.8 Hz"
    );
    assert!(samples.iter().all(|&v| (-0.2..=5.2).contains(&v)));
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("or.wav");
    sim::output::write(&p, &rec, &r).unwrap();
    let mut wr = hound::WavReader::open(&p).unwrap();
    let spec = wr.spec();
    assert_eq!(
        (spec.channels, spec.sample_rate, spec.bits_per_sample),
        (4, 10_000, 32)
    );
    assert_eq!(spec.sample_format, hound::SampleFormat::Float);
    let all: Vec<f32> = wr.samples::<f32>().map(|s| s.unwrap()).collect();
    assert_eq!(all.len(), 4 * rec.len());
    assert_eq!(
        all[4 * 100 + 1],
        rec.channel("vertical").unwrap().samples[100]
    );
    assert_eq!(all[4 * 100 + 3], samples[100]);
}

#[test]
fn cwru_rig_simulates_in_g_at_12khz() {
    let r = rig("cwru-de.toml");
    let fr = 1797.0 / 60.0;
    let rec = sim::simulate(
        &r,
        &Scenario::constant(&[Condition::InnerRace], 1797.0, 2.0, 4),
    )
    .unwrap();
    assert_eq!(rec.sample_rate, 12_000.0);
    // No tacho channel on the rig: the simulator still writes its own revolution times
    // (training data in estimate mode takes its speed from them).
    match &rec.tacho {
        Some(rigmon::recording::Tacho::Edges { times_s }) => {
            assert!(times_s.len() >= 58, "{} revolutions in 2 s", times_s.len());
            for w in times_s.windows(2) {
                assert!(((w[1] - w[0]) * fr - 1.0).abs() < 1e-3, "{w:?}");
            }
        }
        other => panic!("expected the simulator's revolution times, got {other:?}"),
    }
    assert_eq!(rec.rpm, Some(1797.0));
    let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["DE", "FE"]);
    assert_eq!(rec.channels[0].unit, "g");
    let s = env_spec(&rec, "DE");
    let (f, _) = s.peak_near(5.4152 * fr, 0.03);
    assert!(
        (f / (5.4152 * fr) - 1.0).abs() < 0.005,
        "CWRU BPFI peak {f}"
    );
}

/// The product's own feature pipeline (tacho -> order tracking -> envelope order spectrum ->
/// 0.5-order RMS bins) sees the simulated faults in the right bins and the right speed.
#[test]
fn dsp_features_see_the_fault_orders() {
    let r = rig("lut-rig.toml");
    let o = sim::model_fault_orders(&r, r.simulation.as_ref().unwrap());
    let bw = r.features.bin_width_order;
    let bin = |order: f64| ((order / bw).ceil() as usize).saturating_sub(1);
    for fr in [9.8, 19.8] {
        let mut ratio = std::collections::BTreeMap::new();
        for (faults, order) in [
            (vec![], o.bpfo),
            (vec![Condition::OuterRace], o.bpfo),
            (vec![Condition::InnerRace], o.bpfi),
        ] {
            let rec = sim::simulate(&r, &Scenario::constant(&faults, fr * 60.0, 3.0, 8)).unwrap();
            let wins = rigmon::analysis::extract_recording(&rec, &r).unwrap();
            assert!(wins.len() >= 3, "{} windows", wins.len());
            for w in &wins {
                assert!(
                    (w.rpm / (fr * 60.0) - 1.0).abs() < 0.005,
                    "tacho speed {} rpm vs {}",
                    w.rpm,
                    fr * 60.0
                );
            }
            let f = wins[1].classifier_features(&r);
            let mut sorted = f.to_vec();
            sorted.sort_by(f32::total_cmp);
            let med = sorted[sorted.len() / 2] as f64;
            let k = bin(order);
            ratio.insert(format!("{faults:?}"), f[k] as f64 / med);
        }
        eprintln!("{fr} Hz: fault-bin / median-bin ratios {ratio:?}");
        assert!(ratio["[OuterRace]"] > 5.0, "OR bin at {fr} Hz: {ratio:?}");
        assert!(ratio["[InnerRace]"] > 3.5, "IR bin at {fr} Hz: {ratio:?}");
        assert!(ratio["[]"] < 2.5, "healthy BPFO bin at {fr} Hz: {ratio:?}");
    }
}

/// `rigmon dataset`'s engine: MCAP files + labels.csv, labels and plan parameters in the
/// MCAP metadata, read back by the importers' reader.
#[test]
fn dataset_writes_mcap_and_labels() {
    let r = rig("lut-rig.toml");
    let plan = sim::plan::Plan::parse(
        r#"
name = "tiny"
seed = 5
seconds = 0.5
[random]
defect_width_mm = [0.3, 0.6]
[[case]]
faults = "outer_race"
rpm = 1188
recordings = 2
[[case]]
faults = "healthy"
rpm = 588
recordings = 1
[[case]]
faults = "inner_race,ball"
recordings = 1
profile = { kind = "ramp", from_rpm = 600.0, to_rpm = 900.0, seconds = 0.5 }
"#,
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = sim::dataset::generate(
        &r,
        &plan,
        dir.path(),
        "mcap",
        Some(2),
        false,
        Default::default(),
    )
    .unwrap();
    assert_eq!(s.recordings, 4);
    let csv = std::fs::read_to_string(dir.path().join("labels.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "path,label");
    assert_eq!(lines.len(), 5, "{csv}");
    for line in &lines[1..] {
        let (path, label) = line.split_once(',').unwrap();
        let rec = rigmon::recording::mcap::read_recording(&dir.path().join(path)).unwrap();
        assert_eq!(rec.label(), Some(label), "{path}");
        assert_eq!(rec.metadata["plan"], "tiny");
        assert_eq!(rec.len(), 5000);
        if label == "outer_race" {
            let w: f64 = rec.metadata["defect_width_mm"].parse().unwrap();
            assert!((0.3..=0.6).contains(&w), "{w}");
        }
        if label == "inner_race" {
            assert_eq!(rec.metadata["faults"], "inner_race,ball");
            assert!(rec.metadata["speed_profile"].starts_with("ramp"));
        }
    }
}

/// Switchable effects for calibration: electrical line interference is frequency-locked (not
/// order-locked) and off by default; slip shifts the lines down.
#[test]
fn line_interference_and_slip_are_switchable() {
    let r = rig("lut-rig.toml");
    let amp_at = |x: &[f32], fs: f64, f: f64| {
        let (mut re, mut im) = (0.0f64, 0.0f64);
        for (i, &v) in x.iter().enumerate() {
            let p = std::f64::consts::TAU * f * i as f64 / fs;
            re += v as f64 * p.cos();
            im += v as f64 * p.sin();
        }
        2.0 * (re * re + im * im).sqrt() / x.len() as f64
    };
    let mut base = r.simulation.clone().unwrap();
    let off = sim::simulate_with(&r, &base, &Scenario::constant(&[], 700.0, 1.0, 2)).unwrap();
    base.structure.line_amplitudes_m_s2 = vec![0.5, 0.2];
    for rpm in [700.0, 1100.0] {
        let on = sim::simulate_with(&r, &base, &Scenario::constant(&[], rpm, 1.0, 2)).unwrap();
        let a50 = amp_at(vertical(&on), on.sample_rate, 50.0);
        let a100 = amp_at(vertical(&on), on.sample_rate, 100.0);
        assert!(
            (a50 - 0.5).abs() < 0.05 && (a100 - 0.2).abs() < 0.05,
            "{rpm} rpm: {a50} {a100}"
        );
    }
    assert!(amp_at(vertical(&off), off.sample_rate, 50.0) < 0.05);

    let fr = 19.8;
    let mut sc = Scenario::constant(&[Condition::OuterRace], fr * 60.0, 4.0, 6);
    sc.overrides.slip = Some(0.02);
    let rec = sim::simulate(&r, &sc).unwrap();
    let bpfo = sim::model_fault_orders(&r, r.simulation.as_ref().unwrap()).bpfo * fr;
    let (f, _) = env_spec(&rec, "vertical").peak_near(bpfo * 0.98, 0.01);
    assert!(
        (f / (bpfo * 0.98) - 1.0).abs() < 0.004,
        "slipped BPFO {f} vs {}",
        bpfo * 0.98
    );
}

/// The shipped replay `lut-inner_race-588rpm.mcap` was written by `rigmon simulate` (command
/// in replay/README.md) before the simulator was split into the mechanics
/// (`sim::run_engine`) and the sensor stage (`sim::sensor::finish`): simulating it again gives
/// the same samples, bit for bit, and one engine run finished twice gives the same recording.
#[test]
fn the_split_simulator_reproduces_the_shipped_replay() {
    let rig = rig("lut-rig.toml");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let shipped = rigmon::importers::load(
        &root.join("replay/lut-inner_race-588rpm.mcap"),
        &rig,
        &Default::default(),
    )
    .unwrap();
    let sc = Scenario::constant(&[Condition::InnerRace], 588.0, 8.0, 2025);
    let again = sim::simulate(&rig, &sc).unwrap();
    assert_eq!(shipped.channels.len(), again.channels.len());
    for c in &shipped.channels {
        let b = again.channel(&c.name).unwrap();
        assert_eq!(
            c.samples.len(),
            b.samples.len(),
            "channel {} length",
            c.name
        );
        assert!(
            c.samples
                .iter()
                .zip(&b.samples)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "channel {} differs from the shipped replay",
            c.name
        );
    }
    match (&shipped.tacho, &again.tacho) {
        (Some(Tacho::Analog { samples: a, .. }), Some(Tacho::Analog { samples: b, .. })) => {
            assert_eq!(a, b, "tacho differs from the shipped replay")
        }
        other => panic!("tacho kinds differ: {other:?}"),
    }
    let section = rig.simulation.clone().unwrap();
    let run = sim::run_engine(&rig, &section, &sc).unwrap();
    // the sensor stage keeps no state: finishing one engine run twice gives the same
    // recording (calibration re-runs only this stage against a cached engine run)
    let once = sim::sensor::finish(&rig, &section, &sc, &run).unwrap();
    let twice = sim::sensor::finish(&rig, &section, &sc, &run).unwrap();
    assert_eq!(once.channels[1].samples, twice.channels[1].samples);
}

/// `[simulation.shaft_lines]`: order k has amplitude amplitudes[k-1] (rpm / ref_rpm)^exponent
/// on the vertical and horizontal channels (read back by synchronous demodulation), nothing
/// on the axial one, and nothing for an order above Nyquist.
#[test]
fn shaft_lines_have_their_configured_amplitudes() {
    use rigmon::calibrate::shaft_orders;
    use rigmon::config::simulation::ShaftLinesConfig;
    let mut rig = rig("lut-rig.toml");
    let section = rig.simulation.as_mut().unwrap();
    section.shaft_lines = Some(ShaftLinesConfig {
        ref_rpm: 1200.0,
        exponent: 2.0,
        amplitudes_m_s2: vec![0.4, 0.0, 0.2],
        phase_deg: 30.0,
    });
    let rec = sim::simulate(&rig, &Scenario::constant(&[], 600.0, 3.0, 5)).unwrap();
    let track = rigmon::analysis::whole_recording(&rec, &rig).unwrap();
    for (ch, want) in [
        ("vertical", [0.1, 0.05]),
        ("horizontal", [0.1, 0.05]),
        ("axial", [0.0, 0.0]),
    ] {
        let o = shaft_orders::measure(&rec.channel(ch).unwrap().samples, rec.sample_rate, &track);
        for (k, w) in [(0, want[0]), (2, want[1])] {
            let got = o.amplitude[k];
            // the rotor model's own 1x at 600 rpm is a few mm/s^2
            assert!(
                (got - w).abs() < 0.1 * w + 0.01,
                "{ch} order {}: {got} vs {w}",
                k + 1
            );
        }
    }
    // an order above Nyquist (600 x 10 Hz = 6 kHz at 10 kHz) is left out, not aliased: the
    // recording is the one without shaft lines, sample for sample
    let section = rig.simulation.as_mut().unwrap();
    let mut above = vec![0.0; 600];
    above[599] = 1.0;
    section.shaft_lines.as_mut().unwrap().amplitudes_m_s2 = above;
    let sc = Scenario::constant(&[], 600.0, 0.5, 5);
    let with = sim::simulate(&rig, &sc).unwrap();
    rig.simulation.as_mut().unwrap().shaft_lines = None;
    let without = sim::simulate(&rig, &sc).unwrap();
    assert_eq!(
        with.channel("vertical").unwrap().samples,
        without.channel("vertical").unwrap().samples
    );
}

/// `[simulation.subharmonics]`: the half order o has amplitude half_order_m_s2 (2 o)^-slope
/// (rpm / ref_rpm)^exponent on the vertical and horizontal channels, read back by the
/// calibration's fractional view, and nothing on the axial one; and a calibrated rig file
/// carrying it keeps it in the dataset it trains on, whatever the plan draws, in both
/// `--calibrated` modes.
#[test]
fn subharmonics_have_their_configured_amplitudes_and_reach_the_dataset() {
    use rigmon::calibrate::{fractional_orders, half_orders};
    use rigmon::config::simulation::SubharmonicsConfig;
    let mut rig = rig("lut-rig.toml");
    rig.simulation.as_mut().unwrap().subharmonics = Some(SubharmonicsConfig {
        ref_rpm: 1200.0,
        exponent: 2.0,
        half_order_m_s2: 0.4,
        slope: 1.0,
        highest_order: 1.5,
        phase_deg: 40.0,
    });
    // at 600 rpm: 0.5x 0.4 / 4, 1.5x a third of it, 2.5x and 3.5x off
    let want = [0.1, 0.1 / 3.0, 0.0, 0.0];
    let check = |rig: &RigConfig, rec: &rigmon::recording::Recording, what: &str| {
        let track = rigmon::analysis::whole_recording(rec, rig).unwrap();
        for (ch, gain) in [("vertical", 1.0), ("horizontal", 1.0), ("axial", 0.0)] {
            let f = fractional_orders::measure(
                &rec.channel(ch).unwrap().samples,
                rec.sample_rate,
                &track,
            );
            for (k, w) in want.iter().enumerate() {
                let (got, floor, w) = (f.half.amplitude[k], f.half.floor[k], gain * w);
                // where no line is set, the rotor's own response (its bending modes near
                // 31-34 Hz, 3.5x at 600 rpm) is broadband: no line above twice its floor
                let tol = if w > 0.0 {
                    0.1 * w + 0.005
                } else {
                    2.0 * floor
                };
                assert!(
                    (got - w).abs() < tol,
                    "{what} {ch} {}x: {got} vs {w} (floor {floor})",
                    half_orders::ORDERS[k]
                );
            }
        }
    };
    let rec = sim::simulate(&rig, &Scenario::constant(&[], 600.0, 2.0, 5)).unwrap();
    check(&rig, &rec, "simulate");
    // the calibrated rig file: `[calibration]` names the effect; the plan draws unbalance and
    // noise, which must not take the half orders away
    rig.calibration = Some(rigmon::config::CalibrationStamp {
        id: "cal-test".into(),
        effects: vec![toml::from_str("name = \"subharmonics\"\nhalf_order_m_s2 = 0.4").unwrap()],
    });
    let plan = sim::plan::Plan::parse(
        "name = \"loop\"\nseed = 2\nseconds = 2.0\n[random]\nunbalance_scale = [0.5, 2.0]\n\
         noise_rms_m_s2 = [0.1, 0.3]\n[[case]]\nfaults = \"healthy\"\nrpm = 600\nrecordings = 1\n",
    )
    .unwrap();
    for (mode, rec) in crate::sim::planned_recordings(&rig, &plan) {
        check(&rig, &rec, &format!("dataset {mode:?}"));
    }
}

/// A calibrated rig file and a plan that draws the calibrated parameters: `fixed` keeps the
/// fitted noise and resonance in every recording; `spread` draws them from the plan's
/// ranges moved onto the fitted values (same width for the frequency, same ratio for the
/// noise), so they vary around the calibration instead of over the plan's original ranges.
/// The shipped CWRU calibration (its fitted resonance) with a fitted sensor noise added, so
/// both kinds of parameter are covered whatever that calibration accepts.
#[test]
fn a_dataset_keeps_or_spreads_a_calibration() {
    use rigmon::sim::dataset::{generate, CalibratedDraws};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cwru-de-calibrated.toml");
    let mut table: toml::Table = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let effects = table["calibration"]["effects"].as_array().unwrap().clone();
    assert!(
        effects
            .iter()
            .any(|e| e["name"].as_str() == Some("resonance")),
        "the shipped calibration has no resonance: {effects:?}"
    );
    let mut effects: Vec<toml::Value> = effects
        .into_iter()
        .filter(|e| e["name"].as_str() != Some("noise"))
        .collect();
    let mut noise_effect = toml::Table::new();
    noise_effect.insert("name".into(), "noise".into());
    noise_effect.insert("noise_rms_m_s2".into(), 0.04.into());
    effects.push(noise_effect.into());
    table["calibration"]
        .as_table_mut()
        .unwrap()
        .insert("effects".into(), effects.into());
    table["simulation"]["structure"]
        .as_table_mut()
        .unwrap()
        .insert("noise_rms_m_s2".into(), 0.04.into());
    let r = RigConfig::parse(&toml::to_string(&table).unwrap()).unwrap();
    let sim = r.simulation.as_ref().unwrap();
    assert_eq!(sim.structure.noise_rms_m_s2, 0.04);
    let noise = sim.structure.noise_rms_m_s2;
    let hz = sim.structure.resonances[0].hz;
    let plan = sim::plan::Plan::parse(
        r#"
name = "spread"
seed = 5
seconds = 0.2
[random]
noise_rms_m_s2 = [0.1, 1.0]
resonance_hz = [2000.0, 5000.0]
[[case]]
faults = "healthy"
rpm = 1796
recordings = 12
"#,
    )
    .unwrap();
    for mode in [CalibratedDraws::Fixed, CalibratedDraws::Spread] {
        let dir = tempfile::tempdir().unwrap();
        generate(&r, &plan, dir.path(), "mcap", Some(2), false, mode).unwrap();
        let mut noises = Vec::new();
        let mut freqs = Vec::new();
        for e in std::fs::read_dir(dir.path()).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "mcap") {
                let rec = rigmon::recording::mcap::read_recording(&p).unwrap();
                noises.push(rec.metadata["noise_rms_m_s2"].parse::<f64>().unwrap());
                freqs.push(rec.metadata["resonance_hz"].parse::<f64>().unwrap());
            }
        }
        assert_eq!(noises.len(), 12);
        match mode {
            CalibratedDraws::Fixed => {
                assert!(noises.iter().all(|&n| n == noise), "{noises:?} vs {noise}");
                assert!(freqs.iter().all(|&f| f == hz), "{freqs:?} vs {hz}");
            }
            CalibratedDraws::Spread => {
                let (lo, hi) = (noise / 10f64.sqrt(), noise * 10f64.sqrt());
                assert!(
                    noises.iter().all(|&n| n >= lo * 0.999 && n <= hi * 1.001),
                    "{noises:?} outside [{lo}, {hi}]"
                );
                assert!(
                    freqs.iter().all(|&f| (f - hz).abs() <= 1500.0 + 1.0),
                    "{freqs:?}"
                );
                let spread = |v: &[f64]| {
                    v.iter().cloned().fold(f64::MIN, f64::max)
                        - v.iter().cloned().fold(f64::MAX, f64::min)
                };
                assert!(spread(&noises) > 0.2 * (hi - lo), "{noises:?}");
                assert!(spread(&freqs) > 600.0, "{freqs:?}");
            }
        }
    }
}

/// Issue 28: `rigmon simulate`, `calibrate` and `adapt` read the rig file through the one
/// loader (`RigConfig::load`) and its one table of acceleration units, so they take every
/// spelling the daemon's velocity takes (`G`, `m/s2`, `m/s²`, `mm/s^2`, ...): the simulated
/// channel is written in that unit, under the spelling the file had. A unit that is not an
/// acceleration is refused by all three when the rig file is read, naming the line.
#[test]
fn every_acceleration_unit_spelling_simulates_and_a_wrong_one_is_refused_at_load() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"))
            .unwrap();
    // The vertical channel's unit is on line 31 of the shipped rig file.
    assert_eq!(text.lines().nth(30), Some("unit = \"m/s^2\""));
    let rig_with = |spelling: &str| {
        let p = dir
            .path()
            .join(format!("rig-{}.toml", spelling.replace('/', "_")));
        let t = text.replacen("unit = \"m/s^2\"", &format!("unit = {spelling:?}"), 3);
        std::fs::write(&p, t).unwrap();
        p
    };
    let rigmon = |args: &[&std::ffi::OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_rigmon"))
            .args(args)
            .output()
            .unwrap()
    };
    let simulate = |spelling: &str| -> Recording {
        let rig = rig_with(spelling);
        let out = dir
            .path()
            .join(format!("{}.mcap", spelling.replace('/', "_")));
        let o = rigmon(&[
            "simulate".as_ref(),
            "--rig".as_ref(),
            rig.as_os_str(),
            "--fault".as_ref(),
            "outer_race".as_ref(),
            "--rpm".as_ref(),
            "1200".as_ref(),
            "--seconds".as_ref(),
            "0.5".as_ref(),
            "-o".as_ref(),
            out.as_os_str(),
        ]);
        assert!(
            o.status.success(),
            "simulate with unit {spelling:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        rigmon::recording::mcap::read_recording(&out).unwrap()
    };
    let rms = |r: &Recording| {
        let x = vertical(r);
        (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let reference = simulate("m/s^2");
    let m_s2 = rms(&reference);
    for (spelling, per_m_s2) in [
        ("G", 1.0 / 9.80665),
        ("gn", 1.0 / 9.80665),
        ("m/s2", 1.0),
        ("m/s²", 1.0),
        ("mm/s^2", 1000.0),
        ("MM/S2", 1000.0),
    ] {
        let rec = simulate(spelling);
        assert_eq!(rec.channel("vertical").unwrap().unit, spelling);
        let ratio = rms(&rec) / m_s2;
        assert!(
            (ratio / per_m_s2 - 1.0).abs() < 1e-3,
            "{spelling}: rms ratio {ratio}, want {per_m_s2}"
        );
    }

    let furlong = rig_with("furlong");
    let g = rig_with("G");
    let missing = dir.path().join("missing.mcap");
    let (out, report) = (dir.path().join("out"), dir.path().join("report"));
    let run = |command: &str, rig: &Path| {
        let mut args: Vec<&std::ffi::OsStr> = vec![command.as_ref(), "--rig".as_ref()];
        args.push(rig.as_os_str());
        let m = missing.as_os_str();
        match command {
            "simulate" => args.extend(["--rpm".as_ref(), "1200".as_ref(), "-o".as_ref(), m]),
            "calibrate" => args.extend([
                "--measured".as_ref(),
                m,
                "-o".as_ref(),
                out.as_os_str(),
                "--report".as_ref(),
                report.as_os_str(),
            ]),
            _ => args.extend(["--measured".as_ref(), m, "-o".as_ref(), out.as_os_str()]),
        }
        let o = rigmon(&args);
        assert!(!o.status.success(), "rigmon {args:?} succeeded");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    for command in ["simulate", "calibrate", "adapt"] {
        let err = run(command, &furlong);
        assert!(
            err.contains(&furlong.display().to_string())
                && err.contains(
                    "line 25: channels \"axial\": unit = \"furlong\" is not an acceleration unit"
                )
                && err.contains("m/s^2, m/s2"),
            "{command}: {err}"
        );
    }
    // With `G` the same loader passes the rig file: calibrate and adapt go on to the
    // measured recordings (missing here) before any long work.
    for command in ["calibrate", "adapt"] {
        let err = run(command, &g);
        assert!(
            err.contains("missing.mcap") && !err.contains("unit"),
            "{command}: {err}"
        );
    }
}
