//! `rigmon bench`: throughput and speed benchmarks that print ratios against a baseline
//! measured in the same run. One file per benchmark; results go in the README with the
//! machine they ran on (see [`machine_line`]).

pub(crate) mod calibrate;
mod dataset_pair;
pub(crate) mod features;
pub(crate) mod footprint;
pub(crate) mod historian;
mod historian_fleet;
pub(crate) mod load;
pub(crate) mod simulate;
pub(crate) mod speed;

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Options shared by every benchmark.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Rig file (each benchmark has a sensible default).
    pub rig: Option<PathBuf>,
    /// How long to measure, seconds of wall time (or of signal, as the benchmark says).
    pub seconds: f64,
    /// Print one JSON object instead of text.
    pub json: bool,
}

/// One line naming the machine a benchmark ran on (CPU model, cores, build profile).
pub fn machine_line() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let profile = if cfg!(debug_assertions) {
        "debug (use --release for real numbers)"
    } else {
        "release"
    };
    format!("{cpu}, {cores} cores, {profile} build")
}

/// A free TCP port on loopback for a benchmark's own Zenoh session.
pub(crate) fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// `p` made absolute (the benchmarks run from the repository root).
pub(crate) fn abs(p: &Path) -> Result<PathBuf> {
    std::fs::canonicalize(p).with_context(|| {
        format!(
            "{} not found (run from the repository root, or pass --rig)",
            p.display()
        )
    })
}

pub(crate) use crate::usage::cpu_s_of as cpu_seconds;

/// The `p`-quantile of sorted values (nearest rank); NaN when empty.
pub(crate) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

pub(crate) use crate::usage::thread_cpu_s;
