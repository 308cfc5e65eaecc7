//! What this process costs the machine and how busy the machine is: CPU time of the process,
//! of the calling thread or of another process, and the load average. The one copy the
//! benchmarks and `adapt`'s step timings use (a wall time alone says little on a shared
//! machine).

use anyhow::{Context, Result};

/// CPU seconds (user + system, all threads) this process has used so far; NaN where the OS
/// does not tell.
pub fn process_cpu_s() -> f64 {
    // SAFETY: getrusage writes into the zeroed struct we own and reads nothing else.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return f64::NAN;
    }
    let tv = |t: libc::timeval| t.tv_sec as f64 + 1e-6 * t.tv_usec as f64;
    tv(u.ru_utime) + tv(u.ru_stime)
}

/// CPU seconds the calling thread has used (independent of other load on the machine).
pub fn thread_cpu_s() -> f64 {
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

/// CPU seconds (user + system) of another process, from /proc/<pid>/stat.
pub fn cpu_s_of(pid: u32) -> Result<f64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .with_context(|| format!("reading /proc/{pid}/stat (did the process exit?)"))?;
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

/// The 1-minute load average (`/proc/loadavg`); None where the OS does not tell.
pub fn load_1min() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The 1, 5 and 15-minute load averages as the OS writes them ("0.52 0.61 0.70"), or
/// "unknown".
pub fn load_averages() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_times_grow_with_work_and_the_load_reads() {
        let (p0, t0) = (process_cpu_s(), thread_cpu_s());
        let mut x = 0u64;
        for i in 0..20_000_000u64 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(i);
        }
        std::hint::black_box(x);
        assert!(process_cpu_s() > p0 && thread_cpu_s() > t0);
        assert!(cpu_s_of(std::process::id()).unwrap() >= 0.0);
        assert!(load_1min().is_some_and(|l| l >= 0.0));
        assert_eq!(load_averages().split_whitespace().count(), 3);
    }
}
