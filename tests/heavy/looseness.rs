//! Issue 39: `rigmon calibrate` finds a loose housing it was not tuned to. The recordings come
//! from `tests/python/loose_housing.py`, a generator written for this issue from the physics
//! of a loose joint (a 0.5x rocking clipped at the seat, a landing every other revolution
//! whose half-sine contact force rings one mode of the joint), not from rigmon's simulator
//! nor measured_like.py's looseness. Two of the cases from docs/calibration.md's sweep run
//! here (strong landings ringing a high mode over a clipped rocking; weak landings at a low
//! mode with no rocking at all); the sweep's other cases are rerun by the command there.
//! Each: `looseness_impacts` accepted (or `subharmonics` first, then it), its mode and its
//! landing peak within 20 % of the truth, no `noise` or `resonance` taken before it, and no
//! unexplained residual where looseness shows (half orders, the impacts' envelope). Not met
//! yet, so ignored, and `looseness_impacts` is out of `catalog::ALL` (docs/calibration.md).

use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn num(v: &Value, what: &str) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("{what} is not a number: {v}"))
}

/// Generate with `args`, calibrate; (report, truth params).
fn calibrate(case: &str, args: &[&str]) -> (Value, Value) {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let gen = Command::new("python3")
        .arg(repo().join("tests/python/loose_housing.py"))
        .arg("--out")
        .arg(&data)
        .args(args)
        .output()
        .expect("python3 with numpy is needed (tests/python/requirements.txt)");
    assert!(
        gen.status.success(),
        "loose_housing.py {args:?}: {}",
        String::from_utf8_lossy(&gen.stderr)
    );
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("truth.json")).unwrap()).unwrap();
    let t0 = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .arg("calibrate")
        .arg("--rig")
        .arg(repo().join("config/lut-rig.toml"))
        .arg("--measured")
        .arg(data.join("labels.csv"))
        .arg("-o")
        .arg(dir.path().join("calibrated.toml"))
        .arg("--report")
        .arg(dir.path().join("report"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "calibrate on {case}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        dir.path().join("report/looseness.png").is_file(),
        "{case}: the report has no looseness.png"
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!(
        "{case}: {:.0} s; error {} -> {}; effects {}; unexplained {}",
        t0.elapsed().as_secs_f64(),
        report["error_before"],
        report["error_after"],
        report["effects"],
        report["unexplained"]
    );
    (report, truth["params"].clone())
}

/// One independent case: its name and `loose_housing.py`'s arguments.
struct Case {
    name: &'static str,
    args: &'static [&'static str],
}

/// The checks every case shares: `looseness_impacts` accepted first (after `subharmonics` at
/// most), no `noise` or `resonance` before it; its mode, its landing peak and its damping
/// within 20 % of the truth; nothing left unexplained where looseness shows (half orders of
/// any view, the impacts' envelope).
fn found(case: &Case) {
    let (r, truth) = calibrate(case.name, case.args);
    let effects = r["effects"].as_array().unwrap();
    let names: Vec<&str> = effects
        .iter()
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    let Some(at) = names.iter().position(|n| *n == "looseness_impacts") else {
        panic!(
            "{}: looseness_impacts not accepted: effects {names:?}; trials {}",
            case.name, r["rounds"]
        );
    };
    assert!(
        names[..at].iter().all(|n| *n == "subharmonics"),
        "{}: {names:?} taken before looseness_impacts",
        case.name
    );
    let p = &effects[at]["params"];
    for (fitted, want) in [
        ("mode_hz", "mode_hz"),
        ("peak_m_s2", "impact_m_s2"),
        ("damping", "damping"),
    ] {
        let (f, w) = (num(&p[fitted], fitted), num(&truth[want], want));
        assert!(
            (f - w).abs() <= 0.2 * w,
            "{}: {fitted} fitted {f}, truth {w} (more than 20 % off); params {p}",
            case.name
        );
    }
    let half = |o: f64| (o - o.floor() - 0.5).abs() <= 0.03;
    let left: Vec<&Value> = r["unexplained"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|u| {
            u["view"] == "impacts"
                || (u["unit"] == "order" && half(num(&u["location"], "location")))
        })
        .collect();
    assert!(
        left.is_empty(),
        "{}: looseness left unexplained: {left:?}",
        case.name
    );
}

/// Strong landings (30 m/s^2 at 1200 rpm) ringing a 2.5 kHz mode, over a rocking clipped at
/// 60 % of its stroke: the strength at which `noise` used to be named first.
#[test]
#[ignore = "issue 39 not done: 470 s in a debug build at load 9, and the landing peak fits 3.1x the truth (mode and damping within 20 %); run with --ignored"]
fn strong_landings_at_a_high_mode_are_looseness() {
    found(&Case {
        name: "strong, 2.5 kHz, clipped rocking",
        args: &[
            "--impact",
            "30",
            "--mode-hz",
            "2500",
            "--damping",
            "0.03",
            "--seed",
            "3",
        ],
    });
}

/// Weak landings (1 m/s^2) ringing a 600 Hz mode with no rocking line at all.
#[test]
#[ignore = "issue 39 not done: nothing is accepted on this case (the 10 Hz landing comb is left unexplained in `env`); run with --ignored"]
fn weak_landings_at_a_low_mode_without_rocking_are_looseness() {
    found(&Case {
        name: "weak, 600 Hz, no rocking",
        args: &[
            "--impact",
            "1",
            "--mode-hz",
            "600",
            "--damping",
            "0.05",
            "--line",
            "0",
            "--seed",
            "4",
        ],
    });
}
