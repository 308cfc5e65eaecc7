//! `rigmon bench load`: sustained load — 16 acceleration channels at 51.2 kHz plus an analog
//! tacho through the **whole daemon pipeline** (source thread -> bounded queue -> windower ->
//! quality checks and envelope order spectra on all 16 channels -> model -> health state
//! machine -> Zenoh publisher over loopback TCP -> a subscriber in this process) as fast as it
//! goes, for `--seconds` of wall time (default 60 s), with the rig's analog tacho; then the
//! same for a sixth of that time (2-10 s) with each other speed source (`edges`: the
//! generator delivers the tacho's edge times; `fixed`; `recording`: the generator states its
//! 1200 rpm; `estimate`), so the latency is reported per speed source.
//!
//! The source is an in-process generator (it has no hardware to wait for) that blocks when the
//! pipeline's queue is full, so it measures how fast the pipeline consumes. Checked, not just
//! printed, for every speed source: every generated sample reached the windower (no gap on
//! the sample clock), no window failed, and every health message arrived at the subscriber in
//! order. Baseline in the same run: the feature extraction alone on the same windows in this
//! thread, so the ratio says what the queues, model, health logic and publishing cost on top
//! of the DSP. Real-time CPU and RSS at the rig's own rate are `rigmon bench footprint`.

use super::{abs, cpu_seconds, free_port, machine_line, percentile, BenchOptions};
use crate::acquire::{send_block, BlockSender, SampleBlock, Source, SourceStats, StopToken};
use crate::config::{ChannelConfig, ChannelKind, RigConfig, SpeedConfig};
use crate::daemon::config::DaemonConfig;
use crate::daemon::{self, DaemonOptions, Summary};
use crate::dsp::synthetic::Synthetic;
use crate::dsp::{FeaturePipeline, SpeedTrack};
use crate::publish::zenoh::{ZenohSettings, ZenohSubscriber};
use crate::vocabulary::SpeedSourceKind;
use crate::wire::health::HealthMessage;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Channels and rate the issue asks for.
pub const CHANNELS: usize = 16;
pub const SAMPLE_RATE: f64 = 51_200.0;
/// Shaft speed of the generated signal: 20 Hz, so one second holds whole revolutions.
const SHAFT_HZ: f64 = 20.0;
/// Samples per block the generator hands over (80 ms at 51.2 kHz, as a DAQ driver would).
const BLOCK: usize = 4096;

/// One second of 16 channels + tacho, repeated forever on a continuous sample clock.
struct Generator {
    period: Vec<Vec<f32>>,
    tacho: Vec<f32>,
    /// The tacho's rising edges within one period, s from its start.
    edges: Vec<f64>,
}

impl Generator {
    fn new() -> Self {
        // Four different bearing-like signals (fault orders, resonances, noise), each feeding
        // four channels with its own gain, so no two channels are identical.
        let runs: Vec<_> = [
            (3.6, 2500.0, 7),
            (4.9, 3100.0, 8),
            (1.0, 1800.0, 9),
            (5.4, 3600.0, 10),
        ]
        .iter()
        .map(|&(order, res, seed)| {
            Synthetic {
                sample_rate: SAMPLE_RATE,
                seconds: 1.0,
                f_start: SHAFT_HZ,
                f_end: SHAFT_HZ,
                fault_order: order,
                resonance_hz: res,
                damping: 0.05,
                noise: 0.2,
                seed,
                ..Synthetic::default()
            }
            .generate()
        })
        .collect();
        let period = (0..CHANNELS)
            .map(|k| {
                let g = 1.0 + 0.25 * (k / 4) as f32;
                runs[k % 4].vibration.iter().map(|v| g * v).collect()
            })
            .collect();
        Generator {
            tacho: runs[0].tacho.clone(),
            edges: runs[0].edges.clone(),
            period,
        }
    }

    fn len(&self) -> usize {
        self.tacho.len()
    }

    /// The block starting at sample `first` (wrapping around the period), with its tacho as
    /// analog samples or as the edge times inside the block.
    fn block(&self, first: u64, n: usize, tacho: TachoForm) -> SampleBlock {
        let len = self.len();
        let take = |src: &[f32]| -> Vec<f32> {
            (0..n).map(|i| src[((first as usize) + i) % len]).collect()
        };
        let (tacho_analog, tacho_edges) = match tacho {
            TachoForm::Analog => (Some(take(&self.tacho)), Vec::new()),
            TachoForm::Edges => (None, self.edges_in(first, n)),
        };
        SampleBlock {
            first_sample: first,
            sample_rate: SAMPLE_RATE,
            channels: self.period.iter().map(|c| take(c)).collect(),
            tacho_analog,
            tacho_edges,
        }
    }

    /// Edge times (s on the sample clock) in samples `[first, first + n)`.
    fn edges_in(&self, first: u64, n: usize) -> Vec<f64> {
        let (t0, t1) = (
            first as f64 / SAMPLE_RATE,
            (first + n as u64) as f64 / SAMPLE_RATE,
        );
        let period_s = self.len() as f64 / SAMPLE_RATE;
        let p0 = (t0 / period_s).floor() as u64;
        let p1 = (t1 / period_s).ceil() as u64;
        (p0..=p1)
            .flat_map(|p| self.edges.iter().map(move |e| p as f64 * period_s + e))
            .filter(|&t| t >= t0 && t < t1)
            .collect()
    }
}

/// How the generator delivers its tacho.
#[derive(Debug, Clone, Copy, PartialEq)]
enum TachoForm {
    Analog,
    Edges,
}

/// The generator as a daemon source: blocks (never drops) when the pipeline's queue is full.
struct LoadSource {
    generator: Arc<Generator>,
    produced: Arc<AtomicU64>,
    tacho: TachoForm,
    /// The speed it states up front (for `[speed] source = "recording"`).
    nominal_rpm: Option<f64>,
}

impl Source for LoadSource {
    fn describe(&self) -> String {
        format!(
            "load generator {CHANNELS} ch x {SAMPLE_RATE} Hz + tacho ({:?})",
            self.tacho
        )
    }

    fn analog_tacho(&self) -> bool {
        self.tacho == TachoForm::Analog
    }

    fn sample_rate(&self) -> f64 {
        SAMPLE_RATE
    }

    fn nominal_rpm(&self) -> Option<f64> {
        self.nominal_rpm
    }

    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        stats.connected.store(true, Ordering::Relaxed);
        let mut next = 0u64;
        while !stop.is_stopped() {
            let block = self.generator.block(next, BLOCK, self.tacho);
            if !send_block(&tx, block, &stop) {
                break;
            }
            next += BLOCK as u64;
            self.produced.store(next, Ordering::Relaxed);
            SourceStats::add(&stats.blocks, 1);
            SourceStats::add(&stats.samples, BLOCK as u64);
        }
        Ok(())
    }
}

/// The LUT rig file with its three accelerometers replaced by 16 channels at 51.2 kHz.
fn load_rig(base: &Path) -> Result<RigConfig> {
    let mut rig = RigConfig::load(base)?;
    let tacho: Vec<ChannelConfig> = rig
        .channels
        .iter()
        .filter(|c| c.kind != ChannelKind::Acceleration)
        .cloned()
        .collect();
    let template = rig
        .acceleration_channels()
        .next()
        .cloned()
        .context("the rig file has no acceleration channel to copy")?;
    let axes = ["vertical", "horizontal", "axial"];
    let mut chans: Vec<ChannelConfig> = (0..CHANNELS)
        .map(|k| ChannelConfig {
            name: if k == 0 {
                rig.features.classifier_axis.clone()
            } else {
                format!("ch{:02}", k + 1)
            },
            axis: axes[k % 3].to_string(),
            ..template.clone()
        })
        .collect();
    chans.extend(tacho);
    rig.channels = chans;
    rig.acquisition.sample_rate_hz = Some(SAMPLE_RATE);
    rig.machine.id = format!("{}-load", rig.machine.id);
    Ok(rig)
}

/// Feature extraction alone, in this thread, on windows of 4 s of the same generated signal
/// (speed track made once up front): windows per second.
fn baseline(rig: &RigConfig, generator: &Generator, seconds: f64) -> Result<f64> {
    let (thr, hyst, ppr) = match &rig.speed {
        crate::config::SpeedConfig::Tacho {
            threshold,
            hysteresis,
            pulses_per_rev,
            ..
        } => (*threshold, *hysteresis, *pulses_per_rev),
        _ => bail!("the load rig needs an analog tacho ([speed] source = \"tacho\")"),
    };
    let mut pipeline = FeaturePipeline::new(rig, SAMPLE_RATE)?;
    let win = pipeline.window_len();
    let hop = (rig.features.hop_s * SAMPLE_RATE).round() as usize;
    let stretch = generator.block(0, 4 * SAMPLE_RATE as usize, TachoForm::Analog);
    let tacho = stretch.tacho_analog.clone().unwrap_or_default();
    let speed = SpeedTrack::from_analog(&tacho, SAMPLE_RATE, thr, hyst, ppr)?;
    let names: Vec<String> = rig
        .acceleration_channels()
        .map(|c| c.name.clone())
        .collect();
    let starts: Vec<usize> = (0..)
        .map(|k| k * hop)
        .take_while(|s| s + win <= tacho.len())
        .collect();
    let mut views: Vec<(&str, &[f32])> = Vec::with_capacity(names.len());
    let t0 = Instant::now();
    let mut n = 0u64;
    while t0.elapsed().as_secs_f64() < seconds {
        for &s in &starts {
            views.clear();
            views.extend(
                names
                    .iter()
                    .zip(&stretch.channels)
                    .map(|(n, c)| (n.as_str(), &c[s..s + win])),
            );
            pipeline.process_window(s as f64 / SAMPLE_RATE, &views, &speed)?;
            n += 1;
        }
    }
    Ok(n as f64 / t0.elapsed().as_secs_f64())
}

/// One speed source to run the load with.
struct Case {
    speed: SpeedSourceKind,
    config: SpeedConfig,
    tacho: TachoForm,
    nominal_rpm: Option<f64>,
}

/// The rig's analog tacho first, then every other speed source the generator can feed.
fn cases(rig: &RigConfig) -> Result<Vec<Case>> {
    let rpm = SHAFT_HZ * 60.0;
    let case = |config: SpeedConfig, tacho, nominal_rpm| Case {
        speed: config.kind(),
        config,
        tacho,
        nominal_rpm,
    };
    Ok(vec![
        case(rig.speed.clone(), TachoForm::Analog, None),
        case(
            SpeedConfig::Edges {
                pulses_per_rev: rig.speed.pulses_per_rev(),
            },
            TachoForm::Edges,
            None,
        ),
        case(
            SpeedConfig::Fixed {
                rpm,
                check_within_percent: 10.0,
            },
            TachoForm::Analog,
            None,
        ),
        case(
            toml::from_str("source = \"recording\"")?,
            TachoForm::Analog,
            Some(rpm),
        ),
        case(
            toml::from_str("source = \"estimate\"")?,
            TachoForm::Analog,
            None,
        ),
    ])
}

/// What one run of the pipeline measured.
struct LoadRun {
    speed: SpeedSourceKind,
    summary: Summary,
    produced: u64,
    received: u64,
    out_of_order: u64,
    last_seq: u64,
    /// Published -> received, ms, sorted.
    transit: Vec<f64>,
    /// CPU seconds of this process during the run.
    cpu_s: f64,
}

impl LoadRun {
    fn real_time_factor(&self) -> f64 {
        self.summary.samples_in as f64 / SAMPLE_RATE / self.summary.wall_s
    }

    /// What the run got wrong: samples lost, windows missing or failed, messages not received.
    fn problems(&self, rig: &RigConfig) -> Vec<String> {
        let s = &self.summary;
        let win = (rig.features.window_s * SAMPLE_RATE).round() as u64;
        let hop = (rig.features.hop_s * SAMPLE_RATE).round() as u64;
        let expected = self.expected_windows(win, hop);
        let lost = self.lost();
        let mut problems = Vec::new();
        if lost > 0 {
            problems.push(format!("{lost} samples lost"));
        }
        if s.windows != expected {
            problems.push(format!(
                "{} windows for {} samples, expected {expected}",
                s.windows, s.samples_in
            ));
        }
        if s.window_errors > 0 {
            problems.push(format!("{} windows failed", s.window_errors));
        }
        if self.received != s.windows || self.out_of_order > 0 || s.zenoh_dropped > 0 {
            problems.push(format!(
                "subscriber got {} of {} health messages ({} out of order, {} dropped by the publisher)",
                self.received, s.windows, self.out_of_order, s.zenoh_dropped
            ));
        }
        problems
            .iter_mut()
            .for_each(|p| *p = format!("{}: {p}", self.speed));
        problems
    }

    fn expected_windows(&self, win: u64, hop: u64) -> u64 {
        let n = self.summary.samples_in;
        if n >= win {
            (n - win) / hop + 1
        } else {
            0
        }
    }

    fn lost(&self) -> u64 {
        let s = &self.summary;
        s.samples_lost + s.source_samples_lost + (self.produced - s.samples_in)
    }

    /// This run's latency figures as JSON.
    fn latency_json(&self) -> serde_json::Value {
        let s = &self.summary;
        serde_json::json!({
            "pipeline_p50": s.latency_ms_p50,
            "pipeline_p99": s.latency_ms_p99,
            "pipeline_max": s.latency_ms_max,
            "after_end_max": s.after_end_ms_max,
            "publish_to_receive_p50": percentile(&self.transit, 0.5),
            "publish_to_receive_p99": percentile(&self.transit, 0.99),
        })
    }
}

/// What the subscriber saw: messages, how many came out of order, the last sequence number
/// and published -> received per message, ms.
struct Subscribed {
    received: u64,
    out_of_order: u64,
    last_seq: u64,
    transit: Vec<f64>,
}

/// A subscriber over loopback on `endpoint`: counts messages, checks their order and
/// measures published -> received; stops after 1 s of silence once `stop` is set.
fn subscribe(endpoint: &str, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<Result<Subscribed>> {
    let settings = ZenohSettings {
        connect: vec![endpoint.to_string()],
        ..ZenohSettings::default()
    };
    std::thread::spawn(move || -> Result<Subscribed> {
        let sub = ZenohSubscriber::open(&settings, "rigmon/**/health")?;
        let (mut n, mut out_of_order, mut last_seq) = (0u64, 0u64, 0u64);
        let mut transit = Vec::new();
        let mut idle_since: Option<Instant> = None;
        loop {
            match sub.recv_timeout(Duration::from_millis(100))? {
                Some((_, payload)) => {
                    idle_since = None;
                    let now = SystemTime::now().duration_since(UNIX_EPOCH)?.as_nanos() as f64;
                    let m: HealthMessage = serde_json::from_slice(&payload)
                        .context("the subscriber received a health message it cannot parse")?;
                    if m.seq != last_seq + 1 {
                        out_of_order += 1;
                    }
                    last_seq = m.seq;
                    transit.push((now - m.publish_time_ns as f64) / 1e6);
                    n += 1;
                }
                None if stop.load(Ordering::Relaxed) => {
                    // The daemon has finished: stop after 1 s of silence.
                    let t = *idle_since.get_or_insert_with(Instant::now);
                    if t.elapsed() > Duration::from_secs(1) {
                        break;
                    }
                }
                None => {}
            }
        }
        sub.close();
        Ok(Subscribed {
            received: n,
            out_of_order,
            last_seq,
            transit,
        })
    })
}

/// The daemon's config for the load rig file `rig_file`, publishing on `endpoint`.
fn daemon_config(rig_file: &Path, model: &Path, endpoint: &str) -> Result<DaemonConfig> {
    // The LUT model serves the LUT rig renamed `<id>-load`: a foreign model on purpose.
    toml::from_str(&format!(
        "rig = {:?}\n[model]\npath = {:?}\nallow_foreign = true\n[source]\ntype = \"file\"\npath = \"(load generator)\"\n\
         [pipeline]\nspectrum = false\n[zenoh]\nmode = \"peer\"\nlisten = [{:?}]\nmulticast_scouting = false\n\
         [recording]\nenabled = false\n",
        rig_file, model, endpoint
    ))
    .context("building the load configuration")
}

/// A progress bar ticking until `stop`, showing the real-time factor.
fn progress(seconds: f64, stop: Arc<AtomicBool>, produced: Arc<AtomicU64>, speed: SpeedSourceKind) {
    let bar = indicatif::ProgressBar::new(seconds.ceil() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "load ({speed}) {{bar:30}} {{pos}}/{{len}} s {{msg}}"
        ))
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t0 = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(250));
        let s = produced.load(Ordering::Relaxed) as f64 / SAMPLE_RATE;
        bar.set_position(t0.elapsed().as_secs());
        bar.set_message(format!("{:.1}x real time", s / t0.elapsed().as_secs_f64()));
    }
    bar.finish_and_clear();
}

/// Run the whole pipeline on the generator for `seconds` with one speed source.
fn run_case(
    rig: &RigConfig,
    model: &Path,
    case: &Case,
    generator: &Arc<Generator>,
    seconds: f64,
    show_progress: bool,
) -> Result<LoadRun> {
    let dir = tempfile::tempdir().context("cannot create a temporary folder for the rig file")?;
    let rig_file = dir.path().join("load-rig.toml");
    let case_rig = RigConfig {
        speed: case.config.clone(),
        ..rig.clone()
    };
    std::fs::write(&rig_file, toml::to_string(&case_rig)?)
        .with_context(|| format!("writing {}", rig_file.display()))?;
    let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
    let config = daemon_config(&rig_file, model, &endpoint)?;
    let produced = Arc::new(AtomicU64::new(0));
    let source = Box::new(LoadSource {
        generator: generator.clone(),
        produced: produced.clone(),
        tacho: case.tacho,
        nominal_rpm: case.nominal_rpm,
    });
    let sub_stop = Arc::new(AtomicBool::new(false));
    let sub_thread = subscribe(&endpoint, sub_stop.clone());
    let mut dopts = DaemonOptions::new(config);
    dopts.lossless = true;
    dopts.wait_for_subscriber = Some(Duration::from_secs(10));
    let stop = dopts.stop.clone();
    let timer = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_secs_f64(seconds));
            stop.store(true, Ordering::SeqCst);
        })
    };
    let ticker = show_progress.then(|| {
        let (stop, produced, speed) = (stop.clone(), produced.clone(), case.speed);
        std::thread::spawn(move || progress(seconds, stop, produced, speed))
    });
    let cpu0 = cpu_seconds(std::process::id())?;
    let summary = daemon::run_with_source(dopts, source).context("the pipeline failed")?;
    let cpu_s = cpu_seconds(std::process::id())? - cpu0;
    let _ = timer.join();
    if let Some(t) = ticker {
        let _ = t.join();
    }
    sub_stop.store(true, Ordering::SeqCst);
    let mut got = sub_thread
        .join()
        .map_err(|_| anyhow::anyhow!("the subscriber thread panicked"))??;
    got.transit.sort_by(|a, b| a.total_cmp(b));
    Ok(LoadRun {
        speed: case.speed,
        summary,
        produced: produced.load(Ordering::Relaxed),
        received: got.received,
        out_of_order: got.out_of_order,
        last_seq: got.last_seq,
        transit: got.transit,
        cpu_s,
    })
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from("config/lut-rig.toml"));
    let model = abs(Path::new("models/lut-rig.onnx"))?;
    let rig = load_rig(&abs(&rig_path)?)?;
    let seconds = opts.seconds.max(2.0);
    let generator = Arc::new(Generator::new());
    let mut runs = Vec::new();
    for (k, case) in cases(&rig)?.iter().enumerate() {
        // The rig's own tacho for the whole time; each other source for a sixth of it.
        let s = if k == 0 {
            seconds
        } else {
            (seconds / 6.0).clamp(2.0, 10.0)
        };
        runs.push(
            run_case(&rig, &model, case, &generator, s, !opts.json)
                .with_context(|| format!("speed source {:?}", case.speed))?,
        );
    }
    let base = baseline(&rig, &generator, (seconds / 6.0).clamp(2.0, 10.0))?;
    let problems: Vec<String> = runs.iter().flat_map(|r| r.problems(&rig)).collect();
    if opts.json {
        println!("{}", report_json(&rig, &runs, base, &problems));
    } else {
        report_text(&runs, base);
    }
    if !problems.is_empty() {
        bail!("load benchmark failed: {}", problems.join("; "));
    }
    Ok(())
}

/// The JSON report: the main run's figures at the top, every speed source's in `speed_sources`.
fn report_json(
    rig: &RigConfig,
    runs: &[LoadRun],
    base: f64,
    problems: &[String],
) -> serde_json::Value {
    let main = &runs[0];
    let s = &main.summary;
    let win = (rig.features.window_s * SAMPLE_RATE).round() as u64;
    let hop = (rig.features.hop_s * SAMPLE_RATE).round() as u64;
    let windows_per_s = s.windows as f64 / s.wall_s;
    let per_source: Vec<serde_json::Value> = runs
        .iter()
        .map(|r| {
            serde_json::json!({
                "speed_source": r.speed,
                "wall_s": r.summary.wall_s,
                "real_time_factor": r.real_time_factor(),
                "windows": r.summary.windows,
                "samples_lost": r.lost(),
                "latency_ms": r.latency_json(),
                "ok": r.problems(rig).is_empty(),
            })
        })
        .collect();
    serde_json::json!({
        "benchmark": "load",
        "machine": machine_line(),
        "rate": format!("{CHANNELS} ch x {SAMPLE_RATE} Hz + analog tacho, as fast as the pipeline goes"),
        "speed_source": main.speed,
        "wall_s": s.wall_s,
        "signal_s": s.samples_in as f64 / SAMPLE_RATE,
        "real_time_factor": main.real_time_factor(),
        "samples_per_s": s.samples_in as f64 * CHANNELS as f64 / s.wall_s,
        "windows": s.windows,
        "windows_expected": main.expected_windows(win, hop),
        "samples_generated": main.produced,
        "samples_in": s.samples_in,
        "samples_lost": main.lost(),
        "window_errors": s.window_errors,
        "received": main.received,
        "received_out_of_order": main.out_of_order,
        "last_seq": main.last_seq,
        "process_cpu_pct": main.cpu_s / s.wall_s * 100.0,
        "latency_ms": main.latency_json(),
        "speed_sources": per_source,
        "baseline": {"what": "features alone, 16 channels, this thread", "windows_per_s": base},
        "ratio_to_baseline": windows_per_s / base,
        "states": s.states,
        "ok": problems.is_empty(),
        "problems": problems,
    })
}

fn report_text(runs: &[LoadRun], base: f64) {
    let main = &runs[0];
    let s = &main.summary;
    let (wall, rt) = (s.wall_s, main.real_time_factor());
    let windows_per_s = s.windows as f64 / wall;
    println!(
        "load: {CHANNELS} ch x {:.1} kHz + analog tacho through the whole pipeline for {wall:.1} s; {}",
        SAMPLE_RATE / 1e3,
        machine_line()
    );
    println!(
        "  throughput  {:.2} M samples/s ({rt:.2}x real time), {:.1} s of signal, {} windows ({windows_per_s:.1}/s)",
        s.samples_in as f64 * CHANNELS as f64 / wall / 1e6,
        s.samples_in as f64 / SAMPLE_RATE,
        s.windows
    );
    println!(
        "  lost        {} samples ({} generated, {} windowed); {} window errors; {}/{} health messages received in order",
        main.lost(),
        main.produced,
        s.samples_in,
        s.window_errors,
        main.received,
        s.windows
    );
    println!(
        "  baseline    features alone: {base:.1} windows/s in one thread; whole pipeline {windows_per_s:.1} windows/s (ratio {:.2}); process CPU {:.0} % of one core",
        windows_per_s / base,
        main.cpu_s / wall * 100.0
    );
    println!(
        "  latency per speed source: window complete -> published p50 / p99 / max ms; signal past a window's end when analysed (max, ms: the 80 ms blocks); published -> received p99 ms"
    );
    for r in runs {
        let s = &r.summary;
        println!(
            "    {:<10} {:6.2} / {:6.2} / {:6.2}   after end {:5.1}   transit {:5.2}   ({:.1} s, {:.2}x real time, {} windows, {} lost)",
            r.speed,
            s.latency_ms_p50,
            s.latency_ms_p99,
            s.latency_ms_max,
            s.after_end_ms_max,
            percentile(&r.transit, 0.99),
            s.wall_s,
            r.real_time_factor(),
            s.windows,
            r.lost()
        );
    }
}
