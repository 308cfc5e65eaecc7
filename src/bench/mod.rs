//! `rigmon bench`: throughput and speed benchmarks that print ratios against a baseline
//! measured in the same run. One file per benchmark; results go in the README with the
//! machine they ran on (see [`machine_line`]).

pub mod calibrate;
pub mod features;
pub mod footprint;
pub mod historian;
pub mod load;
pub mod simulate;
pub mod speed;

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

/// CPU seconds (user + system) of a process, from /proc/<pid>/stat.
pub(crate) fn cpu_seconds(pid: u32) -> Result<f64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .with_context(|| format!("reading /proc/{pid}/stat (did the daemon exit?)"))?;
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = s.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime, stime are fields 14 and 15 of stat(5); f[0] is field 3.
    let ticks = |i: usize| {
        f.get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    Ok((ticks(11) + ticks(12)) / hz)
}

/// The `p`-quantile of sorted values (nearest rank); NaN when empty.
pub(crate) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// CPU time consumed by the calling thread, s (independent of other load on the machine).
pub(crate) fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}
