//! The daemon's topology, built from config: source thread -> bounded block queue -> pipeline
//! (rolling windows -> features -> model -> health state machine) -> sinks (Zenoh publisher
//! thread, MCAP recorder thread, stdout), each behind its own bounded queue. Live sources drop
//! (and count) when the pipeline falls behind; file replays wait. The pipeline thread also
//! drives sd_notify (READY, WATCHDOG on progress, STATUS, STOPPING), the status topic and
//! SIGHUP reloads.

pub mod analyze;
pub mod code_pages;
pub mod latency;
pub mod notify;
pub mod reload;
pub mod signals;
pub mod sinks;
pub mod speed_window;
pub mod status;
pub mod velocity;
pub mod windows;

use crate::acquire::{Source, SourceStats, StopToken};
use crate::config::daemon::DaemonConfig;
use crate::health::message::HealthMessage;
use crate::publish::zenoh::ZenohPublisher;
use crate::recorder::{RecordEvent, Recorder};
use crate::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
use analyze::{now_ns, Analyzer};
use anyhow::{Context, Result};
use notify::Notifier;
use serde::Serialize;
use sinks::{Delivery, RecordSink, ZenohMsg, ZenohSink};
use status::{ModelStatus, Phase, PipelineStatus, SinkStatus, SourceStatus, StatusMessage};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::time::{Duration, Instant};
use windows::{WindowSpec, Windower};

/// What to print on stdout, one line per health message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    None,
    Lines,
    Json,
}

/// How to run the daemon.
pub struct DaemonOptions {
    pub config: DaemonConfig,
    /// The file `config` came from (re-read on SIGHUP); None for `rigmon replay`.
    pub config_path: Option<PathBuf>,
    pub output: Output,
    /// Before starting the pipeline, wait up to this long for a health subscriber.
    pub wait_for_subscriber: Option<Duration>,
    /// Sinks wait instead of dropping when their queue is full (replays).
    pub lossless: bool,
    /// React to SIGTERM/SIGINT/SIGHUP (the CLI); tests driving the library use `stop`.
    pub use_signals: bool,
    /// Stop flag for library callers.
    pub stop: Arc<AtomicBool>,
}

impl DaemonOptions {
    pub fn new(config: DaemonConfig) -> Self {
        DaemonOptions {
            config,
            config_path: None,
            output: Output::None,
            wait_for_subscriber: None,
            lossless: false,
            use_signals: false,
            stop: Arc::default(),
        }
    }
}

/// What happened during a run (printed at the end of `rigmon replay`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    pub source: String,
    pub windows: u64,
    /// Windows per smoothed state.
    pub states: BTreeMap<String, u64>,
    /// Windows per window state.
    pub window_states: BTreeMap<String, u64>,
    pub final_state: Option<String>,
    pub samples_in: u64,
    pub samples_lost: u64,
    pub source_samples_lost: u64,
    pub bad_frames: u64,
    pub window_errors: u64,
    pub zenoh_dropped: u64,
    pub record_dropped: u64,
    pub reloads: u64,
    pub reloads_rejected: u64,
    pub latency_ms_max: f64,
    /// Per-window processing latency (last block in -> health out), median and 99th percentile.
    pub latency_ms_p50: f64,
    pub latency_ms_p99: f64,
    pub source_error: Option<String>,
    pub wall_s: f64,
}

impl Summary {
    /// A few lines for a terminal.
    pub fn text(&self) -> String {
        let states: Vec<String> = self
            .states
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let wstates: Vec<String> = self
            .window_states
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let mut s = format!(
            "{} windows from {} in {:.1} s; final state: {}\n  smoothed states: {}\n  window states:   {}\n  samples: {} in, {} lost on the sample clock, {} dropped at the source; {} bad frames; {} window errors; sink drops: zenoh {}, recording {}",
            self.windows,
            self.source,
            self.wall_s,
            self.final_state.as_deref().unwrap_or("-"),
            states.join(", "),
            wstates.join(", "),
            self.samples_in,
            self.samples_lost,
            self.source_samples_lost,
            self.bad_frames,
            self.window_errors,
            self.zenoh_dropped,
            self.record_dropped
        );
        if self.reloads + self.reloads_rejected > 0 {
            s.push_str(&format!(
                "\n  reloads: {} applied, {} rejected",
                self.reloads, self.reloads_rejected
            ));
        }
        if let Some(e) = &self.source_error {
            s.push_str(&format!("\n  source error: {e}"));
        }
        s
    }
}

/// Build everything from the options and run until the source ends or a stop is requested.
pub fn run(opts: DaemonOptions) -> Result<Summary> {
    let rig = opts.config.load_rig()?;
    let source = opts
        .config
        .source
        .build(&rig)
        .context("cannot start the source")?;
    run_with_source(opts, source)
}

/// [`run`] with a source built by the caller (benchmarks, tests); `opts.config.source` is
/// then only reported.
pub fn run_with_source(mut opts: DaemonOptions, source: Box<dyn Source>) -> Result<Summary> {
    let started = Instant::now();
    if opts.use_signals {
        signals::install();
    }
    let mut notifier = Notifier::from_env();
    notifier.status("starting: loading rig, model and source");
    let cfg = opts.config.clone();
    let rig = cfg.load_rig()?;
    let model = reload::load_model(&cfg.model.path, &rig)?;
    let mut model_path = cfg.model.path.clone();

    let describe = source.describe();
    let fs = source.sample_rate();
    let absent = source.absent_channels();
    let nominal = source.nominal_rpm();
    let start_ns = now_ns();
    let mut analyzer = Analyzer::new(
        &rig,
        fs,
        model,
        &reload::model_id(&model_path),
        cfg.health.clone(),
        &absent,
        nominal,
        start_ns,
    )?;
    let spec = WindowSpec::new(fs, rig.features.window_s, rig.features.hop_s)?;
    let tacho_levels = match &rig.speed {
        crate::config::SpeedConfig::Tacho {
            threshold,
            hysteresis,
            ..
        } => Some((*threshold, *hysteresis)),
        _ => None,
    };
    let n_chan = rig.acceleration_channels().count();
    let mut windower = Windower::new(spec, n_chan, tacho_levels);
    let delivery = if opts.lossless {
        Delivery::Wait
    } else {
        Delivery::DropNewest
    };

    // Sinks.
    let base_key = cfg
        .zenoh
        .base_key(&rig.machine.id, &rig.machine.asset, &rig.machine.point);
    let config_json = serde_json::to_vec(&cfg).unwrap_or_default();
    let zenoh = if cfg.zenoh.enabled {
        let publisher = ZenohPublisher::open(&cfg.zenoh, &base_key, config_json)?;
        tracing::info!("publishing on {base_key}/{{health,spectrum,status}} (zenoh {} {:?} listen {:?} connect {:?})", publisher.session().zid(), cfg.zenoh.mode, cfg.zenoh.listen, cfg.zenoh.connect);
        if let Some(t) = opts.wait_for_subscriber {
            if !publisher.wait_for_subscriber(t) {
                tracing::warn!("no subscriber on {base_key}/health after {t:?}; starting anyway");
            }
        }
        Some(ZenohSink::spawn(
            publisher,
            cfg.pipeline.sink_queue,
            delivery,
        )?)
    } else {
        None
    };
    let record = if cfg.recording.enabled {
        let info = RecordingInfo {
            sample_rate: fs,
            start_time_ns: start_ns,
            channels: rig
                .acceleration_channels()
                .map(|c| ChannelInfo {
                    name: c.name.clone(),
                    axis: c.axis.clone(),
                    unit: c.unit.clone(),
                })
                .collect(),
            tacho: match &rig.speed {
                crate::config::SpeedConfig::Tacho { channel, .. } => TachoInfo::Analog {
                    unit: rig
                        .channels
                        .iter()
                        .find(|c| &c.name == channel)
                        .map(|c| c.unit.clone())
                        .unwrap_or_else(|| "V".into()),
                },
                crate::config::SpeedConfig::Edges { .. } => TachoInfo::Edges,
                _ => TachoInfo::None,
            },
            rpm: nominal,
            provenance: crate::recording::Provenance {
                source_path: describe.clone(),
                format: "rigmon-daemon".into(),
                notes: Vec::new(),
            },
            metadata: BTreeMap::from([("rig_id".to_string(), rig.machine.id.clone())]),
        };
        let recorder = Recorder::new(cfg.recording.clone(), info, &rig.machine.id)?;
        Some(RecordSink::spawn(
            recorder,
            cfg.pipeline.sink_queue,
            delivery,
            cfg.recording.flush_s,
        )?)
    } else {
        None
    };

    // Source thread.
    let (tx, rx) = std::sync::mpsc::sync_channel(cfg.pipeline.queue_blocks);
    let stats = Arc::new(SourceStats::default());
    let stop = StopToken::new();
    let source_thread = {
        let (stats, stop) = (stats.clone(), stop.clone());
        std::thread::Builder::new()
            .name("rigmon-source".into())
            .spawn(move || source.run(tx, stats, stop))?
    };

    notifier.ready(&format!(
        "running: {describe}; model {}",
        analyzer.model_id()
    ));
    tracing::info!(
        "pipeline running: {describe} at {fs} Hz, windows {} s / hop {} s",
        rig.features.window_s,
        rig.features.hop_s
    );

    let mut summary = Summary {
        source: describe.clone(),
        ..Default::default()
    };
    let mut reloader = reload::Reloader::default();
    let mut model_status = ModelStatus {
        id: analyzer.model_id().to_string(),
        sha256: analyzer.model().meta().sha256.clone(),
        ..Default::default()
    };
    let mut pipe = PipelineStatus::default();
    let status_every = Duration::from_secs_f64(cfg.pipeline.status_every_s);
    let mut last_status = Instant::now() - status_every;
    let mut newest_t = 0.0f64;
    let mut first_block: Option<(Instant, f64)> = None;
    let mut backlog_run = 0usize;
    let live = cfg.source.kind() != "file";
    let mut behind_since: Option<Instant> = None;
    let mut stdout = std::io::stdout().lock();
    let mut stopping = false;
    let mut last_state: Option<String> = None;
    let mut latencies = latency::LatencyHistogram::default();

    let status_msg = |phase: Phase,
                      pipe: &PipelineStatus,
                      model_status: &ModelStatus,
                      zenoh: &Option<ZenohSink>,
                      record: &Option<RecordSink>,
                      state: &Option<String>,
                      finished: Option<&Result<()>>| StatusMessage {
        schema: status::SCHEMA.into(),
        schema_version: status::SCHEMA_VERSION,
        rig: rig.machine.id.clone(),
        asset: rig.machine.asset.clone(),
        point: rig.machine.point.clone(),
        time_ns: now_ns(),
        uptime_s: started.elapsed().as_secs_f64(),
        phase,
        software_version: env!("CARGO_PKG_VERSION").into(),
        source: SourceStatus {
            describe: describe.clone(),
            connected: stats.connected.load(Ordering::Relaxed),
            blocks: stats.blocks.load(Ordering::Relaxed),
            samples: stats.samples.load(Ordering::Relaxed),
            bad_frames: stats.bad_frames.load(Ordering::Relaxed),
            sequence_gaps: stats.sequence_gaps.load(Ordering::Relaxed),
            samples_lost: stats.samples_lost.load(Ordering::Relaxed),
            reconnects: stats.reconnects.load(Ordering::Relaxed),
            finished: finished.is_some(),
            error: finished
                .and_then(|r| r.as_ref().err())
                .map(|e| format!("{e:#}")),
        },
        pipeline: pipe.clone(),
        model: model_status.clone(),
        sinks: SinkStatus {
            zenoh_dropped: zenoh.as_ref().map_or(0, |z| z.dropped()),
            record_dropped: record.as_ref().map_or(0, |r| r.dropped()),
        },
        publish: zenoh.as_ref().map(|z| z.stats()),
        recording: record.as_ref().map(|r| r.stats()),
        state: state.clone(),
    };

    let source_result: Result<()> = loop {
        if !stopping
            && (opts.stop.load(Ordering::SeqCst) || (opts.use_signals && signals::stop_requested()))
        {
            stopping = true;
            notifier.stopping("stopping: closing sinks");
            tracing::info!("stop requested; finishing");
            stop.stop();
        }
        if opts.use_signals && signals::take_reload() {
            notifier.reloading();
            tracing::info!(
                "SIGHUP: reloading {}",
                opts.config_path
                    .as_ref()
                    .map_or("the model".to_string(), |p| p.display().to_string())
            );
            reloader.start(
                opts.config_path.clone(),
                Some(opts.config.clone()),
                model_path.clone(),
                analyzer.policy().clone(),
                rig.clone(),
            );
        }
        if let Some(r) = reloader.poll() {
            let applied = r.and_then(|l| {
                let reload::Loaded {
                    model,
                    model_id,
                    model_path,
                    policy,
                    config,
                    needs_restart,
                } = l;
                analyzer.swap(model, &model_id, policy)?;
                Ok((model_path, config, needs_restart))
            });
            match applied {
                Ok((path, config, needs)) => {
                    model_path = path;
                    model_status.reloads += 1;
                    model_status.id = analyzer.model_id().to_string();
                    model_status.sha256 = analyzer.model().meta().sha256.clone();
                    if let Some(c) = config {
                        if let Some(z) = &zenoh {
                            z.send(ZenohMsg::Config(serde_json::to_vec(&c).unwrap_or_default()));
                        }
                        opts.config = c;
                    }
                    if !needs.is_empty() {
                        tracing::warn!(
                            "reload: changes to {:?} need a restart and were not applied",
                            needs
                        );
                    }
                    tracing::info!(
                        "reload: now using model {} ({})",
                        model_status.id,
                        &model_status.sha256[..model_status.sha256.len().min(12)]
                    );
                }
                Err(e) => {
                    model_status.reloads_rejected += 1;
                    model_status.last_reload_error = Some(format!("{e:#}"));
                    tracing::error!(
                        "reload rejected, keeping model {}: {e:#}",
                        analyzer.model_id()
                    );
                }
            }
            notifier.reloaded(&format!(
                "running: {describe}; model {}",
                analyzer.model_id()
            ));
        }

        // Blocks already waiting come first; an empty queue means we are keeping up.
        let received = match rx.try_recv() {
            Ok(b) => {
                backlog_run += 1;
                Ok(b)
            }
            Err(_) => {
                backlog_run = 0;
                rx.recv_timeout(Duration::from_millis(50))
            }
        };
        match received {
            Ok(block) => {
                let last_block_at = Instant::now();
                notifier.progress();
                let block = Arc::new(block);
                windower.push(&block);
                if let Some(next) = windower.next_sample() {
                    newest_t = next as f64 / fs;
                    first_block.get_or_insert((Instant::now(), newest_t - block.len() as f64 / fs));
                }
                if let Some(r) = &record {
                    r.send(RecordEvent::Block(block.clone()));
                }
                while let Some(view) = windower.window() {
                    let out = analyzer.analyze(&view);
                    drop(view);
                    windower.advance();
                    let msg = out.health;
                    let latency_ms = last_block_at.elapsed().as_secs_f64() * 1e3;
                    pipe.latency_ms_last = latency_ms;
                    pipe.latency_ms_max = pipe.latency_ms_max.max(latency_ms);
                    latencies.record(latency_ms);
                    *summary.states.entry(msg.state.clone()).or_default() += 1;
                    *summary
                        .window_states
                        .entry(msg.window_state.clone())
                        .or_default() += 1;
                    if msg.state_changed {
                        tracing::info!(
                            "state -> {} at {:.1} s (confidence {:.2})",
                            msg.state,
                            msg.window.end_s,
                            msg.confidence
                        );
                    }
                    emit(
                        &msg,
                        out.features.as_ref(),
                        opts.output,
                        &mut stdout,
                        &zenoh,
                        &record,
                        cfg.pipeline.spectrum,
                        &rig,
                    );
                    last_state = Some(msg.state.clone());
                    pipe.windows += 1;
                }
                let ws = windower.stats();
                pipe.samples_in = ws.samples_in;
                pipe.samples_lost = ws.samples_lost;
                pipe.gaps = ws.gaps;
                pipe.restarts = ws.restarts;
                pipe.window_errors = analyzer.errors;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                break match source_thread.join() {
                    Ok(r) => r,
                    Err(_) => Err(anyhow::anyhow!("the source thread panicked")),
                };
            }
        }

        // Falling behind (live sources): blocks keep waiting in the queue, so every receive
        // returns at once; past half the queue the source starts dropping (and counting) blocks.
        let behind_now = live && backlog_run >= (cfg.pipeline.queue_blocks / 2).max(2);
        if behind_now {
            if behind_since.is_none() {
                tracing::warn!(
                    "processing is falling behind: {backlog_run} blocks waiting in a queue of {}; the source drops what does not fit (status: source.samples_lost = {})",
                    cfg.pipeline.queue_blocks,
                    stats.samples_lost.load(Ordering::Relaxed)
                );
            }
            behind_since = Some(Instant::now());
        } else if behind_since.is_some_and(|t| t.elapsed() > Duration::from_secs(5)) {
            tracing::info!("processing caught up");
            behind_since = None;
        }
        pipe.behind = behind_since.is_some();
        // Wall time minus signal time since the first block: grows when a live source outruns us.
        if let Some((t0_wall, t0_sig)) = first_block.filter(|_| live) {
            pipe.lag_s = (t0_wall.elapsed().as_secs_f64() - (newest_t - t0_sig)).max(0.0);
        }

        notifier.tick(!stats.connected.load(Ordering::Relaxed) || stopping);
        if last_status.elapsed() >= status_every {
            last_status = Instant::now();
            let phase = if stopping {
                Phase::Stopping
            } else if reloader.in_progress() {
                Phase::Reloading
            } else {
                Phase::Running
            };
            let st = status_msg(
                phase,
                &pipe,
                &model_status,
                &zenoh,
                &record,
                &last_state,
                None,
            );
            notifier.status(&status_line(&st));
            if let Some(z) = &zenoh {
                z.send(ZenohMsg::Status(
                    serde_json::to_vec(&st).unwrap_or_default(),
                ));
            }
        }
    };

    if let Err(e) = &source_result {
        tracing::error!("source stopped: {e:#}");
    }
    notifier.stopping("stopping: closing sinks");
    let final_status = status_msg(
        Phase::Finished,
        &pipe,
        &model_status,
        &zenoh,
        &record,
        &last_state,
        Some(&source_result),
    );
    if let Some(z) = &zenoh {
        z.send(ZenohMsg::Status(
            serde_json::to_vec(&final_status).unwrap_or_default(),
        ));
    }
    let _ = stdout.flush();
    summary.zenoh_dropped = zenoh.as_ref().map_or(0, |z| z.dropped());
    summary.record_dropped = record.as_ref().map_or(0, |r| r.dropped());
    if let Some(z) = zenoh {
        z.close();
    }
    if let Some(r) = record {
        let st = r.close();
        if st.write_errors > 0 {
            tracing::warn!(
                "recording had {} write errors; last: {}",
                st.write_errors,
                st.last_error.unwrap_or_default()
            );
        }
    }
    summary.windows = pipe.windows;
    summary.final_state = last_state;
    summary.samples_in = pipe.samples_in;
    summary.samples_lost = pipe.samples_lost;
    summary.source_samples_lost = stats.samples_lost.load(Ordering::Relaxed);
    summary.bad_frames = stats.bad_frames.load(Ordering::Relaxed);
    summary.window_errors = analyzer.errors;
    summary.reloads = model_status.reloads;
    summary.reloads_rejected = model_status.reloads_rejected;
    summary.latency_ms_max = pipe.latency_ms_max;
    summary.latency_ms_p50 = latencies.quantile(0.5);
    summary.latency_ms_p99 = latencies.quantile(0.99);
    summary.source_error = source_result.as_ref().err().map(|e| format!("{e:#}"));
    summary.wall_s = started.elapsed().as_secs_f64();
    if !stopping {
        if let Err(e) = source_result {
            return Err(e.context(format!("source {describe} failed")));
        }
    }
    Ok(summary)
}

/// One status line for systemd (`systemctl status`).
fn status_line(st: &StatusMessage) -> String {
    format!(
        "{}: state {} | {} windows | source {} lost {} bad frames {} | model {}{}{}",
        match st.phase {
            Phase::Running => "running",
            Phase::Reloading => "reloading",
            Phase::Stopping => "stopping",
            Phase::Starting => "starting",
            Phase::Finished => "finished",
        },
        st.state.as_deref().unwrap_or("-"),
        st.pipeline.windows,
        if st.source.connected {
            "connected"
        } else {
            "disconnected"
        },
        st.source.samples_lost + st.pipeline.samples_lost,
        st.source.bad_frames,
        st.model.id,
        if st.pipeline.behind { " | BEHIND" } else { "" },
        match st.recording.as_ref().and_then(|r| r.failed.as_deref()) {
            Some(why) => format!(" | RECORDING FAILED: {why}"),
            None => String::new(),
        }
    )
}

/// Hand one window's results to stdout and the sinks.
#[allow(clippy::too_many_arguments)]
fn emit(
    msg: &HealthMessage,
    features: Option<&crate::dsp::features::FeatureWindow>,
    output: Output,
    stdout: &mut std::io::StdoutLock,
    zenoh: &Option<ZenohSink>,
    record: &Option<RecordSink>,
    spectrum: bool,
    rig: &crate::config::RigConfig,
) {
    let json = serde_json::to_vec(msg).unwrap_or_default();
    match output {
        Output::None => {}
        Output::Lines => {
            let _ = writeln!(stdout, "{}", msg.line());
        }
        Output::Json => {
            let _ = stdout.write_all(&json);
            let _ = stdout.write_all(b"\n");
        }
    }
    if output != Output::None {
        let _ = stdout.flush();
    }
    if let Some(z) = zenoh {
        z.send(ZenohMsg::Health(json.clone()));
        if spectrum {
            if let Some(fw) = features {
                let s = serde_json::json!({
                    "schema": "rigmon.spectrum",
                    "schema_version": 1,
                    "rig": msg.rig, "asset": msg.asset, "point": msg.point,
                    "seq": msg.seq,
                    "bin_width_order": rig.features.bin_width_order,
                    "window": fw,
                });
                z.send(ZenohMsg::Spectrum(
                    serde_json::to_vec(&s).unwrap_or_default(),
                ));
            }
        }
    }
    if let Some(r) = record {
        if let Some(fw) = features {
            r.send(RecordEvent::Features {
                t_ns: msg.window.end_ns,
                json: serde_json::to_vec(fw).unwrap_or_default(),
            });
        }
        r.send(RecordEvent::Health {
            t_ns: msg.window.end_ns,
            json,
        });
    }
}
