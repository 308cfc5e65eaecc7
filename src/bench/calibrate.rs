//! `rigmon bench calibrate`: wall time of one calibration ([`fit::calibrate`]) of measured
//! recordings analysed whole, against the same calibration the way it ran before
//! ([`fit::Options::baseline`]: each recording as one piece with a twin as long as it, the
//! trials of a round one after the other, the engine cache emptied when full), in the same
//! run on the same data. Default data: the independent generator's `speed_fluctuation` case
//! (`tests/python/measured_like.py`, six recordings of 20 s, seed 1); `--measured` takes any
//! `labels.csv`, `--seconds` cuts each recording (default: whole).

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
    /// CPU time of the process (user + system, all threads) during the run.
    cpu_seconds: f64,
    /// The 1-minute load average at the start and at the end of the run (other jobs on the
    /// machine show here).
    load: (f64, f64),
    outcome: fit::Outcome,
}

fn one(
    rig: &RigConfig,
    ops: &[measured::Measured],
    part: &[bool],
    options: fit::Options,
) -> Result<Timed> {
    let load = || load_1min().unwrap_or(f64::NAN);
    let (l0, c0, t0) = (load(), process_cpu_s(), Instant::now());
    let outcome = fit::calibrate_with(rig, ops, part.to_vec(), options)?;
    Ok(Timed {
        seconds: t0.elapsed().as_secs_f64(),
        cpu_seconds: process_cpu_s() - c0,
        load: (l0, load()),
        outcome,
    })
}

/// The per-stage times of one calibration, one line.
fn stages(o: &fit::Outcome) -> String {
    o.timings
        .iter()
        .map(|t| format!("{} {:.1} s ({} calls)", t.stage, t.seconds, t.calls))
        .collect::<Vec<_>>()
        .join(", ")
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
        "  {what:<9} {:.1} s (CPU {:.1} s, load {:.1} -> {:.1})  {}",
        t.seconds,
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
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| shipped("config/lut-rig.toml"));
    let rig = RigConfig::load(&rig_path)?;
    let labels = match measured_path {
        Some(p) => p,
        None => generate("speed_fluctuation")?,
    };
    let inputs = std::slice::from_ref(&labels);
    let ops = measured::load(&rig, inputs, analysed.unwrap_or(f64::INFINITY))?;
    let part = measured::checkerboard(&ops);
    let signal: f64 = ops.iter().map(|m| m.recording.duration_s()).sum();
    eprintln!(
        "bench calibrate: {} recordings, {:.1} s of signal from {}",
        ops.len(),
        signal,
        labels.display()
    );
    let new = one(&rig, &ops, &part, fit::Options::default())?;
    progress("now:", &new);
    let old = one(&rig, &ops, &part, fit::Options::baseline())?;
    progress("baseline:", &old);
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
            })
        );
    } else {
        println!("machine: {}", machine_line());
        println!(
            "calibration of {} recordings ({:.1} s of signal, analysed whole): {:.1} s \
             (CPU {:.1} s, load average {:.1} -> {:.1}); the same calibration before (one \
             piece per recording, serial trials, engine cache emptied when full): {:.1} s \
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
