//! `rigmon bench calibrate`: wall time of one calibration as `rigmon calibrate` runs it
//! (the recordings loaded, then [`fit::calibrate`]) against the same calibration the way the
//! first pass at issue 37 left it ([`fit::Options::first_issue_37_pass`]: every section a
//! search visits re-runs the whole engine, the `resonance` effect's too, and 8 engine runs
//! are kept per recording), in the same run on the same data. (The way before issue 37,
//! [`fit::Options::before_issue_37`], was 1.36x slower than that pass, and the way before
//! issue 15, [`fit::Options::baseline`], 15x slower; their figures are in
//! docs/calibration-speed.md.) Default data: the independent generator's
//! `speed_fluctuation` case (`tests/python/measured_like.py`, six recordings of 20 s, seed
//! 1); `--measured` takes any `labels.csv`, `--seconds` cuts each recording (default: whole).

use super::{machine_line, BenchOptions};
use crate::calibrate::{fit, measured};
use crate::config::RigConfig;
use crate::usage::{load_1min, process_cpu_s};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Generated recording length, s.
pub const GENERATED_SECONDS: f64 = 20.0;

fn shipped(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Generate the default data set; returns its labels.csv.
fn generate(case: &str) -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("rigmon-bench-cal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let out = Command::new("python3")
        .arg(shipped("tests/python/measured_like.py"))
        .arg("--out")
        .arg(&dir)
        .args(["--case", case, "--seed", "1", "--seconds"])
        .arg(GENERATED_SECONDS.to_string())
        .output()
        .context("running python3 tests/python/measured_like.py (needs numpy)")?;
    if !out.status.success() {
        bail!(
            "measured_like.py failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(dir.join("labels.csv"))
}

struct Timed {
    seconds: f64,
    /// Of which loading the recordings.
    load_seconds: f64,
    /// CPU time of the process (user + system, all threads) during the run.
    cpu_seconds: f64,
    /// The 1-minute load average at the start and at the end of the run (other jobs on the
    /// machine show here).
    load: (f64, f64),
    outcome: fit::Outcome,
}

/// Load and calibrate, timed; also returns the recordings.
fn one(
    rig: &RigConfig,
    inputs: &[PathBuf],
    analysed: f64,
    options: fit::Options,
    parallel_load: bool,
) -> Result<(Timed, Vec<measured::Measured>)> {
    let load = || load_1min().unwrap_or(f64::NAN);
    let (l0, c0, t0) = (load(), process_cpu_s(), Instant::now());
    let ops = measured::load_with(rig, inputs, analysed, parallel_load)?;
    let load_seconds = t0.elapsed().as_secs_f64();
    let part = measured::checkerboard(&ops);
    let outcome = fit::calibrate_with(rig, &ops, part, options)?;
    let t = Timed {
        seconds: t0.elapsed().as_secs_f64(),
        load_seconds,
        cpu_seconds: process_cpu_s() - c0,
        load: (l0, load()),
        outcome,
    };
    Ok((t, ops))
}

/// The per-stage times of one calibration, one line.
fn stages(o: &fit::Outcome) -> String {
    let rounds: Vec<String> = o
        .round_times
        .iter()
        .map(|r| format!("{:.1} s ({} tried)", r.wall_s, r.trials.len()))
        .collect();
    let stages: Vec<String> = o
        .timings
        .iter()
        .map(|t| format!("{} {:.1} s ({} calls)", t.stage, t.seconds, t.calls))
        .collect();
    format!(
        "{}; measured views {:.1} s wall, rounds {}",
        stages.join(", "),
        o.measured_views_wall_s,
        rounds.join(", ")
    )
}

fn summary(o: &fit::Outcome) -> String {
    let effects: Vec<String> = o
        .accepted
        .iter()
        .map(|t| format!("{} {:?}", t.name, t.params))
        .collect();
    format!(
        "error {:.3} -> {:.3}; effects [{}]",
        o.before.total,
        o.after.total,
        effects.join(", ")
    )
}

/// One timed calibration on stderr, as it finishes.
fn progress(what: &str, t: &Timed) {
    eprintln!(
        "  {what:<9} {:.1} s, of which loading {:.1} s (CPU {:.1} s, load {:.1} -> {:.1})  {}",
        t.seconds,
        t.load_seconds,
        t.cpu_seconds,
        t.load.0,
        t.load.1,
        summary(&t.outcome)
    );
    eprintln!("            stages: {}", stages(&t.outcome));
}

pub fn run(
    opts: &BenchOptions,
    measured_path: Option<PathBuf>,
    analysed: Option<f64>,
) -> Result<()> {
    let rig_path = opts.rig.clone();
    let rig = RigConfig::load(&rig_path.unwrap_or_else(|| shipped("config/lut-rig.toml")))?;
    let labels = match measured_path {
        Some(p) => p,
        None => generate("speed_fluctuation")?,
    };
    let inputs = std::slice::from_ref(&labels);
    let analysed = analysed.unwrap_or(f64::INFINITY);
    let (new, ops) = one(&rig, inputs, analysed, fit::Options::default(), true)?;
    let signal: f64 = ops.iter().map(|m| m.recording.duration_s()).sum();
    eprintln!(
        "bench calibrate: {} recordings, {:.1} s of signal from {}",
        ops.len(),
        signal,
        labels.display()
    );
    progress("now:", &new);
    let before = fit::Options::first_issue_37_pass();
    let (old, _) = one(&rig, inputs, analysed, before, true)?;
    progress("before:", &old);
    let ratio = old.seconds / new.seconds;
    if opts.json {
        println!(
            "{}",
            serde_json::json!({
                "machine": machine_line(),
                "recordings": ops.len(),
                "signal_s": signal,
                "seconds": new.seconds,
                "cpu_seconds": new.cpu_seconds,
                "load_average": [new.load.0, new.load.1],
                "baseline_seconds": old.seconds,
                "baseline_cpu_seconds": old.cpu_seconds,
                "baseline_load_average": [old.load.0, old.load.1],
                "speedup": ratio,
                "error": [new.outcome.before.total, new.outcome.after.total],
                "baseline_error": [old.outcome.before.total, old.outcome.after.total],
                "effects": new.outcome.accepted.iter().map(|t| &t.name).collect::<Vec<_>>(),
                "baseline_effects": old.outcome.accepted.iter().map(|t| &t.name).collect::<Vec<_>>(),
                "stages": new.outcome.timings,
                "baseline_stages": old.outcome.timings,
                "load_seconds": new.load_seconds,
                "baseline_load_seconds": old.load_seconds,
                "rounds": new.outcome.round_times,
                "baseline_rounds": old.outcome.round_times,
            })
        );
    } else {
        println!("machine: {}", machine_line());
        println!(
            "load and calibration of {} recordings ({:.1} s of signal, analysed whole): {:.1} s \
             (CPU {:.1} s, load average {:.1} -> {:.1}); the same the previous way (the whole \
             engine re-run for every section tried, resonances too; 8 engine runs kept per \
             recording): {:.1} s \
             (CPU {:.1} s, load average {:.1} -> {:.1}): {:.2}x faster",
            ops.len(),
            signal,
            new.seconds,
            new.cpu_seconds,
            new.load.0,
            new.load.1,
            old.seconds,
            old.cpu_seconds,
            old.load.0,
            old.load.1,
            ratio
        );
    }
    Ok(())
}
