//! Issue 39: `rigmon calibrate` finds a loose housing it was not tuned to. The recordings come
//! from `tests/python/loose_housing.py`, a generator written for this issue from the physics
//! of a loose joint (a 0.5x rocking clipped at the seat, a landing every other revolution
//! whose half-sine contact force rings one mode of the joint), not from rigmon's simulator
//! nor measured_like.py's looseness. Four of the cases from docs/calibration.md's sweep run
//! here (strong landings ringing a high mode over a clipped rocking; medium landings lost in
//! the broadband views, searched on request; medium landings over a rocking that is not
//! clipped, where the band energies alone traded the damping for the strength; weak landings
//! at a low mode with no rocking at all); the sweep's other cases are rerun by the command
//! there. Each calibrates as a user runs it, without `--looseness-impacts` but for the one
//! lost in the broadband views: where the recordings show the landings (a half-order comb of
//! the envelope against the model), `looseness_impacts` is searched anyway. Each:
//! `looseness_impacts` accepted (or `subharmonics` first, then it), its mode, damping and
//! landing peak within 20 % of the truth, no `noise` or `resonance` taken before it, and no
//! unexplained residual where looseness shows (half orders, the impacts' envelope). The
//! strong and medium cases meet it; the weak one does not (located and named, not searched;
//! with the flag, its mode stands less than 10 dB above the floor on the fit part, so its
//! damping cannot be read there and the views it is searched on do not show it), so it is
//! ignored (docs/calibration.md).
//! Two checks more: the simulator's own landings are fitted back, and the absolute `floor` is
//! what tells the landing strength on the strong independent case.

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

/// `loose_housing.py`'s strong case: 30 m/s^2 landings ringing a 2.5 kHz mode (damping 3 %)
/// over a clipped rocking.
const STRONG: &[&str] = &[
    "--impact",
    "30",
    "--mode-hz",
    "2500",
    "--damping",
    "0.03",
    "--seed",
    "3",
];

/// Write `loose_housing.py`'s recordings for `args` into `out`.
fn generate(out: &std::path::Path, args: &[&str]) {
    let gen = Command::new("python3")
        .arg(repo().join("tests/python/loose_housing.py"))
        .arg("--out")
        .arg(out)
        .args(args)
        .output()
        .expect("python3 with numpy is needed (tests/python/requirements.txt)");
    assert!(
        gen.status.success(),
        "loose_housing.py {args:?}: {}",
        String::from_utf8_lossy(&gen.stderr)
    );
}

/// Generate with `args`, calibrate with `flags`; (report, truth params).
fn calibrate(case: &str, args: &[&str], flags: &[&str]) -> (Value, Value) {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    generate(&data, args);
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
        .args(flags)
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
    /// `rigmon calibrate`'s flags beyond the defaults.
    flags: &'static [&'static str],
}

/// The checks every case shares: `looseness_impacts` accepted first (after `subharmonics` at
/// most), no `noise` or `resonance` before it; its mode, its landing peak and its damping
/// within 20 % of the truth (the peak at the speed it is stated at); nothing left
/// unexplained where looseness shows (half orders of any view, the impacts' envelope).
fn found(case: &Case) {
    let (r, truth) = calibrate(case.name, case.args, case.flags);
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
    // the landing peak is stated at the fit part's healthy speed (`at_rpm`): the truth there
    let rpm = format!("{}", num(&p["at_rpm"], "at_rpm").round());
    let peak = &truth["peak_at_rpm_m_s2"][&rpm];
    for (fitted, want) in [
        ("mode_hz", &truth["mode_hz"]),
        ("peak_m_s2", peak),
        ("damping", &truth["damping"]),
    ] {
        let (f, w) = (num(&p[fitted], fitted), num(want, fitted));
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
fn strong_landings_at_a_high_mode_are_looseness() {
    found(&Case {
        name: "strong, 2.5 kHz, clipped rocking",
        args: STRONG,
        flags: &[],
    });
}

/// Medium landings (5 m/s^2 at 1200 rpm) ringing a 1.8 kHz mode at 3 %, over a clipped
/// rocking: lost in the broadband views (`impacts`, `env`), located by the half-order comb of
/// the band where they ring (`landings`), which does not open the search (a real machine's
/// healthy record shows such a comb: docs/calibration.md), so searched as a user asks for it
/// (`--looseness-impacts`), and fitted once the search reads the mode's damping from its
/// half-power width (before, with the flag: damping and peak 59 % high, each trading for the
/// other).
#[test]
fn medium_landings_searched_on_request_are_looseness() {
    found(&Case {
        name: "medium, 1.8 kHz, clipped rocking",
        args: &[
            "--impact",
            "5",
            "--mode-hz",
            "1800",
            "--damping",
            "0.03",
            "--seed",
            "12",
        ],
        flags: &["--looseness-impacts"],
    });
}

/// Medium landings (5 m/s^2 at 1200 rpm) ringing a 1 kHz mode at 4 % over a rocking that is
/// not clipped (a pure 0.5x line): the band energies alone put the damping and the peak 38 %
/// and 40 % high (docs/calibration.md, 2026-12-07); the ring's half-power width fixes the
/// damping.
#[test]
fn landings_over_an_unclipped_rocking_are_looseness() {
    found(&Case {
        name: "medium, 1 kHz, unclipped rocking",
        args: &[
            "--impact",
            "5",
            "--mode-hz",
            "1000",
            "--damping",
            "0.04",
            "--clip",
            "1",
            "--seed",
            "14",
        ],
        flags: &[],
    });
}

/// Weak landings: 1 m/s^2 at 1200 rpm ringing a 600 Hz mode, with no rocking line at all.
const WEAK: &[&str] = &[
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
];

/// Weak landings (1 m/s^2) ringing a 600 Hz mode with no rocking line at all.
#[test]
#[ignore = "issue 39 not done: the landings are located and named (`weak_landings_are_located_and_named`), but not searched (and refused with --looseness-impacts: on the fit part their mode stands < 10 dB above the floor); run with --ignored"]
fn weak_landings_at_a_low_mode_without_rocking_are_looseness() {
    found(&Case {
        name: "weak, 600 Hz, no rocking",
        args: WEAK,
        flags: &[],
    });
}

/// The same weak landings, lost in the broadband views, are located in the band where they
/// ring and named (`landings` at 0.5x, "impacting once every two revolutions"), if not fitted;
/// the same rig without landings (the control, same seed) shows none.
#[test]
fn weak_landings_are_located_and_named() {
    let control: &[&str] = &["--impact", "0", "--line", "0", "--seed", "4"];
    for (case, args, loose) in [
        ("weak, 600 Hz, no rocking", WEAK, true),
        ("control: no landings", control, false),
    ] {
        let (r, _) = calibrate(case, args, &[]);
        let fitted = r["effects"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["name"] == "looseness_impacts");
        let named = r["unexplained"].as_array().unwrap().iter().any(|u| {
            u["view"] == "landings"
                && (num(&u["location"], "location") - 0.5).abs() < 1e-9
                && u["candidates"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|c| c.as_str().unwrap().contains("once every two revolutions"))
        });
        assert_eq!(
            fitted || named,
            loose,
            "{case}: landings fitted {fitted}, located and named {named}; report {r}"
        );
    }
}

/// Where the healthy recordings ring beyond the uncalibrated model: the middle of the band
/// whose measured level exceeds the simulated one most (the median over the recordings),
/// Hz, as `calibrate` starts `looseness_impacts`' mode (`fit::ringing_hz`).
fn ringing_hz(
    twin: &rigmon::calibrate::fit::Twin,
    base: &rigmon::config::simulation::SimulationConfig,
) -> Option<f64> {
    use rigmon::calibrate::views::BAND_HZ;
    let mut hz: Vec<f64> = (0..twin.measured.len())
        .filter_map(|i| {
            let (m, s) = (&twin.measured[i], twin.simulated(base, i).unwrap());
            let excess = m.bands.iter().zip(&s.bands).map(|(a, b)| a - b);
            let (k, _) = excess.enumerate().max_by(|a, b| a.1.total_cmp(&b.1))?;
            m.band_lo_hz.get(k).map(|lo| lo + BAND_HZ / 2.0)
        })
        .collect();
    hz.sort_by(f64::total_cmp);
    (!hz.is_empty()).then(|| hz[hz.len() / 2])
}

/// The simulator's own landings are fitted back (issue 39's self-consistency check): a loose
/// housing simulated by rigmon on the LUT rig, healthy at 600 and 1200 rpm, 3 s each, its
/// landings 5 m/s^2 at 1200 rpm growing with the shaft rate (exponent 1: the housing falls
/// through a fixed clearance, so its landing speed, and the impulse, follow the shaft rate),
/// ringing a 1500 Hz joint mode at 4 % damping (a bolted joint's 1-5 %). `looseness_impacts`
/// is searched on them on its own components from the catalog's start, passes and bounds, as
/// a calibration's trial runs it (`fit::search_effect`). The landing's peak, the mode and the
/// damping come back within 20 %: the effect and the views it is judged on agree with each
/// other, so a strength off on other data comes from what else the model puts in those
/// relative views (docs/calibration.md, issue 39).
#[test]
fn simulated_landings_are_fitted_back() {
    use rigmon::calibrate::{catalog::Effect, fit, measured::Measured, search};
    use rigmon::config::simulation::LooseImpactsConfig;
    use rigmon::sim::{landing_peak, rig_simulation, simulate_with, Scenario};
    let rig = rigmon::config::RigConfig::load(&repo().join("config/lut-rig.toml")).unwrap();
    let base = rig_simulation(&rig).unwrap().clone();
    let loose = LooseImpactsConfig {
        ref_rpm: 1200.0,
        exponent: 1.0,
        impact_m_s2: 5.0,
        mode_hz: 1500.0,
        damping: 0.04,
        horizontal_ratio: 0.5,
        phase_deg: 0.0,
        timing_jitter: 0.01,
    };
    let mut truth = base.clone();
    truth.loose_impacts = Some(loose.clone());
    let ops: Vec<Measured> = [600.0, 1200.0]
        .into_iter()
        .enumerate()
        .map(|(i, rpm)| {
            let sc = Scenario::constant(&[], rpm, 3.0, 70 + i as u64);
            let recording = simulate_with(&rig, &truth, &sc).unwrap();
            Measured {
                name: format!("healthy-{rpm}"),
                label: sc.label().to_string(),
                recorded_sample_rate: recording.sample_rate,
                recording,
                faults: Vec::new(),
                rpm,
            }
        })
        .collect();
    let twin = fit::Twin::new(&rig, &ops).unwrap();
    let all = [0, 1];
    let effect = Effect::LoosenessImpacts;
    let cx = rigmon::calibrate::catalog::Context {
        ringing_hz: ringing_hz(&twin, &base),
        ..fit::context(&ops)
    };
    let t0 = std::time::Instant::now();
    let mut x = effect.start(&base, &cx);
    let mut evaluations = 0;
    let mut objective = f64::INFINITY;
    for _ in 0..effect.search_passes() {
        let (next, e, n) = search::minimize(&effect.params(&cx), &x, &mut |v| {
            twin.error_of(&effect.apply(&base, v, &cx), &all, effect.components())
                .unwrap()
        });
        (x, objective, evaluations) = (next, e, evaluations + n);
    }
    let fitted = effect.apply(&base, &x, &cx).loose_impacts.unwrap();
    let at_truth = twin.error_of(&truth, &all, effect.components()).unwrap();
    eprintln!(
        "fitted {fitted:?} (peak {:.3}, truth {:.3}), objective {objective:.3} (at the truth \
         {at_truth:.3}), {evaluations} evaluations, {:.0} s; ringing_hz {:?}",
        landing_peak(&fitted),
        landing_peak(&loose),
        t0.elapsed().as_secs_f64(),
        cx.ringing_hz
    );
    for (what, f, w) in [
        ("peak_m_s2", landing_peak(&fitted), landing_peak(&loose)),
        ("mode_hz", fitted.mode_hz, loose.mode_hz),
        ("damping", fitted.damping, loose.damping),
    ] {
        assert!(
            (f - w).abs() <= 0.2 * w,
            "{what}: fitted {f}, simulated {w} (more than 20 % off); {fitted:?}"
        );
    }
}

/// Why the landing strength fits 2-3x on `loose_housing.py`'s strong case (30 m/s^2 at 1200
/// rpm ringing 2.5 kHz at 3 %, seed 3): at the true mode and damping, the relative components
/// of `looseness_impacts` barely tell the strength (`impacts` to the local median, `bands` to
/// the strongest band, `half_orders` to the floors; `bands` keeps falling past the truth,
/// the model's own resonances sitting lower beside the landings than the generator's), while
/// the absolute broadband floor of the healthy recordings (`floor`, the ring-down's skirts)
/// is lowest at the true strength and rises by more than its smallest
/// meaningful cut at half and at twice it. Prints every component of the scan.
#[test]
fn the_absolute_floor_tells_the_landing_strength() {
    use rigmon::calibrate::{catalog, error::min_cut, fit, measured};
    use rigmon::vocabulary::ErrorComponent as C;
    let dir = tempfile::tempdir().unwrap();
    generate(dir.path(), STRONG);
    let rig = rigmon::config::RigConfig::load(&repo().join("config/lut-rig.toml")).unwrap();
    let base = rigmon::sim::rig_simulation(&rig).unwrap().clone();
    let ops = measured::load(&rig, &[dir.path().join("labels.csv")], f64::INFINITY).unwrap();
    let cx = fit::context(&ops);
    let twin = fit::Twin::new(&rig, &ops).unwrap();
    let all: Vec<usize> = (0..ops.len()).collect();
    let effect = catalog::Effect::LoosenessImpacts;
    // the truth: the landing peak 30 m/s^2 at 1200 rpm (impact_m_s2 a little above it), the
    // generator's speed law (exponent 1)
    let scale = [0.5, 1.0, 1.5, 2.0, 3.0];
    let floor: Vec<f64> = scale
        .iter()
        .map(|k| {
            let mut x = vec![30.0 * k, 2500.0, 0.03, 1.0];
            let sim = effect.apply(&base, &x, &cx);
            let peak = rigmon::sim::landing_peak(sim.loose_impacts.as_ref().unwrap());
            x[0] *= 30.0 * k / peak;
            let e = twin.error(&effect.apply(&base, &x, &cx), &all).unwrap();
            eprintln!(
                "peak {:.1} m/s^2 (x{k}): own {:.3} (impacts {:.3} half_orders {:.3} bands {:.3} \
                 modes {:.3}), floor {:.3}, total {:.3}",
                30.0 * k,
                e.of(effect.components()),
                e.get(C::Impacts),
                e.get(C::HalfOrders),
                e.get(C::Bands),
                e.get(C::Modes),
                e.get(C::Floor),
                e.total
            );
            e.get(C::Floor)
        })
        .collect();
    assert!(
        floor[1] + min_cut(C::Floor) < floor[0] && floor[1] + min_cut(C::Floor) < floor[3],
        "floor at 0.5x, 1x, 1.5x, 2x, 3x the true landing: {floor:?}"
    );
}
