//! `rigmon bench load`: sustained load — 16 acceleration channels at 51.2 kHz plus an analog
//! tacho through the **whole daemon pipeline** (source thread -> bounded queue -> windower ->
//! quality checks and envelope order spectra on all 16 channels -> model -> health state
//! machine -> Zenoh publisher over loopback TCP -> a subscriber in this process) as fast as it
//! goes, for `--seconds` of wall time (default 60 s).
//!
//! The source is an in-process generator (it has no hardware to wait for) that blocks when the
//! pipeline's queue is full, so it measures how fast the pipeline consumes. Checked, not just
//! printed: every generated sample reached the windower (no gap on the sample clock), no
//! window failed, and every health message arrived at the subscriber in order. Baseline in the
//! same run: the feature extraction alone on the same windows in this thread, so the ratio says
//! what the queues, model, health logic and publishing cost on top of the DSP. Real-time
//! CPU and RSS at the rig's own rate are `rigmon bench footprint`.

use super::{abs, cpu_seconds, free_port, machine_line, percentile, BenchOptions};
use crate::acquire::{send_block, BlockSender, SampleBlock, Source, SourceStats, StopToken};
use crate::config::{ChannelConfig, ChannelKind, RigConfig};
use crate::daemon::config::DaemonConfig;
use crate::daemon::{self, DaemonOptions};
use crate::dsp::synthetic::Synthetic;
use crate::dsp::{FeaturePipeline, SpeedTrack};
use crate::health::message::HealthMessage;
use crate::publish::zenoh::{ZenohSettings, ZenohSubscriber};
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
            period,
        }
    }

    fn len(&self) -> usize {
        self.tacho.len()
    }

    /// The block starting at sample `first` (wrapping around the period).
    fn block(&self, first: u64, n: usize) -> SampleBlock {
        let len = self.len();
        let take = |src: &[f32]| -> Vec<f32> {
            (0..n).map(|i| src[((first as usize) + i) % len]).collect()
        };
        SampleBlock {
            first_sample: first,
            sample_rate: SAMPLE_RATE,
            channels: self.period.iter().map(|c| take(c)).collect(),
            tacho_analog: Some(take(&self.tacho)),
            tacho_edges: Vec::new(),
        }
    }
}

/// The generator as a daemon source: blocks (never drops) when the pipeline's queue is full.
struct LoadSource {
    generator: Arc<Generator>,
    produced: Arc<AtomicU64>,
}

impl Source for LoadSource {
    fn describe(&self) -> String {
        format!("load generator {CHANNELS} ch x {SAMPLE_RATE} Hz + analog tacho")
    }

    fn analog_tacho(&self) -> bool {
        true
    }

    fn sample_rate(&self) -> f64 {
        SAMPLE_RATE
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
            let block = self.generator.block(next, BLOCK);
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
    let stretch = generator.block(0, 4 * SAMPLE_RATE as usize);
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

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts
        .rig
        .clone()
        .unwrap_or_else(|| PathBuf::from("config/lut-rig.toml"));
    let model = abs(Path::new("models/lut-rig.onnx"))?;
    let rig = load_rig(&abs(&rig_path)?)?;
    let seconds = opts.seconds.max(2.0);
    let dir = tempfile::tempdir().context("cannot create a temporary folder for the rig file")?;
    let rig_file = dir.path().join("load-rig.toml");
    std::fs::write(&rig_file, toml::to_string(&rig)?)
        .with_context(|| format!("writing {}", rig_file.display()))?;
    let port = free_port()?;
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let config: DaemonConfig = toml::from_str(&format!(
        // The LUT model serves the LUT rig renamed `<id>-load`: a foreign model on purpose.
        "rig = {:?}\n[model]\npath = {:?}\nallow_foreign = true\n[source]\ntype = \"file\"\npath = \"(load generator)\"\n\
         [pipeline]\nspectrum = false\n[zenoh]\nmode = \"peer\"\nlisten = [{:?}]\nmulticast_scouting = false\n\
         [recording]\nenabled = false\n",
        rig_file, model, endpoint
    ))
    .context("building the load configuration")?;

    let generator = Arc::new(Generator::new());
    let produced = Arc::new(AtomicU64::new(0));
    let source = Box::new(LoadSource {
        generator: generator.clone(),
        produced: produced.clone(),
    });

    // Subscriber in this process over loopback: counts messages, checks their order and
    // measures published -> received.
    let sub_settings = ZenohSettings {
        connect: vec![endpoint.clone()],
        ..ZenohSettings::default()
    };
    let sub_stop = Arc::new(AtomicBool::new(false));
    let sub_thread = {
        let stop = sub_stop.clone();
        std::thread::spawn(move || -> Result<(u64, u64, u64, Vec<f64>)> {
            let sub = ZenohSubscriber::open(&sub_settings, "rigmon/**/health")?;
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
            Ok((n, out_of_order, last_seq, transit))
        })
    };

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
    let bar = indicatif::ProgressBar::new(seconds.ceil() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("load {bar:30} {pos}/{len} s {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let ticker = {
        let (bar, stop, produced) = (bar.clone(), stop.clone(), produced.clone());
        std::thread::spawn(move || {
            let t0 = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(250));
                let s = produced.load(Ordering::Relaxed) as f64 / SAMPLE_RATE;
                bar.set_position(t0.elapsed().as_secs());
                bar.set_message(format!("{:.1}x real time", s / t0.elapsed().as_secs_f64()));
            }
        })
    };
    let cpu0 = cpu_seconds(std::process::id())?;
    let summary = daemon::run_with_source(dopts, source).context("the pipeline failed")?;
    let cpu = cpu_seconds(std::process::id())? - cpu0;
    let _ = timer.join();
    let _ = ticker.join();
    bar.finish_and_clear();
    sub_stop.store(true, Ordering::SeqCst);
    let (received, out_of_order, last_seq, mut transit) = sub_thread
        .join()
        .map_err(|_| anyhow::anyhow!("the subscriber thread panicked"))??;
    transit.sort_by(|a, b| a.total_cmp(b));

    let produced = produced.load(Ordering::Relaxed);
    let win = (rig.features.window_s * SAMPLE_RATE).round() as u64;
    let hop = (rig.features.hop_s * SAMPLE_RATE).round() as u64;
    let expected_windows = if summary.samples_in >= win {
        (summary.samples_in - win) / hop + 1
    } else {
        0
    };
    let wall = summary.wall_s;
    let signal_s = summary.samples_in as f64 / SAMPLE_RATE;
    let rt = signal_s / wall;
    let samples_per_s = summary.samples_in as f64 * CHANNELS as f64 / wall;
    let windows_per_s = summary.windows as f64 / wall;
    let base = baseline(&rig, &generator, (seconds / 6.0).clamp(2.0, 10.0))?;
    let lost = summary.samples_lost + summary.source_samples_lost + (produced - summary.samples_in);

    let mut problems = Vec::new();
    if lost > 0 {
        problems.push(format!("{lost} samples lost"));
    }
    if summary.windows != expected_windows {
        problems.push(format!(
            "{} windows for {} samples, expected {expected_windows}",
            summary.windows, summary.samples_in
        ));
    }
    if summary.window_errors > 0 {
        problems.push(format!("{} windows failed", summary.window_errors));
    }
    if received != summary.windows || out_of_order > 0 || summary.zenoh_dropped > 0 {
        problems.push(format!(
            "subscriber got {received} of {} health messages ({out_of_order} out of order, {} dropped by the publisher)",
            summary.windows, summary.zenoh_dropped
        ));
    }

    if opts.json {
        let j = serde_json::json!({
            "benchmark": "load",
            "machine": machine_line(),
            "rate": format!("{CHANNELS} ch x {SAMPLE_RATE} Hz + analog tacho, as fast as the pipeline goes"),
            "wall_s": wall,
            "signal_s": signal_s,
            "real_time_factor": rt,
            "samples_per_s": samples_per_s,
            "windows": summary.windows,
            "windows_expected": expected_windows,
            "samples_generated": produced,
            "samples_in": summary.samples_in,
            "samples_lost": lost,
            "window_errors": summary.window_errors,
            "received": received,
            "received_out_of_order": out_of_order,
            "last_seq": last_seq,
            "process_cpu_pct": cpu / wall * 100.0,
            "latency_ms": {
                "pipeline_p50": summary.latency_ms_p50,
                "pipeline_p99": summary.latency_ms_p99,
                "pipeline_max": summary.latency_ms_max,
                "publish_to_receive_p50": percentile(&transit, 0.5),
                "publish_to_receive_p99": percentile(&transit, 0.99),
            },
            "baseline": {"what": "features alone, 16 channels, this thread", "windows_per_s": base},
            "ratio_to_baseline": windows_per_s / base,
            "states": summary.states,
            "ok": problems.is_empty(),
            "problems": problems,
        });
        println!("{j}");
    } else {
        println!(
            "load: {CHANNELS} ch x {:.1} kHz + analog tacho through the whole pipeline for {wall:.1} s; {}",
            SAMPLE_RATE / 1e3,
            machine_line()
        );
        println!(
            "  throughput  {:.2} M samples/s ({rt:.2}x real time), {signal_s:.1} s of signal, {} windows ({windows_per_s:.1}/s)",
            samples_per_s / 1e6,
            summary.windows
        );
        println!(
            "  lost        {lost} samples ({} generated, {} windowed); {} window errors; {received}/{} health messages received in order",
            produced, summary.samples_in, summary.window_errors, summary.windows
        );
        println!(
            "  latency     window complete -> published: p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms; published -> received: p50 {:.2} ms, p99 {:.2} ms",
            summary.latency_ms_p50,
            summary.latency_ms_p99,
            summary.latency_ms_max,
            percentile(&transit, 0.5),
            percentile(&transit, 0.99)
        );
        println!(
            "  baseline    features alone: {base:.1} windows/s in one thread; whole pipeline {windows_per_s:.1} windows/s (ratio {:.2}); process CPU {:.0} % of one core",
            windows_per_s / base,
            cpu / wall * 100.0
        );
    }
    if !problems.is_empty() {
        bail!("load benchmark failed: {}", problems.join("; "));
    }
    Ok(())
}
