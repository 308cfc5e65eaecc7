//! `rigmon bench footprint`: the whole daemon pipeline at the rig's rate (3 acceleration
//! channels at 10 kHz + tacho) in real time — a generator thread releases each 10 ms block at
//! the wall-clock instant its last sample exists, the pipeline computes windows, classifies and
//! publishes health on Zenoh over loopback TCP to a subscriber in the same process. Measured:
//! CPU share of one core (getrusage, whole process, and minus a baseline of generator +
//! subscriber alone measured in the same run), resident memory (VmRSS/VmHWM) and publish
//! latency = health received by the subscriber - wall time of the window's last sample.
//! Goals: <= 2 % of one core, <= 30 MB RSS, <= 20 ms.

use super::{machine_line, BenchOptions};
use crate::acquire::{offer_block, BlockSender, SampleBlock, Source, SourceStats, StopToken};
use crate::config::daemon::{DaemonConfig, ModelConfig, PipelineConfig};
use crate::config::RigConfig;
use crate::daemon::{DaemonOptions, Output};
use crate::health::message::HealthMessage;
use crate::health::HealthPolicy;
use crate::publish::zenoh::{ZenohSettings, ZenohSubscriber};
use crate::record::RecordConfig;
use crate::recording::{Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const GOAL_CPU_PCT: f64 = 2.0;
const GOAL_RSS_MB: f64 = 30.0;
const GOAL_LATENCY_MS: f64 = 20.0;
const BLOCK: usize = 100;

/// Replays a recording's samples at real time, looping, with a continuous sample clock.
struct RealTime {
    rec: Arc<Recording>,
    /// Wall-clock anchor: sample k exists at `t0 + k / fs`.
    t0: Instant,
    edges: Vec<f64>,
}

impl Source for RealTime {
    fn describe(&self) -> String {
        format!(
            "real-time generator ({} ch at {} Hz, looping {})",
            self.rec.channels.len(),
            self.rec.sample_rate,
            self.rec.provenance.source_path
        )
    }
    fn sample_rate(&self) -> f64 {
        self.rec.sample_rate
    }
    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        let fs = self.rec.sample_rate;
        let n = self.rec.len();
        let dur = n as f64 / fs;
        stats.connected.store(true, Ordering::Relaxed);
        let mut k: u64 = 0;
        while !stop.is_stopped() {
            let due = self.t0 + Duration::from_secs_f64((k + BLOCK as u64) as f64 / fs);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            let pass = k / n as u64;
            let i0 = (k % n as u64) as usize;
            let take = BLOCK.min(n - i0);
            let channels: Vec<Vec<f32>> = self
                .rec
                .channels
                .iter()
                .map(|c| c.samples[i0..i0 + take].to_vec())
                .collect();
            let (t_lo, t_hi) = (i0 as f64 / fs, (i0 + take) as f64 / fs);
            let offset = pass as f64 * dur;
            let (tacho_analog, tacho_edges) = match &self.rec.tacho {
                Some(Tacho::Analog { samples, .. }) => {
                    (Some(samples[i0..i0 + take].to_vec()), Vec::new())
                }
                _ => (
                    None,
                    self.edges
                        .iter()
                        .filter(|&&e| e >= t_lo && e < t_hi)
                        .map(|e| e + offset)
                        .collect(),
                ),
            };
            let block = SampleBlock {
                first_sample: k,
                sample_rate: fs,
                channels,
                tacho_analog,
                tacho_edges,
            };
            if !offer_block(&tx, block, &stats) {
                break;
            }
            k += take as u64;
        }
        Ok(())
    }
}

fn cpu_seconds() -> f64 {
    // SAFETY: getrusage fills the struct we pass.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) };
    let t = |tv: libc::timeval| tv.tv_sec as f64 + tv.tv_usec as f64 * 1e-6;
    t(ru.ru_utime) + t(ru.ru_stime)
}

/// (VmRSS, VmHWM) in MB.
fn rss_mb() -> (f64, f64) {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let get = |key: &str| {
        s.lines()
            .find(|l| l.starts_with(key))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1024.0)
    };
    (get("VmRSS:"), get("VmHWM:"))
}

fn free_port() -> Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
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
    let rig = RigConfig::load(&rig_path)?;
    let rec = load_for_rig(&replay, &rig)?;
    if rec.channels.len() != rig.acceleration_channels().count() {
        bail!(
            "{}: {} channels, rig {} has {}",
            replay.display(),
            rec.channels.len(),
            rig.machine.id,
            rig.acceleration_channels().count()
        );
    }
    let rec = Arc::new(rec);
    let seconds = opts.seconds.max(5.0);
    let warmup = 3.0;

    // Baseline: generator + a consumer that only drops blocks, same rate, no pipeline.
    let base_s = (seconds / 3.0).clamp(3.0, 10.0);
    let baseline_cpu = {
        let (tx, rx) = std::sync::mpsc::sync_channel(64);
        let stop = StopToken::new();
        let src = Box::new(RealTime {
            rec: rec.clone(),
            t0: Instant::now(),
            edges: edges_of(&rec),
        });
        let st = stop.clone();
        let h = std::thread::spawn(move || src.run(tx, Arc::new(SourceStats::default()), st));
        let drain = std::thread::spawn(move || while rx.recv().is_ok() {});
        std::thread::sleep(Duration::from_secs(1));
        let (c0, w0) = (cpu_seconds(), Instant::now());
        std::thread::sleep(Duration::from_secs_f64(base_s));
        let share = (cpu_seconds() - c0) / w0.elapsed().as_secs_f64() * 100.0;
        stop.stop();
        let _ = h.join();
        let _ = drain.join();
        share
    };

    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let config = DaemonConfig {
        rig: rig_path.clone(),
        source: crate::acquire::SourceConfig::File(crate::acquire::FileSourceConfig::new(&replay)),
        model: ModelConfig {
            path: model.clone(),
        },
        health: HealthPolicy::default(),
        pipeline: PipelineConfig {
            spectrum: false,
            ..PipelineConfig::default()
        },
        zenoh: ZenohSettings {
            listen: vec![endpoint.clone()],
            ..ZenohSettings::default()
        },
        recording: RecordConfig::default(),
    };
    let t0 = Instant::now();
    let t0_wall_ns = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as f64;
    let source = Box::new(RealTime {
        rec: rec.clone(),
        t0,
        edges: edges_of(&rec),
    });
    let mut dopts = DaemonOptions::new(config);
    dopts.output = Output::None;
    let stop = dopts.stop.clone();
    let daemon = std::thread::Builder::new()
        .name("rigmon-daemon".into())
        .spawn(move || crate::daemon::run_with_source(dopts, source))?;

    // Subscriber in this process, over loopback TCP.
    let sub_settings = ZenohSettings {
        connect: vec![endpoint.clone()],
        ..ZenohSettings::default()
    };
    let latencies: Arc<Mutex<Vec<(f64, f64)>>> = Arc::default();
    let sub_stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let sub_thread = {
        let (lat, stop) = (latencies.clone(), sub_stop.clone());
        std::thread::spawn(move || -> Result<u64> {
            let sub = ZenohSubscriber::open(&sub_settings, "rigmon/**/health")?;
            let mut n = 0;
            while !stop.load(Ordering::Relaxed) {
                if let Some((_, payload)) = sub.recv_timeout(Duration::from_millis(100))? {
                    let now = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as f64;
                    if let Ok(m) = serde_json::from_slice::<HealthMessage>(&payload) {
                        let ms = (now - (t0_wall_ns + m.window.end_s * 1e9)) / 1e6;
                        lat.lock()
                            .map_err(|_| anyhow::anyhow!("poisoned"))?
                            .push((m.window.end_s, ms));
                        n += 1;
                    }
                }
            }
            sub.close();
            Ok(n)
        })
    };

    std::thread::sleep(Duration::from_secs_f64(warmup));
    let (c0, w0) = (cpu_seconds(), Instant::now());
    let mut rss_max = 0.0f64;
    while w0.elapsed().as_secs_f64() < seconds {
        std::thread::sleep(Duration::from_millis(500));
        rss_max = rss_max.max(rss_mb().0);
    }
    let wall = w0.elapsed().as_secs_f64();
    let cpu_total = (cpu_seconds() - c0) / wall * 100.0;
    let (rss_now, hwm) = rss_mb();
    stop.store(true, Ordering::SeqCst);
    let summary = daemon
        .join()
        .map_err(|_| anyhow::anyhow!("daemon thread panicked"))??;
    sub_stop.store(true, Ordering::SeqCst);
    let received = sub_thread
        .join()
        .map_err(|_| anyhow::anyhow!("subscriber panicked"))??;

    let mut lat: Vec<f64> = latencies
        .lock()
        .map_err(|_| anyhow::anyhow!("poisoned"))?
        .iter()
        .filter(|(t, _)| *t > warmup)
        .map(|(_, l)| *l)
        .collect();
    lat.sort_by(|a, b| a.total_cmp(b));
    let (p50, p99, max) = (
        percentile(&lat, 0.5),
        percentile(&lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN),
    );
    let cpu_pipeline = (cpu_total - baseline_cpu).max(0.0);
    let lost = summary.source_samples_lost + summary.samples_lost;

    if opts.json {
        let j = serde_json::json!({
            "benchmark": "footprint",
            "machine": machine_line(),
            "rate": format!("{} ch x {} Hz + tacho", rec.channels.len(), rec.sample_rate),
            "seconds": wall,
            "cpu_pct_total": cpu_total,
            "cpu_pct_baseline": baseline_cpu,
            "cpu_pct_pipeline": cpu_pipeline,
            "rss_mb": rss_max.max(rss_now),
            "rss_peak_mb": hwm,
            "latency_ms": {"p50": p50, "p99": p99, "max": max, "n": lat.len()},
            "windows": summary.windows,
            "received": received,
            "samples_lost": lost,
            "goals": {"cpu_pct": GOAL_CPU_PCT, "rss_mb": GOAL_RSS_MB, "latency_ms": GOAL_LATENCY_MS},
            "ratios": {"cpu": cpu_total / GOAL_CPU_PCT, "rss": hwm / GOAL_RSS_MB, "latency_p99": p99 / GOAL_LATENCY_MS},
        });
        println!("{j}");
    } else {
        println!(
            "footprint: {} ch x {} Hz + tacho in real time for {wall:.1} s; {}",
            rec.channels.len(),
            rec.sample_rate,
            machine_line()
        );
        println!("  CPU      {cpu_total:6.2} % of one core (whole process; goal {GOAL_CPU_PCT} %: ratio {:.2})", cpu_total / GOAL_CPU_PCT);
        println!("           {baseline_cpu:6.2} % baseline (generator + subscriber, no pipeline) -> pipeline {cpu_pipeline:.2} %");
        println!(
            "  RSS      {:6.1} MB now, {hwm:.1} MB peak (goal {GOAL_RSS_MB} MB: ratio {:.2})",
            rss_max.max(rss_now),
            hwm / GOAL_RSS_MB
        );
        println!(
            "  latency  p50 {p50:.2} ms, p99 {p99:.2} ms, max {max:.2} ms over {} health messages (window end -> received; goal {GOAL_LATENCY_MS} ms: ratio {:.2})",
            lat.len(),
            p99 / GOAL_LATENCY_MS
        );
        println!(
            "  windows  {} computed, {received} received, {lost} samples lost",
            summary.windows
        );
    }
    Ok(())
}

fn edges_of(rec: &Recording) -> Vec<f64> {
    match &rec.tacho {
        Some(Tacho::Edges { times_s }) => times_s.clone(),
        _ => Vec::new(),
    }
}

fn load_for_rig(path: &Path, rig: &RigConfig) -> Result<Recording> {
    crate::importers::load(path, rig, &crate::importers::ImportOptions::default())
        .with_context(|| format!("loading {}", path.display()))
}
