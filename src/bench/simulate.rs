//! `rigmon bench simulate`: wall time of the rig simulator for `--seconds` (default 10) of
//! signal at f_r = 19.8 Hz on one core, against the thesis' MSC Adams run (Paper A Table 8:
//! 7,255.17 s for 10 s with the 6DOF bearing, 8,251.25 s with the hi-fi bearing), and the
//! thesis dataset plan (378 one-second recordings) on all cores, against the single-core rate
//! measured in the same run; then adapt's two datasets of that plan apart and as a pair
//! sharing their mechanics ([`super::dataset_pair`]), the ratio between them.

use super::{machine_line, BenchOptions};
use crate::config::RigConfig;
use crate::sim::{self, dataset::generate, plan::Plan, Scenario};
use crate::vocabulary::Condition::{InnerRace, OuterRace};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Paper A Table 8, 19.8 Hz, 10 s of signal.
const THESIS_6DOF_S: f64 = 7255.17;
const THESIS_HIFI_S: f64 = 8251.25;

fn shipped(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| shipped("config/lut-rig.toml"));
    let rig = RigConfig::load(&rig_path)?;
    sim::rig_simulation(&rig)?;
    let seconds = if opts.seconds > 0.0 {
        opts.seconds
    } else {
        10.0
    };
    let rpm = 19.8 * 60.0;

    // 1) one core, 10 s of signal, each fault class (best of two runs each).
    let mut single = Vec::new();
    for faults in [vec![], vec![OuterRace], vec![InnerRace]] {
        let sc = Scenario::constant(&faults, rpm, seconds, 1);
        let mut best = f64::INFINITY;
        for _ in 0..2 {
            let t0 = Instant::now();
            let rec = sim::simulate(&rig, &sc)?;
            best = best.min(t0.elapsed().as_secs_f64());
            if rec.is_empty() {
                bail!("the simulator returned an empty recording");
            }
        }
        single.push((sc.label(), best));
    }
    let worst = single.iter().map(|s| s.1).fold(0.0, f64::max);
    let per_signal_s = worst / seconds;

    // 2) the thesis plan on all cores (MCAP files into a temporary directory).
    let plan_path = shipped("config/plans/thesis.toml");
    let plan = Plan::load(&plan_path)?;
    let dir = tempfile_dir()?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let ds = generate(&rig, &plan, &dir, "mcap", None, false, Default::default())
        .with_context(|| format!("thesis plan into {}", dir.display()))?;
    let _ = std::fs::remove_dir_all(&dir);
    let pair = super::dataset_pair::time_both(&rig, &plan, &tempfile_dir()?)?;
    let expected_one_core = ds.seconds * per_signal_s;
    let thesis_plan_s = ds.seconds / 10.0 * THESIS_6DOF_S;

    let table = validation_table(&rig)?;

    if opts.json {
        let v = serde_json::json!({
            "benchmark": "simulate",
            "machine": machine_line(),
            "rig": rig.machine.id,
            "signal_seconds": seconds,
            "shaft_hz": 19.8,
            "single_core_wall_s": single.iter().map(|(l, w)| serde_json::json!({"label": l, "wall_s": w})).collect::<Vec<_>>(),
            "worst_wall_s": worst,
            "speedup_vs_thesis_6dof": THESIS_6DOF_S * seconds / 10.0 / worst,
            "speedup_vs_thesis_hifi": THESIS_HIFI_S * seconds / 10.0 / worst,
            "thesis_plan": {"recordings": ds.recordings, "signal_seconds": ds.seconds, "cores": cores, "wall_s": ds.wall_s,
                "parallel_speedup_vs_one_core": expected_one_core / ds.wall_s, "thesis_adams_estimate_s": thesis_plan_s},
            "adapt_datasets": pair,
            "table6_style": table.iter().map(|(fr, case, v)| serde_json::json!({"f_r": fr, "case": case, "bpfo_1_3_hz": &v[..3], "bpfi_1_3_hz": &v[3..]})).collect::<Vec<_>>(),
        });
        println!("{v}");
        return Ok(());
    }
    println!("rigmon bench simulate — {}", machine_line());
    println!(
        "rig {} ({}), f_r = 19.8 Hz, {seconds} s of signal, one core:",
        rig.machine.id,
        rig_path.display()
    );
    for (label, wall) in &single {
        println!(
            "  {label:<11} {wall:8.3} s wall  ({:7.1}x real time)",
            seconds / wall
        );
    }
    println!(
        "  vs thesis Table 8 (MSC Adams, i9-13900, 10 s): 6DOF-BM {THESIS_6DOF_S} s -> {:.0}x faster; hi-fi BM {THESIS_HIFI_S} s -> {:.0}x faster",
        THESIS_6DOF_S * seconds / 10.0 / worst,
        THESIS_HIFI_S * seconds / 10.0 / worst
    );
    println!(
        "thesis plan ({} recordings, {:.0} s of signal, MCAP written) on {cores} cores: {:.2} s wall ({:.2}x the one-core rate measured above; Adams would need ~{:.0} s)",
        ds.recordings,
        ds.seconds,
        ds.wall_s,
        expected_one_core / ds.wall_s,
        thesis_plan_s
    );
    println!("{}", pair.line());
    println!("\nCharacteristic frequencies (Hz), Paper A Table 6/7 style; rigmon = envelope-spectrum peaks of 10 s of simulated vertical acceleration:");
    println!("| f_r (Hz) | case | BPFO | 2BPFO | 3BPFO | BPFI | 2BPFI | 3BPFI |");
    println!("|---|---|---|---|---|---|---|---|");
    for (fr, case, v) in &table {
        let cells: Vec<String> = v
            .iter()
            .map(|x| {
                if x.is_nan() {
                    "-".into()
                } else {
                    format!("{x:.2}")
                }
            })
            .collect();
        println!("| {fr} | {case} | {} |", cells.join(" | "));
    }
    Ok(())
}

/// Thesis Table 6 rows (experiment, MBD) and this simulator's peaks, at alpha = 0 (the real
/// rig) and at the MBD's preload contact angle (28.3 deg at 9.8 Hz, 28.87 deg at 19.8 Hz).
fn validation_table(rig: &RigConfig) -> Result<Vec<(f64, String, Vec<f64>)>> {
    let nan = f64::NAN;
    let thesis: [(f64, &str, [f64; 6]); 4] = [
        (
            9.8,
            "thesis experiment",
            [45.30, 90.60, 135.80, 62.40, 124.6, 187.4],
        ),
        (
            9.8,
            "thesis MBD (alpha 28.3)",
            [46.40, 92.60, 139.00, 61.40, 122.8, 184.40],
        ),
        (
            19.8,
            "thesis experiment",
            [90.80, 181.70, 272.5, 126.2, 252.2, nan],
        ),
        (
            19.8,
            "thesis MBD (alpha 28.87)",
            [93.00, 186.00, 276.00, 124.2, 248.4, nan],
        ),
    ];
    let mut rows = Vec::new();
    for (fr, alpha_mbd) in [(9.8, 28.3), (19.8, 28.87)] {
        for alpha in [0.0, alpha_mbd] {
            let o = rig.bearing.with_contact_angle(alpha).fault_orders();
            let theory: Vec<f64> = [
                o.bpfo,
                2.0 * o.bpfo,
                3.0 * o.bpfo,
                o.bpfi,
                2.0 * o.bpfi,
                3.0 * o.bpfi,
            ]
            .iter()
            .map(|x| x * fr)
            .collect();
            rows.push((fr, format!("theory (alpha {alpha})"), theory.clone()));
            let mut meas = Vec::new();
            for (fault, base) in [(OuterRace, 0), (InnerRace, 3)] {
                let mut sc = Scenario::constant(&[fault], fr * 60.0, 10.0, 42);
                if alpha > 0.0 {
                    sc.overrides.contact_angle_deg = Some(alpha);
                    sc.overrides.radial_clearance_mm = Some(0.0);
                }
                let rec = sim::simulate(rig, &sc)?;
                let ch = rig
                    .classifier_channel()
                    .map(|c| c.name.clone())
                    .unwrap_or_else(|| "vertical".into());
                let x = &rec
                    .channel(&ch)
                    .with_context(|| format!("no channel {ch}"))?
                    .samples;
                let spec = sim::signature::envelope_spectrum(
                    x,
                    rec.sample_rate,
                    0.0,
                    rig.features.lowpass_hz,
                    4,
                );
                for k in 0..3 {
                    meas.push(spec.peak_near(theory[base + k], 0.02).0);
                }
            }
            rows.push((fr, format!("rigmon (alpha {alpha})"), meas));
        }
        for (tf, case, v) in thesis.iter().filter(|t| t.0 == fr) {
            rows.push((*tf, case.to_string(), v.to_vec()));
        }
    }
    Ok(rows)
}

fn tempfile_dir() -> Result<PathBuf> {
    let d = std::env::temp_dir().join(format!("rigmon-bench-sim-{}", std::process::id()));
    std::fs::create_dir_all(&d).with_context(|| format!("cannot create {}", d.display()))?;
    Ok(d)
}
