//! `rigmon calibrate` against measured-like data with undeclared effects.
//!
//! The data come from `tests/python/measured_like.py`, an independent generator that is not
//! rigmon's simulator (impulse trains through damped resonances, load-zone modulation, an
//! analog tacho channel). Each case injects one catalog effect with parameters that are
//! written to `truth.json` and never passed to `calibrate`; the test reads `truth.json` only
//! to assert. For each of the nine catalog cases: the right effect is named first, its
//! main parameter is within 20 % of the truth and the error at least halves. The `outside`
//! case (an order-locked line at order 17.3, which no catalog effect explains) must come
//! back `unexplained` at the right place with no effect accepted, and so must `whirl` (a
//! 0.46x line, beside the half order `subharmonics` fits); `baseline` must accept nothing.
//! `looseness_impacts` (a 0.5x line and impacts every other revolution) must name
//! `subharmonics` first and locate the impacts.
//! The calibrated rig file written by `-o` must parse back with the effects and an id.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

const SEED: &str = "1";
const SECONDS: &str = "3";

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Generate a case with the independent generator; returns truth.json.
fn generate_seed(dir: &Path, case: &str, seed: &str) -> Value {
    generate_long(dir, case, seed, SECONDS)
}

/// Generate `seconds` of each recording.
fn generate_long(dir: &Path, case: &str, seed: &str, seconds: &str) -> Value {
    let out = Command::new("python3")
        .arg(repo().join("tests/python/measured_like.py"))
        .args(["--out"])
        .arg(dir)
        .args(["--case", case, "--seed", seed, "--seconds", seconds])
        .output()
        .expect("python3 with numpy is needed (tests/python/requirements.txt)");
    assert!(
        out.status.success(),
        "measured_like.py --case {case} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap()
}

struct Run {
    report: Value,
    calibrated: PathBuf,
    _dir: tempfile::TempDir,
    truth: Value,
}

/// Generate `case`, run `rigmon calibrate --json` on it (labels only, no parameters).
fn calibrate(case: &str) -> Run {
    calibrate_long(case, SECONDS)
}

/// [`calibrate`] on recordings of `seconds`, analysed whole.
fn calibrate_long(case: &str, seconds: &str) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let truth = generate_long(&data, case, SEED, seconds);
    let calibrated = dir.path().join("calibrated.toml");
    let report = run_calibrate(
        case,
        &repo().join("config/lut-rig.toml"),
        &data.join("labels.csv"),
        dir.path(),
    );
    Run {
        report,
        calibrated,
        _dir: dir,
        truth,
    }
}

/// `rigmon calibrate --rig <rig> --measured <measured> -o <dir>/calibrated.toml --report
/// <dir>/report --json`; returns the JSON report and checks the report files exist.
fn run_calibrate(what: &str, rig: &Path, measured: &Path, dir: &Path) -> Value {
    run_calibrate_args(what, rig, measured, dir, &[])
}

/// [`run_calibrate`] with extra arguments (e.g. `--seconds`).
fn run_calibrate_args(
    what: &str,
    rig: &Path,
    measured: &Path,
    dir: &Path,
    extra: &[&str],
) -> Value {
    let t0 = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .arg("calibrate")
        .args(extra)
        .arg("--rig")
        .arg(rig)
        .arg("--measured")
        .arg(measured)
        .arg("-o")
        .arg(dir.join("calibrated.toml"))
        .arg("--report")
        .arg(dir.join("report"))
        .arg("--json")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "calibrate on {what} failed:\n{stderr}"
    );
    let report: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("--json output of {what} is not one JSON object ({e})"));
    eprintln!(
        "{what}: {:.1} s; error {} -> {}; effects {}; unexplained {}",
        t0.elapsed().as_secs_f64(),
        report["error_before"],
        report["error_after"],
        report["effects"],
        report["unexplained"]
    );
    for f in ["report.md", "report.json", "spectra.png", "residual.png"] {
        assert!(dir.join("report").join(f).is_file(), "{what}: no {f}");
    }
    report
}

fn num(v: &Value, what: &str) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"))
}

/// The JSON shape the issue asks for.
fn check_shape(r: &Value) {
    num(&r["error_before"], "error_before");
    num(&r["error_after"], "error_after");
    for e in r["effects"].as_array().expect("effects is a list") {
        assert!(e["name"].is_string(), "effect without a name: {e}");
        assert!(e["params"].is_object(), "effect without params: {e}");
        num(&e["error_before"], "effect error_before");
        num(&e["error_after"], "effect error_after");
    }
    for u in r["unexplained"].as_array().expect("unexplained is a list") {
        num(&u["location"], "unexplained location");
        assert!(u["unit"].is_string() && u["locked_to"].is_string(), "{u}");
    }
}

/// A catalog case: right effect first, main parameter within 20 %, error at least halved,
/// and the calibrated rig file parses back with the effects and the calibration id.
fn catalog_case(case: &str, param: &str, truth_key: &str) -> Run {
    let run = calibrate(case);
    let r = &run.report;
    check_shape(r);
    let effects = r["effects"].as_array().unwrap();
    assert!(
        !effects.is_empty(),
        "{case}: no effect accepted; trials: {}",
        r["rounds"]
    );
    let first = &effects[0];
    assert_eq!(
        first["name"], case,
        "{case}: wrong effect named first; effects {}",
        r["effects"]
    );
    let fitted = num(&first["params"][param], param);
    let truth = num(&run.truth["params"][truth_key], truth_key);
    assert!(
        (fitted - truth).abs() <= 0.2 * truth.abs(),
        "{case}: {param} fitted {fitted}, truth {truth} (more than 20 % off)"
    );
    let (before, after) = (num(&r["error_before"], ""), num(&r["error_after"], ""));
    assert!(
        after <= 0.5 * before,
        "{case}: error {before} -> {after} did not halve"
    );

    // the calibrated rig file
    let rig = rigmon::config::RigConfig::load(&run.calibrated)
        .unwrap_or_else(|e| panic!("{case}: calibrated rig does not parse: {e:#}"));
    let stamp = rig
        .calibration
        .as_ref()
        .unwrap_or_else(|| panic!("{case}: calibrated rig has no [calibration]"));
    assert_eq!(
        Some(stamp.id.as_str()),
        r["calibration_id"].as_str(),
        "{case}: calibration id"
    );
    assert!(stamp.id.starts_with("cal-"), "{}", stamp.id);
    let names: Vec<&str> = stamp
        .effects
        .iter()
        .map(|e| e.get("name").and_then(|n| n.as_str()).unwrap_or(""))
        .collect();
    let want: Vec<&str> = effects
        .iter()
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, want, "{case}: effects in the calibrated rig file");
    let sim = rig.simulation.as_ref().expect("[simulation]");
    match case {
        "slip" => assert!((sim.bearing.slip - fitted).abs() < 1e-3 * fitted.max(1.0)),
        "contact_angle" => {
            assert!((sim.bearing.contact_angle_deg.unwrap() - fitted).abs() < 0.01 * fitted)
        }
        "resonance" => assert!((sim.structure.resonances[0].hz - fitted).abs() < 0.01 * fitted),
        "line_interference" => assert_eq!(sim.structure.line_hz, 60.0),
        "speed_fluctuation" => {
            let f = sim
                .speed_fluctuation
                .expect("[simulation.speed_fluctuation]");
            assert!((f.fraction - fitted).abs() < 0.01 * fitted);
        }
        "unbalance" => {
            // the searched 1x line added to the rotor's own response, not the reported total
            let l = sim.shaft_lines.as_ref().expect("[simulation.shaft_lines]");
            let line1 = num(&first["params"]["line1_m_s2"], "line1_m_s2");
            assert!(
                (l.amplitudes_m_s2[0] - line1).abs() <= 1e-3 * line1,
                "{l:?} vs line1_m_s2 {line1}"
            );
        }
        "looseness" => {
            // orders 3..=highest, harmonics_m_s2 at the geometric-mean order, none above
            let l = sim.shaft_lines.as_ref().expect("[simulation.shaft_lines]");
            let highest = num(&first["params"]["highest_order"], "highest_order") as usize;
            let a = &l.amplitudes_m_s2;
            assert!(
                a.len() >= highest && a[highest..].iter().all(|&x| x == 0.0),
                "{a:?}"
            );
            let lo = a[2..highest].iter().cloned().fold(f64::MAX, f64::min);
            let hi = a[2..highest].iter().cloned().fold(f64::MIN, f64::max);
            assert!(
                lo <= fitted * 1.001 && fitted <= hi * 1.001 && lo > 0.0,
                "harmonics_m_s2 {fitted} not within the fitted lines 3x..{highest}x {a:?}"
            );
        }
        "noise" => assert!((sim.structure.noise_rms_m_s2 - fitted).abs() < 0.01 * fitted),
        _ => {}
    }
    run
}

/// Slip, then the loop: the calibrated rig file -> `rigmon dataset` -> `rigmon train` ->
/// `rigmon evaluate` on recordings not used to calibrate (the generator's next seed), next
/// to the same loop from the uncalibrated rig. The calibration must reach the dataset (the
/// plan's slip draws give way to the fitted slip) and the model's metadata (its id);
/// the two accuracies are printed, not asserted (a small plan, few epochs).
#[test]
fn slip_is_found() {
    let run = catalog_case("slip", "slip", "slip");
    // the rig file holds the full-precision value; the report rounds to 4 digits
    let fitted = rigmon::config::RigConfig::load(&run.calibrated)
        .unwrap()
        .simulation
        .unwrap()
        .bearing
        .slip;
    let id = run.report["calibration_id"].as_str().unwrap().to_string();
    let dir = tempfile::tempdir().unwrap();
    let held = dir.path().join("held");
    generate_seed(&held, "slip", "2");
    let plan = dir.path().join("plan.toml");
    std::fs::write(
        &plan,
        "name = \"loop\"\nseed = 3\nseconds = 1.0\n[random]\nrpm = [500.0, 1300.0]\nslip = [0.0, 0.01]\nnoise_rms_m_s2 = [0.2, 0.4]\n\
         [[case]]\nfaults = \"healthy\"\nrecordings = 12\n[[case]]\nfaults = \"outer_race\"\nrecordings = 12\n\
         [[case]]\nfaults = \"inner_race\"\nrecordings = 12\n",
    )
    .unwrap();
    let mut accuracy = Vec::new();
    for (tag, rig) in [
        ("before", repo().join("config/lut-rig.toml")),
        ("after", run.calibrated.clone()),
    ] {
        let data = dir.path().join(format!("data-{tag}"));
        let model = dir.path().join(format!("{tag}.onnx"));
        rigmon(
            &["dataset", "--rig"],
            &rig,
            &[
                "--plan",
                plan.to_str().unwrap(),
                "-q",
                "-o",
                data.to_str().unwrap(),
            ],
        );
        rigmon(
            &["train", "--rig"],
            &rig,
            &[
                "--data",
                data.to_str().unwrap(),
                "-o",
                model.to_str().unwrap(),
                "--epochs",
                "40",
                "--seed",
                "1",
            ],
        );
        let ev = rigmon(
            &["evaluate", "--rig"],
            &rig,
            &[
                "--model",
                model.to_str().unwrap(),
                "--manifest",
                held.join("labels.csv").to_str().unwrap(),
                "--json",
            ],
        );
        let ev: Value = serde_json::from_str(&ev).expect("evaluate --json prints one object");
        accuracy.push(num(&ev["balanced_accuracy"], "balanced_accuracy"));
        let meta = rigmon::model::OnnxClassifier::load(&model).unwrap();
        let want = if tag == "after" { id.as_str() } else { "none" };
        assert_eq!(
            meta.meta().calibration_id,
            want,
            "{tag}: model calibration id"
        );
        let first = std::fs::read_dir(&data)
            .unwrap()
            .filter_map(|e| e.ok().map(|e| e.path()))
            .find(|p| p.extension().is_some_and(|e| e == "mcap"))
            .unwrap();
        let rec = rigmon::importers::load(
            &first,
            &rigmon::config::RigConfig::load(&rig).unwrap(),
            &Default::default(),
        )
        .unwrap();
        let slip: f64 = rec.metadata["slip"].parse().unwrap();
        if tag == "after" {
            assert!(
                (slip - fitted).abs() < 1e-9,
                "dataset slip {slip}, calibrated {fitted}"
            );
        } else {
            assert!(slip <= 0.01, "plan draw {slip}");
        }
    }
    eprintln!(
        "LOOP slip: balanced accuracy on the held-out generator seed 2: before calibration {:.3}, after {:.3}",
        accuracy[0], accuracy[1]
    );
}

/// Run rigmon with `pre`, the rig path, `post`; returns stdout (fails the test on an error).
fn rigmon(pre: &[&str], rig: &Path, post: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(pre)
        .arg(rig)
        .args(post)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rigmon {pre:?} {post:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn contact_angle_is_found() {
    catalog_case("contact_angle", "contact_angle_deg", "contact_angle_deg");
}

#[test]
fn resonance_is_found() {
    catalog_case("resonance", "hz", "hz");
}

/// The generator's 1x grows with speed^2, the rotor model's with about speed^4.7: the
/// shaft lines' fitted exponent takes up the difference.
#[test]
fn unbalance_is_found() {
    catalog_case("unbalance", "order1_m_s2", "order1_m_s2");
}

#[test]
fn line_interference_is_found() {
    catalog_case("line_interference", "amplitude_m_s2", "amplitude_m_s2");
}

#[test]
fn speed_fluctuation_is_found() {
    catalog_case("speed_fluctuation", "fraction", "fraction");
}

#[test]
fn looseness_is_found() {
    catalog_case("looseness", "harmonics_m_s2", "harmonics_m_s2");
}

/// Half-order sub-harmonics (0.5x, 1.5x, 2.5x, ...) of a housing rocking between two stops
/// every other revolution: the generator clips a 0.5x motion, rigmon adds power-law lines at
/// the half orders; the 0.5x amplitude at 1200 rpm is scored.
#[test]
fn subharmonics_are_found() {
    let run = catalog_case("subharmonics", "half_order_m_s2", "half_order_m_s2");
    let first = &run.report["effects"][0];
    eprintln!(
        "subharmonics: fitted {} (truth {}, 0.5x-3.5x ratios {})",
        first["params"], run.truth["params"]["half_order_m_s2"], run.truth["params"]["line_ratios"]
    );
}

/// Looseness with impacts (issues 26, 39): a 0.5x line plus an impact once every two
/// revolutions ringing down at 900 Hz (a resonance of the loose joint below the generator's
/// structural ones; 12 m/s^2 at 1200 rpm, speed^2, so 3 m/s^2 at 600 rpm), generator seed 7.
/// The measured recordings show the landings (a half-order comb of the envelope against the
/// model), so `looseness_impacts` is searched without being asked for and named first, its
/// mode and damping within 20 % and its landing peak within 25 % (measured: -20 %, the
/// generator's ring-down a cosine from its peak, rigmon's a sine); `subharmonics` follows
/// with the 0.5x line of the total vertical signal within 20 %; and the landings are no
/// longer left in the envelope (before issue 39 they were located there and named, with
/// `subharmonics` alone accepted).
#[test]
fn looseness_with_impacts_is_found() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let truth = generate_seed(&data, "looseness_impacts", "7");
    let r = run_calibrate(
        "looseness_impacts",
        &repo().join("config/lut-rig.toml"),
        &data.join("labels.csv"),
        dir.path(),
    );
    check_shape(&r);
    let effects = r["effects"].as_array().unwrap();
    let names: Vec<&str> = effects.iter().filter_map(|e| e["name"].as_str()).collect();
    assert!(
        names.first() == Some(&"looseness_impacts") && names.contains(&"subharmonics"),
        "looseness_impacts: effects {}; trials {}",
        r["effects"],
        r["rounds"]
    );
    let landings = &effects[0]["params"];
    let p = truth["params"].clone();
    let at_600 = num(&p["impact_m_s2"], "impact") * (600.0f64 / 1200.0).powi(2);
    for (key, want, tol) in [
        ("mode_hz", num(&p["ring_hz"], "ring_hz"), 0.2),
        ("damping", num(&p["damping"], "damping"), 0.2),
        ("peak_m_s2", at_600, 0.25),
    ] {
        let got = num(&landings[key], key);
        assert!(
            (got - want).abs() <= tol * want,
            "looseness_impacts: {key} fitted {got}, truth {want} (more than {} % off); {landings}",
            100.0 * tol
        );
    }
    assert_eq!(num(&landings["at_rpm"], "at_rpm"), 600.0, "{landings}");
    let sub = effects
        .iter()
        .find(|e| e["name"] == "subharmonics")
        .unwrap();
    let fitted = num(&sub["params"]["half_order_m_s2"], "half_order_m_s2");
    let want = num(&p["half_order_m_s2"], "truth half_order_m_s2");
    assert!(
        (fitted - want).abs() <= 0.2 * want,
        "looseness_impacts: 0.5x fitted {fitted} m/s^2, truth {want} (more than 20 % off)"
    );
    let left = r["unexplained"].as_array().unwrap().iter().any(|u| {
        (u["view"] == "env" || u["view"] == "impacts")
            && u["candidates"].as_array().unwrap().iter().any(|c| {
                c.as_str()
                    .unwrap_or("")
                    .contains("once every two revolutions")
            })
    });
    assert!(
        !left,
        "looseness_impacts: the landings are still left in the envelope: {}",
        r["unexplained"]
    );
    eprintln!(
        "looseness_impacts: effects {}; landings {landings} (truth 900 Hz, 0.04, {at_600} m/s^2 at 600 rpm); 0.5x fitted {fitted}, truth {want}",
        r["effects"]
    );
}

#[test]
fn noise_is_found() {
    catalog_case("noise", "noise_rms_m_s2", "noise_rms_m_s2");
}

/// An order-locked narrowband line at a non-integer order is no catalog effect: it comes
/// back unexplained at its order, locked to speed, and nothing is accepted for it.
#[test]
fn an_effect_outside_the_catalog_is_unexplained() {
    let run = calibrate("outside");
    let r = &run.report;
    check_shape(r);
    assert_eq!(
        r["effects"].as_array().unwrap().len(),
        0,
        "outside: a catalog effect absorbed it: {}",
        r["effects"]
    );
    let want = &run.truth["outside"];
    let loc = num(&want["location"], "truth location");
    let found = r["unexplained"].as_array().unwrap().iter().any(|u| {
        u["unit"] == want["unit"]
            && u["locked_to"] == want["locked_to"]
            && (num(&u["location"], "location") - loc).abs() <= 0.02 * loc
    });
    assert!(
        found,
        "outside: no unexplained residual at {loc} {} locked to {}; got {}",
        want["unit"], want["locked_to"], r["unexplained"]
    );
}

/// Nothing injected: nothing may be accepted.
#[test]
fn baseline_accepts_nothing() {
    let run = calibrate("baseline");
    check_shape(&run.report);
    assert_eq!(
        run.report["effects"].as_array().unwrap().len(),
        0,
        "baseline: {}",
        run.report["effects"]
    );
}

/// The real CWRU healthy record (healthy-only calibration, the README's *Real data*),
/// recorded at 48 kHz and analysed at the rig's 12 kHz simulation rate: the resonance the
/// record rings at (4.1-4.3 kHz) is found and confirmed by the held-out half, no bearing
/// effect (slip, contact angle) is invented from a healthy record, the error drops, and the
/// drive-end bearing's inner-race line (162 Hz, 5.415 orders at 1796 rpm), which no catalog
/// effect models, comes back unexplained. The fitted resonance must agree with the shipped
/// `config/cwru-de-calibrated.toml` (the README's numbers) within 1 %. (Analysed at 48 kHz,
/// the sensor noise was accepted too; at 12 kHz fitting it costs more in the shaft harmonics
/// than it gains in the floor, docs/calibration.md, so it is not asserted.)
#[test]
fn cwru_healthy_record_calibrates() {
    let record = repo().join("../shared/data/cwru/97_Normal_0.mat");
    assert!(
        record.is_file(),
        "shared CWRU data missing at {} (CI always has it; see ../shared/data/README.md)",
        record.display()
    );
    let dir = tempfile::tempdir().unwrap();
    // the shipped calibration analyses the record's first 2 s (one second fits, one is held out)
    let r = run_calibrate_args(
        "cwru",
        &repo().join("config/cwru-de.toml"),
        &record,
        dir.path(),
        &["--seconds", "2"],
    );
    check_shape(&r);
    assert!(num(&r["error_after"], "error_after") < num(&r["error_before"], "error_before"));
    let effects = r["effects"].as_array().unwrap();
    let named = |n: &str| effects.iter().find(|e| e["name"] == n);
    for bearing_effect in ["slip", "contact_angle"] {
        assert!(
            named(bearing_effect).is_none(),
            "a healthy record cannot show {bearing_effect}: {}",
            r["effects"]
        );
    }
    for rec in r["recordings"].as_array().unwrap() {
        assert_eq!(rec["recorded_sample_rate_hz"], 48_000.0, "{rec}");
        assert_eq!(rec["sample_rate_hz"], 12_000.0, "{rec}");
    }
    let resonance = named("resonance").expect("no resonance fitted");
    let hz = num(&resonance["params"]["hz"], "resonance hz");
    assert!((4100.0..4300.0).contains(&hz), "resonance {hz} Hz");
    let shipped: toml::Table = toml::from_str(
        &std::fs::read_to_string(repo().join("config/cwru-de-calibrated.toml")).unwrap(),
    )
    .unwrap();
    let shipped_hz = shipped["calibration"]["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"].as_str() == Some("resonance"))
        .and_then(|e| e["hz"].as_float())
        .expect("the shipped calibrated rig file has no resonance effect");
    assert!(
        (hz - shipped_hz).abs() <= 0.01 * shipped_hz,
        "resonance {hz} Hz, the shipped calibration says {shipped_hz} Hz"
    );
    let bpfi = r["unexplained"]
        .as_array()
        .unwrap()
        .iter()
        .any(|u| u["unit"] == "Hz" && (num(&u["location"], "location") - 162.1).abs() <= 1.5);
    assert!(
        bpfi,
        "the 162 Hz inner-race line is not unexplained: {}",
        r["unexplained"]
    );
}

/// `case` generated and analysed whole at 20 s (the length of issue 15's held-out
/// recordings): `speed_fluctuation` is named first with its depth and its period within 20 %,
/// the error at least halves, and the report says how much of each recording was analysed.
/// At 20 s the speed view's line is 0.1 Hz wide on a 0.005 Hz grid: a search over the whole
/// period range (7 log points over 0.2-5 s) lands nowhere near it; the search around the line
/// the measured speed spectra show finds it.
fn speed_fluctuation_fitted_at_20_s(case: &str) {
    let run = calibrate_long(case, "20");
    let r = &run.report;
    check_shape(r);
    let effects = r["effects"].as_array().unwrap();
    assert!(
        !effects.is_empty() && effects[0]["name"] == "speed_fluctuation",
        "{case}: effects {}",
        r["effects"]
    );
    for key in ["fraction", "period_s"] {
        let fitted = num(&effects[0]["params"][key], key);
        let truth = num(&run.truth["params"][key], key);
        assert!(
            (fitted - truth).abs() <= 0.2 * truth,
            "{case}: {key} fitted {fitted}, truth {truth} (more than 20 % off)"
        );
    }
    let (before, after) = (num(&r["error_before"], ""), num(&r["error_after"], ""));
    assert!(
        after <= 0.5 * before,
        "{case}: error {before} -> {after} did not halve"
    );
    for rec in r["recordings"].as_array().unwrap() {
        let s = num(&rec["seconds"], "recordings[].seconds");
        assert!(
            (s - 20.0).abs() < 0.01,
            "analysed {s} s of {}",
            rec["recording"]
        );
        assert_eq!(rec["segments"], 10, "{rec}");
    }
}

/// A speed fluctuation slower than the old 2 s of analysis could show (period 4 s, 4 %
/// deep), five periods in 20 s recordings analysed whole.
#[test]
fn a_slow_speed_fluctuation_is_fitted_from_the_whole_recording() {
    speed_fluctuation_fitted_at_20_s("slow_speed_fluctuation");
}

/// The 0.8 s, 4 % fluctuation on 20 s recordings: its 1.25 Hz line needs the period right to
/// a few percent, which the search over the whole period range did not get (nothing was
/// accepted, docs/calibration-speed.md).
#[test]
fn a_speed_fluctuation_is_fitted_on_20_s_recordings() {
    speed_fluctuation_fitted_at_20_s("speed_fluctuation");
}

/// A sub-synchronous line locked to the shaft (0.46x, as fluid-film whirl) is no catalog
/// effect and sits below 1x, where `orders` and `harmonics` do not look and `lines` sees
/// healthy recordings only: the `fractional` view locates it, locked to speed, within 3 %
/// of its order, with whirl among the candidates; nothing is accepted for it. In particular
/// `subharmonics`, whose 0.5x line the 0.46x one spills onto at 600 rpm, is tried and
/// turned down.
#[test]
fn a_sub_synchronous_effect_outside_the_catalog_is_located() {
    let run = calibrate("whirl");
    let r = &run.report;
    check_shape(r);
    assert_eq!(
        r["effects"].as_array().unwrap().len(),
        0,
        "whirl: a catalog effect absorbed it: {}",
        r["effects"]
    );
    let want = &run.truth["outside"];
    let loc = num(&want["location"], "truth location");
    let hit = r["unexplained"].as_array().unwrap().iter().find(|u| {
        u["unit"] == "order"
            && u["locked_to"] == "speed"
            && (num(&u["location"], "location") - loc).abs() <= 0.03 * loc
    });
    let hit = hit.unwrap_or_else(|| {
        panic!(
            "whirl: nothing unexplained at order {loc} locked to speed; got {}",
            r["unexplained"]
        )
    });
    assert!(
        hit["candidates"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c.as_str().unwrap_or("").contains("whirl")),
        "whirl: candidates {}",
        hit["candidates"]
    );
    let sub = r["rounds"][0]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["name"] == "subharmonics")
        .unwrap_or_else(|| panic!("whirl: subharmonics was not tried: {}", r["rounds"][0]));
    assert_eq!(sub["accepted"], false, "whirl: {sub}");
    eprintln!(
        "whirl: subharmonics tried, own components {} -> {} (fit), {} -> {} (held out), params {}",
        sub["own_fit_before"],
        sub["own_fit_after"],
        sub["own_held_before"],
        sub["own_held_after"],
        sub["params"]
    );
}

/// The search objective from an effect's own views, on the recordings its components apply
/// to (`Twin::error_of`), is bit for bit the one from every view of every recording (the
/// full error's `of(own)`), for every catalog effect: the speed-up moves no fitted value.
#[test]
fn searching_on_own_views_gives_the_same_objective() {
    use rigmon::calibrate::{catalog, fit};
    use rigmon::sim::{rig_simulation, simulate_with, Scenario};
    use rigmon::vocabulary::Condition;
    let rig = rigmon::config::RigConfig::load(&repo().join("config/lut-rig.toml")).unwrap();
    let base = rig_simulation(&rig).unwrap().clone();
    let mut truth = base.clone();
    truth.structure.noise_rms_m_s2 = 0.1;
    truth.bearing.slip = 0.01;
    // half-order lines in the "measured" side, so `half_orders` compares something
    truth.subharmonics = Some(rigmon::config::simulation::SubharmonicsConfig {
        ref_rpm: 1200.0,
        exponent: 2.0,
        half_order_m_s2: 0.2,
        slope: 1.0,
        highest_order: 2.5,
        phase_deg: 0.0,
    });
    let ops: Vec<rigmon::calibrate::measured::Measured> =
        [(vec![], 600.0), (vec![Condition::OuterRace], 1200.0)]
            .into_iter()
            .enumerate()
            .map(|(i, (faults, rpm))| {
                let sc = Scenario::constant(&faults, rpm, 1.0, 50 + i as u64);
                let recording = simulate_with(&rig, &truth, &sc).unwrap();
                rigmon::calibrate::measured::Measured {
                    name: format!("r{i}"),
                    label: sc.label().to_string(),
                    recorded_sample_rate: recording.sample_rate,
                    recording,
                    faults,
                    rpm,
                }
            })
            .collect();
    let cx = fit::context(&ops);
    let fast = fit::Twin::with_options(&rig, &ops, fit::Options::default()).unwrap();
    let full = fit::Options {
        own_views: false,
        ..fit::Options::default()
    };
    let slow = fit::Twin::with_options(&rig, &ops, full).unwrap();
    for effect in catalog::ALL {
        let mut x = effect.start(&base, &cx);
        // away from the rig's own value, so the section differs from the base
        x[0] = match effect.params(&cx)[0].range {
            catalog::Range::Choice(ref c) => c[c.len() - 1],
            catalog::Range::Linear(a, b) => a + 0.3 * (b - a),
            catalog::Range::Log(a, b) => (a * a * b).cbrt(),
        };
        let sim = effect.apply(&base, &x, &cx);
        let own = effect.components();
        let a = fast.error_of(&sim, &[0, 1], own).unwrap();
        let b = slow.error(&sim, &[0, 1]).unwrap().of(own);
        assert_eq!(a.to_bits(), b.to_bits(), "{}: {a} vs {b}", effect.name());
        assert!(a.is_finite(), "{}: {a}", effect.name());
        if effect == catalog::Effect::Subharmonics {
            // the measured half orders against a weaker simulated set: not a trivial 0
            assert!(a > 0.5, "subharmonics: objective {a}");
        }
    }
    assert!(catalog::ALL.contains(&catalog::Effect::Subharmonics));
}
