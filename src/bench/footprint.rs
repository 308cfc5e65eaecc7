//! `rigmon bench footprint`: the daemon as it runs on the rig — the service binary
//! `rigmon-daemon` (the daemon `rigmon run` runs, without the lab) as a **child process**
//! with a generated config (the shipped replay as a file source at real time, looping: 3
//! acceleration channels at 10 kHz + tacho, no recording, spectrum off) publishing health on
//! Zenoh over loopback TCP to a subscriber in this (the benchmark's) process, once
//! per speed source: the rig file's own (`tacho`, the analog tacho), then `edges` (the same
//! recording with its tacho as edge times in the MCAP), `fixed` and `recording` (its stored
//! 588 rpm) and `estimate`.
//!
//! Measured on the child only: CPU share of one core (utime + stime from /proc/<pid>/stat);
//! resident memory from /proc/<pid>/status: the start-up peak (VmRSS sampled every
//! millisecond until the warm-up ends, and VmHWM), the steady state (VmRSS every 0.5 s
//! while measuring) and what it is made of (RssAnon: private memory; RssFile: mapped code);
//! and latency = health received here - the window's end in wall time (`end_ns`: the
//! source's start time + sample clock). Goals: <= 2 % of one core (target 1 %), <= 30 MB
//! RSS at start-up and in steady state, p99 <= 20 ms for every speed source.

use super::{abs, cpu_seconds, free_port, machine_line, percentile, BenchOptions};
use crate::config::{RigConfig, SpeedConfig};
use crate::publish::zenoh::{ZenohSettings, ZenohSubscriber};
use crate::vocabulary::SpeedSourceKind;
use crate::wire::health::HealthMessage;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const GOAL_CPU_PCT: f64 = 2.0;
const TARGET_CPU_PCT: f64 = 1.0;
const GOAL_RSS_MB: f64 = 30.0;
const GOAL_LATENCY_MS: f64 = 20.0;
/// From the start to the measurement: start-up, the first windows and the page-out of their
/// one-off code 5 s in (`daemon::code_pages`).
const WARMUP_S: f64 = 6.0;
const REPLAY: &str = "replay/lut-outer_race-588rpm.mcap";

/// A `/proc/<pid>/status` memory line in MB.
fn status_mb(pid: u32, key: &str) -> f64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with(key))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Kills the daemon if the benchmark stops early.
struct ChildGuard(Child);
impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One speed source to run the daemon with.
struct Case {
    speed: SpeedSourceKind,
    rig: PathBuf,
    replay: PathBuf,
}

/// What one run of the daemon measured.
#[derive(Debug, Clone, serde::Serialize)]
struct Measured {
    speed_source: SpeedSourceKind,
    seconds: f64,
    cpu_pct: f64,
    /// Start-up peak: the largest VmRSS sampled during the warm-up, and VmHWM at its end.
    rss_startup_peak_mb: f64,
    rss_startup_hwm_mb: f64,
    /// Steady state: VmRSS median and max while measuring, and its parts at the end.
    rss_steady_median_mb: f64,
    rss_steady_max_mb: f64,
    rss_anon_mb: f64,
    rss_file_mb: f64,
    latency_p50_ms: f64,
    latency_p99_ms: f64,
    latency_max_ms: f64,
    /// Health messages measured, those without a speed (the window's speed could not be
    /// found), and the speed sources the messages name.
    received: usize,
    without_speed: usize,
    speed_sources_seen: Vec<SpeedSourceKind>,
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from("config/lut-rig.toml"));
    let model = PathBuf::from("models/lut-rig.onnx");
    let replay = PathBuf::from(REPLAY);
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
    let dir = tempfile::tempdir().context("cannot create a temporary folder for the configs")?;
    let cases = cases(&abs(&rig_path)?, &abs(&replay)?, dir.path())?;
    let model = abs(&model)?;
    let mut runs = Vec::new();
    for case in &cases {
        if !opts.json {
            eprintln!(
                "footprint: speed source {:?}, {WARMUP_S} s warm-up + {seconds} s",
                case.speed
            );
        }
        let m = measure(case, &model, dir.path(), seconds)
            .with_context(|| format!("speed source {:?}", case.speed))?;
        runs.push(m);
    }
    report(opts.json, &replay, &runs);
    Ok(())
}

/// The rig's own speed source first, then every other one the replay can feed.
fn cases(rig_path: &Path, replay: &Path, dir: &Path) -> Result<Vec<Case>> {
    let rig = RigConfig::load(rig_path)?;
    let mut rec = crate::recording::mcap::read_recording(replay)?;
    let rpm = rec
        .rpm
        .with_context(|| format!("{} stores no rpm", replay.display()))?;
    let edges_replay = dir.join("replay-edges.mcap");
    crate::analysis::speed_source::analog_tacho_to_edges(&mut rec, &rig)?;
    crate::recording::mcap::write_recording(&edges_replay, &rec)?;
    let ppr = rig.speed.pulses_per_rev();
    let others: [(SpeedConfig, &Path); 4] = [
        (
            SpeedConfig::Edges {
                pulses_per_rev: ppr,
            },
            &edges_replay,
        ),
        (
            SpeedConfig::Fixed {
                rpm,
                check_within_percent: 10.0,
            },
            replay,
        ),
        (toml::from_str("source = \"recording\"")?, replay),
        (toml::from_str("source = \"estimate\"")?, replay),
    ];
    let own = rig.speed.kind();
    let mut cases = vec![Case {
        speed: own,
        rig: rig_path.to_path_buf(),
        replay: replay.to_path_buf(),
    }];
    for (speed, file) in others.into_iter().filter(|(s, _)| s.kind() != own) {
        let name = speed.kind();
        let path = dir.join(format!("rig-{name}.toml"));
        let r = RigConfig {
            speed,
            ..rig.clone()
        };
        std::fs::write(&path, toml::to_string(&r)?)
            .with_context(|| format!("writing {}", path.display()))?;
        cases.push(Case {
            speed: name,
            rig: path,
            replay: file.to_path_buf(),
        });
    }
    Ok(cases)
}

/// The daemon's config for one case, publishing on `endpoint`.
fn write_config(case: &Case, model: &Path, endpoint: &str, dir: &Path) -> Result<PathBuf> {
    let cfg = dir.join(format!("rigmon-{}.toml", case.speed));
    std::fs::write(
        &cfg,
        format!(
            "rig = {:?}\n[model]\npath = {:?}\n[source]\ntype = \"file\"\npath = {:?}\nspeed = 1.0\nloop = true\n\
             [pipeline]\nspectrum = false\n[zenoh]\nmode = \"peer\"\nlisten = [{:?}]\nmulticast_scouting = false\n\
             [recording]\nenabled = false\n",
            case.rig, model, case.replay, endpoint
        ),
    )
    .with_context(|| format!("writing {}", cfg.display()))?;
    Ok(cfg)
}

/// Health messages received while `counting`: (window end -> received ms, speed source, the
/// window had a speed).
type Received = Arc<Mutex<Vec<(f64, SpeedSourceKind, bool)>>>;

/// A subscriber thread on `endpoint` that records what arrives while `counting` is set.
fn subscribe(
    endpoint: &str,
    counting: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    got: Received,
) -> std::thread::JoinHandle<Result<()>> {
    let settings = ZenohSettings {
        connect: vec![endpoint.to_string()],
        ..ZenohSettings::default()
    };
    std::thread::spawn(move || -> Result<()> {
        let sub = ZenohSubscriber::open(&settings, "rigmon/**/health")?;
        while !stop.load(Ordering::Relaxed) {
            if let Some((_, payload)) = sub.recv_timeout(Duration::from_millis(100))? {
                let now = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as f64;
                if let Ok(m) = serde_json::from_slice::<HealthMessage>(&payload) {
                    if counting.load(Ordering::Relaxed) {
                        let ms = (now - m.window.end_ns as f64) / 1e6;
                        got.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.push((
                            ms,
                            m.speed_source,
                            m.rpm.is_some(),
                        ));
                    }
                }
            }
        }
        sub.close();
        Ok(())
    })
}

/// The service binary systemd starts (`rigmon-daemon`, beside this executable): what the
/// footprint is measured on.
fn service_binary() -> Result<std::path::PathBuf> {
    let me = std::env::current_exe().context("cannot find the rigmon executable")?;
    let exe = me.with_file_name("rigmon-daemon");
    if !exe.exists() {
        bail!(
            "{} is missing: bench footprint measures the service binary; build it beside rigmon \
             (`cargo build --release`)",
            exe.display()
        );
    }
    Ok(exe)
}

/// Run the daemon for one case: warm-up (sampling the start-up peak), then `seconds` of
/// measurement, then SIGTERM.
fn measure(case: &Case, model: &Path, dir: &Path, seconds: f64) -> Result<Measured> {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let cfg = write_config(case, model, &endpoint, dir)?;
    let exe = service_binary()?;
    let child = Command::new(&exe)
        .arg("--config")
        .arg(&cfg)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    let mut child = ChildGuard(child);
    let pid = child.0.id();
    let (counting, stop) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicBool::new(false)),
    );
    let got: Received = Arc::default();
    let sub = subscribe(&endpoint, counting.clone(), stop.clone(), got.clone());

    // Start-up: the resident set every millisecond until the warm-up ends.
    let t0 = Instant::now();
    let mut startup_peak = 0.0f64;
    while t0.elapsed().as_secs_f64() < WARMUP_S {
        let r = status_mb(pid, "VmRSS:");
        if r.is_finite() {
            startup_peak = startup_peak.max(r);
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let startup_hwm = status_mb(pid, "VmHWM:");
    if let Some(st) = child.0.try_wait()? {
        bail!("the daemon exited during warm-up ({st}); its log is above");
    }
    counting.store(true, Ordering::SeqCst);
    let (c0, w0) = (cpu_seconds(pid)?, Instant::now());
    let mut steady = Vec::new();
    while w0.elapsed().as_secs_f64() < seconds {
        std::thread::sleep(Duration::from_millis(500));
        steady.push(status_mb(pid, "VmRSS:"));
    }
    let wall = w0.elapsed().as_secs_f64();
    let cpu_pct = (cpu_seconds(pid)? - c0) / wall * 100.0;
    let (anon, file) = (status_mb(pid, "RssAnon:"), status_mb(pid, "RssFile:"));
    counting.store(false, Ordering::SeqCst);
    stop_daemon(&mut child.0)?;
    stop.store(true, Ordering::SeqCst);
    sub.join()
        .map_err(|_| anyhow::anyhow!("subscriber panicked"))??;

    steady.sort_by(|a, b| a.total_cmp(b));
    let got = got.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.clone();
    let mut lat: Vec<f64> = got.iter().map(|(ms, ..)| *ms).collect();
    lat.sort_by(|a, b| a.total_cmp(b));
    let without_speed = got.iter().filter(|(.., speed)| !speed).count();
    let mut seen: Vec<SpeedSourceKind> = got.into_iter().map(|(_, s, _)| s).collect();
    seen.sort();
    seen.dedup();
    Ok(Measured {
        speed_source: case.speed,
        seconds: wall,
        cpu_pct,
        rss_startup_peak_mb: startup_peak,
        rss_startup_hwm_mb: startup_hwm,
        rss_steady_median_mb: percentile(&steady, 0.5),
        rss_steady_max_mb: steady.last().copied().unwrap_or(f64::NAN),
        rss_anon_mb: anon,
        rss_file_mb: file,
        latency_p50_ms: percentile(&lat, 0.5),
        latency_p99_ms: percentile(&lat, 0.99),
        latency_max_ms: lat.last().copied().unwrap_or(f64::NAN),
        received: lat.len(),
        without_speed,
        speed_sources_seen: seen,
    })
}

/// SIGTERM, then wait up to 15 s for a clean exit.
fn stop_daemon(child: &mut Child) -> Result<()> {
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let t_stop = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait()? {
            break s;
        }
        if t_stop.elapsed() > Duration::from_secs(15) {
            bail!("the daemon did not stop within 15 s of SIGTERM");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    if !status.success() {
        bail!("the daemon exited with {status}");
    }
    Ok(())
}

/// The worst figure of every run, against its goal.
struct Worst {
    cpu: f64,
    startup: f64,
    steady: f64,
    p99: f64,
}

impl Worst {
    fn of(runs: &[Measured]) -> Worst {
        let max = |f: fn(&Measured) -> f64| runs.iter().map(f).fold(0.0, f64::max);
        Worst {
            cpu: max(|m| m.cpu_pct),
            startup: max(startup_peak),
            steady: max(|m| m.rss_steady_max_mb),
            p99: max(|m| m.latency_p99_ms),
        }
    }
}

fn report(json: bool, replay: &Path, runs: &[Measured]) {
    let w = Worst::of(runs);
    if json {
        let j = serde_json::json!({
            "benchmark": "footprint",
            "machine": machine_line(),
            "load_average": crate::usage::load_averages(),
            "process": "rigmon-daemon (child process)",
            "rate": "3 ch x 10 kHz + tacho (replay at real time)",
            "runs": runs,
            "worst": {"cpu_pct": w.cpu, "rss_startup_peak_mb": w.startup, "rss_steady_max_mb": w.steady, "latency_p99_ms": w.p99},
            "goals": {"cpu_pct": GOAL_CPU_PCT, "cpu_target_pct": TARGET_CPU_PCT, "rss_mb": GOAL_RSS_MB, "latency_p99_ms": GOAL_LATENCY_MS},
            "ratios": {"cpu": w.cpu / GOAL_CPU_PCT, "cpu_to_target": w.cpu / TARGET_CPU_PCT, "rss_startup": w.startup / GOAL_RSS_MB, "rss_steady": w.steady / GOAL_RSS_MB, "latency_p99": w.p99 / GOAL_LATENCY_MS},
        });
        println!("{j}");
        return;
    }
    println!(
        "footprint: the service binary rigmon-daemon as a child process, {} replayed at real time (3 ch x 10 kHz + tacho), once per speed source; {}; load average {}",
        replay.display(),
        machine_line(),
        crate::usage::load_averages()
    );
    print_table(runs);
    println!(
        "  worst    CPU {:.2} % of one core (goal {GOAL_CPU_PCT} %: ratio {:.2}; target {TARGET_CPU_PCT} %: {:.2})",
        w.cpu,
        w.cpu / GOAL_CPU_PCT,
        w.cpu / TARGET_CPU_PCT
    );
    println!(
        "           RSS start-up peak {:.1} MB (ratio {:.2}), steady max {:.1} MB (ratio {:.2}; goal {GOAL_RSS_MB} MB both)",
        w.startup,
        w.startup / GOAL_RSS_MB,
        w.steady,
        w.steady / GOAL_RSS_MB
    );
    println!(
        "           latency p99 {:.2} ms, window end -> received (goal {GOAL_LATENCY_MS} ms: ratio {:.2})",
        w.p99,
        w.p99 / GOAL_LATENCY_MS
    );
}

/// One line per run, then a note on windows that had no speed.
fn print_table(runs: &[Measured]) {
    println!(
        "  {:<10} {:>6} | {:>10} {:>6} | {:>10} {:>6} {:>5} {:>5} | {:>7} {:>7} {:>7} {:>4} {:>8}",
        "speed",
        "CPU %",
        "start peak",
        "VmHWM",
        "steady med",
        "max",
        "anon",
        "file",
        "p50 ms",
        "p99 ms",
        "max ms",
        "n",
        "no speed"
    );
    for m in runs {
        println!(
            "  {:<10} {:>6.2} | {:>10.1} {:>6.1} | {:>10.1} {:>6.1} {:>5.1} {:>5.1} | {:>7.2} {:>7.2} {:>7.2} {:>4} {:>8}",
            m.speed_source,
            m.cpu_pct,
            m.rss_startup_peak_mb,
            m.rss_startup_hwm_mb,
            m.rss_steady_median_mb,
            m.rss_steady_max_mb,
            m.rss_anon_mb,
            m.rss_file_mb,
            m.latency_p50_ms,
            m.latency_p99_ms,
            m.latency_max_ms,
            m.received,
            m.without_speed
        );
    }
    for m in runs.iter().filter(|m| m.without_speed > 0) {
        println!(
            "  {}: {} of {} windows had no speed (published `unknown` without features); their latency is that path's",
            m.speed_source, m.without_speed, m.received
        );
    }
}

/// The start-up peak of a run: the sampled maximum or VmHWM, whichever is larger.
fn startup_peak(m: &Measured) -> f64 {
    m.rss_startup_peak_mb.max(m.rss_startup_hwm_mb)
}
