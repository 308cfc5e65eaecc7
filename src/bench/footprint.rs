//! `rigmon bench footprint`: the daemon as it runs on the rig — `rigmon run` as a **child
//! process** with a generated config (the shipped replay as a file source at real time,
//! looping: 3 acceleration channels at 10 kHz + tacho, no recording, spectrum off) publishing
//! health on Zenoh over loopback TCP to a subscriber in this (the benchmark's) process.
//! Measured on the child only: CPU share of one core (utime + stime from /proc/<pid>/stat),
//! resident memory (VmRSS sampled every 0.5 s, VmHWM at the end, from /proc/<pid>/status),
//! and publish latency = health received here - the window's end in wall time (`end_ns`:
//! the source's start time + sample clock). Goals: <= 2 % of one core, <= 30 MB RSS, <= 20 ms.

use super::{abs, cpu_seconds, free_port, machine_line, percentile, BenchOptions};
use crate::health::message::HealthMessage;
use crate::publish::zenoh::{ZenohSettings, ZenohSubscriber};
use anyhow::{bail, Context, Result};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const GOAL_CPU_PCT: f64 = 2.0;
const GOAL_RSS_MB: f64 = 30.0;
const GOAL_LATENCY_MS: f64 = 20.0;

/// A `/proc/<pid>/status` memory line in MB.
fn status_mb(pid: u32, key: &str) -> f64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// (VmRSS, VmHWM) of a process in MB.
fn rss_mb(pid: u32) -> (f64, f64) {
    (status_mb(pid, "VmRSS:"), status_mb(pid, "VmHWM:"))
}

/// Kills the daemon if the benchmark stops early.
struct ChildGuard(Child);
impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from("config/lut-rig.toml"));
    let model = PathBuf::from("models/lut-rig.onnx");
    let replay = PathBuf::from("replay/lut-outer_race-588rpm.mcap");
    for (p, hint) in [
        (&rig_path, "--rig <toml>"),
        (&model, "train it with `rigmon train`"),
        (&replay, "the shipped replays live in replay/"),
    ] {
        if !p.exists() {
            bail!(
                "{} not found (run from the repository root; {hint})",
                p.display()
            );
        }
    }
    let seconds = opts.seconds.max(5.0);
    let warmup = 3.0;
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let dir = tempfile::tempdir().context("cannot create a temporary folder for the config")?;
    let cfg = dir.path().join("rigmon.toml");
    std::fs::write(
        &cfg,
        format!(
            "rig = {:?}\n[model]\npath = {:?}\n[source]\ntype = \"file\"\npath = {:?}\nspeed = 1.0\nloop = true\n\
             [pipeline]\nspectrum = false\n[zenoh]\nmode = \"peer\"\nlisten = [{:?}]\nmulticast_scouting = false\n\
             [recording]\nenabled = false\n",
            abs(&rig_path)?,
            abs(&model)?,
            abs(&replay)?,
            endpoint
        ),
    )
    .with_context(|| format!("writing {}", cfg.display()))?;
    let exe = std::env::current_exe().context("cannot find the rigmon executable")?;
    let child = Command::new(&exe)
        .args(["run", "--config"])
        .arg(&cfg)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .with_context(|| format!("cannot start {} run", exe.display()))?;
    let mut child = ChildGuard(child);
    let pid = child.0.id();

    // Subscriber in this process, over loopback TCP.
    let sub_settings = ZenohSettings {
        connect: vec![endpoint.clone()],
        ..ZenohSettings::default()
    };
    let latencies: Arc<Mutex<Vec<f64>>> = Arc::default();
    let counting = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sub_stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sub_thread = {
        let (lat, stop, counting) = (latencies.clone(), sub_stop.clone(), counting.clone());
        std::thread::spawn(move || -> Result<(u64, u64)> {
            let sub = ZenohSubscriber::open(&sub_settings, "rigmon/**/health")?;
            let (mut n, mut last_seq) = (0, 0);
            while !stop.load(Ordering::Relaxed) {
                if let Some((_, payload)) = sub.recv_timeout(Duration::from_millis(100))? {
                    let now = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as f64;
                    if let Ok(m) = serde_json::from_slice::<HealthMessage>(&payload) {
                        if counting.load(Ordering::Relaxed) {
                            let ms = (now - m.window.end_ns as f64) / 1e6;
                            lat.lock()
                                .map_err(|_| anyhow::anyhow!("poisoned"))?
                                .push(ms);
                            n += 1;
                        }
                        last_seq = m.seq;
                    }
                }
            }
            sub.close();
            Ok((n, last_seq))
        })
    };

    std::thread::sleep(Duration::from_secs_f64(warmup));
    if let Some(st) = child.0.try_wait()? {
        bail!("the daemon exited during warm-up ({st}); its log is above");
    }
    counting.store(true, Ordering::SeqCst);
    let (c0, w0) = (cpu_seconds(pid)?, Instant::now());
    let mut rss_max = 0.0f64;
    let mut rss_samples = Vec::new();
    while w0.elapsed().as_secs_f64() < seconds {
        std::thread::sleep(Duration::from_millis(500));
        let r = rss_mb(pid).0;
        rss_samples.push(r);
        rss_max = rss_max.max(r);
    }
    let wall = w0.elapsed().as_secs_f64();
    let cpu = (cpu_seconds(pid)? - c0) / wall * 100.0;
    let (rss_now, hwm) = rss_mb(pid);
    // What the resident set is made of: private memory vs pages of mapped files (mostly the
    // executable's own code, shared with the page cache and reclaimable).
    let (rss_anon, rss_file) = (status_mb(pid, "RssAnon:"), status_mb(pid, "RssFile:"));
    counting.store(false, Ordering::SeqCst);
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(pid as i32, libc::SIGTERM) };
    let t_stop = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait()? {
            break s;
        }
        if t_stop.elapsed() > Duration::from_secs(15) {
            bail!("the daemon did not stop within 15 s of SIGTERM");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    sub_stop.store(true, Ordering::SeqCst);
    let (received, last_seq) = sub_thread
        .join()
        .map_err(|_| anyhow::anyhow!("subscriber panicked"))??;
    if !status.success() {
        bail!("the daemon exited with {status}");
    }
    rss_samples.sort_by(|a, b| a.total_cmp(b));
    let rss_median = percentile(&rss_samples, 0.5);

    let mut lat = latencies
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .clone();
    lat.sort_by(|a, b| a.total_cmp(b));
    let (p50, p99, max) = (
        percentile(&lat, 0.5),
        percentile(&lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN),
    );

    if opts.json {
        let j = serde_json::json!({
            "benchmark": "footprint",
            "machine": machine_line(),
            "process": "rigmon run (child process)",
            "rate": "3 ch x 10 kHz + tacho (replay at real time)",
            "seconds": wall,
            "cpu_pct": cpu,
            "rss_mb": {"median": rss_median, "max": rss_max.max(rss_now), "hwm": hwm, "anon": rss_anon, "file": rss_file},
            "latency_ms": {"p50": p50, "p99": p99, "max": max, "n": lat.len()},
            "received": received,
            "last_seq": last_seq,
            "goals": {"cpu_pct": GOAL_CPU_PCT, "rss_mb": GOAL_RSS_MB, "latency_ms": GOAL_LATENCY_MS},
            "ratios": {"cpu": cpu / GOAL_CPU_PCT, "rss": hwm / GOAL_RSS_MB, "latency_p99": p99 / GOAL_LATENCY_MS},
        });
        println!("{j}");
    } else {
        println!(
            "footprint: `rigmon run` as a child process, {} replayed at real time (3 ch x 10 kHz + tacho) for {wall:.1} s; {}",
            replay.display(),
            machine_line()
        );
        println!(
            "  CPU      {cpu:6.2} % of one core (daemon process; goal {GOAL_CPU_PCT} %: ratio {:.2})",
            cpu / GOAL_CPU_PCT
        );
        println!(
            "  RSS      {rss_median:6.1} MB median, {:.1} MB max sampled, {hwm:.1} MB peak VmHWM (goal {GOAL_RSS_MB} MB: ratio {:.2})",
            rss_max.max(rss_now),
            hwm / GOAL_RSS_MB
        );
        println!(
            "           {rss_anon:6.1} MB private (RssAnon), {rss_file:.1} MB mapped files (RssFile: the executable's code pages)"
        );
        println!(
            "  latency  p50 {p50:.2} ms, p99 {p99:.2} ms, max {max:.2} ms over {} health messages (window end -> received; goal {GOAL_LATENCY_MS} ms: ratio {:.2})",
            lat.len(),
            p99 / GOAL_LATENCY_MS
        );
        println!("  received {received} health messages while measuring");
    }
    Ok(())
}
