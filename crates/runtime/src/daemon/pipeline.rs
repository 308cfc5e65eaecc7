//! The pipeline: blocks in, rolling windows -> features -> model -> health state machine, and
//! each window's results out to the sinks. It is driven by four events: a block arrived
//! ([`Pipeline::on_block`]), a SIGHUP reload finished ([`Pipeline::on_reload`]), a turn of
//! the loop ([`Pipeline::on_tick`]: backlog, watchdog, status cadence) and the end
//! ([`Pipeline::finish`]: last status, sinks closed, summary). It also drives sd_notify
//! (READY, WATCHDOG on progress, STATUS, RELOADING, STOPPING). Every call into the analysis
//! stage ([`Analyzer`], [`Windower`]) is in this file. Building it (source open, then model
//! loaded) and the first block in end three start-up phases, whose code is dropped at once
//! ([`code_pages::end_of_phase`]).

use super::analyze::{now_ns, Analyzer, WindowOutput};
use super::backlog::Backlog;
use super::code_pages;
use super::config::DaemonConfig;
use super::intake::SourceInfo;
use super::latency::LatencyHistogram;
use super::notify::Notifier;
use super::options::DaemonOptions;
use super::queued_sink::Delivery;
use super::reload::{self, Loaded, Reloader};
use super::sink::{SinkContext, WindowEvent};
use super::sinks::Sinks;
use super::summary::{StateCounts, Summary};
use crate::acquire::{SampleBlock, Source, SourceStats};
use crate::analysis::Windower;
use crate::config::RigConfig;
use crate::model::onnx::OnnxClassifier;
use crate::wire::status::{self, ModelStatus, Phase, PipelineStatus, StatusMessage};
use anyhow::Result;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The daemon's pipeline between the source's queue and the sinks.
pub struct Pipeline {
    rig: RigConfig,
    source: SourceInfo,
    stats: Arc<SourceStats>,
    started: Instant,
    analyzer: Analyzer,
    windower: Windower,
    sinks: Sinks,
    notifier: Notifier,
    reloader: Reloader,
    /// The running config (replaced when a reload brings a new one).
    config: DaemonConfig,
    /// The file `config` came from (re-read on SIGHUP).
    config_path: Option<PathBuf>,
    model_path: PathBuf,
    model: ModelStatus,
    pipe: PipelineStatus,
    backlog: Backlog,
    counts: StateCounts,
    latencies: LatencyHistogram,
    last_state: Option<String>,
    status_every: Duration,
    last_status: Instant,
}

impl Pipeline {
    /// Load the rig and the model, set up the analysis for `source` and build the sinks.
    /// `stats` are the source's counters; `started` is when the run began.
    pub fn build(
        opts: &DaemonOptions,
        source: &dyn Source,
        stats: Arc<SourceStats>,
        started: Instant,
    ) -> Result<Pipeline> {
        // The config read and the source opened (a file replay has read its recording).
        code_pages::end_of_phase("config and source");
        let mut notifier = Notifier::from_env();
        notifier.status("starting: loading rig, model and source");
        let config = opts.config.clone();
        let rig = config.load_rig()?;
        let model = reload::load_model(
            &config.model.path,
            &rig,
            &config.rig,
            config.model.allow_foreign,
        )?;
        code_pages::end_of_phase("model loaded");
        let model_path = config.model.path.clone();
        let info = SourceInfo::of(source);
        let start_ns = now_ns();
        let (analyzer, windower) = analysis(&rig, &info, model, &model_path, &config, start_ns)?;
        let cx = SinkContext {
            rig: &rig,
            config: &config,
            source: &info,
            start_ns,
            delivery: if opts.lossless {
                Delivery::Wait
            } else {
                Delivery::DropNewest
            },
            wait_for_subscriber: opts.wait_for_subscriber,
        };
        let sinks = Sinks::build(&cx, opts.output)?;
        let model_status = ModelStatus {
            id: analyzer.model_id().to_string(),
            sha256: analyzer.model().meta().sha256.clone(),
            ..Default::default()
        };
        let status_every = Duration::from_secs_f64(config.pipeline.status_every_s);
        Ok(Pipeline {
            backlog: Backlog::new(config.source.kind() != "file", config.pipeline.queue_blocks),
            config_path: opts.config_path.clone(),
            source: info,
            analyzer,
            windower,
            sinks,
            notifier,
            reloader: Reloader::default(),
            model_path,
            model: model_status,
            pipe: PipelineStatus::default(),
            counts: StateCounts::default(),
            latencies: LatencyHistogram::default(),
            last_state: None,
            status_every,
            last_status: Instant::now() - status_every,
            rig,
            config,
            stats,
            started,
        })
    }

    /// The source is running: tell systemd and the log.
    pub fn ready(&mut self) {
        self.notifier.ready(&self.running_line());
        tracing::info!(
            "pipeline running: {} at {} Hz, windows {} s / hop {} s",
            self.source.describe,
            self.source.sample_rate,
            self.rig.features.window_s,
            self.rig.features.hop_s
        );
    }

    fn running_line(&self) -> String {
        format!(
            "running: {}; model {}",
            self.source.describe,
            self.analyzer.model_id()
        )
    }

    /// A block arrived: cut every window it completes and hand the results to the sinks.
    pub fn on_block(&mut self, block: SampleBlock) {
        if self.windower.next_sample().is_none() {
            // Sinks open, source running: drop the code that took (no window is waiting yet).
            code_pages::end_of_phase("start-up");
        }
        let block_at = Instant::now();
        self.notifier.progress();
        let block = Arc::new(block);
        self.windower.push(&block);
        if let Some(next) = self.windower.next_sample() {
            let fs = self.source.sample_rate;
            self.backlog
                .saw_block(next as f64 / fs, block.len() as f64 / fs);
        }
        self.sinks.on_block(&block);
        self.drain_windows(block_at);
    }

    /// Analyse every window the cutter has ready and update the pipeline counters.
    fn drain_windows(&mut self, block_at: Instant) {
        let fs = self.source.sample_rate;
        while let Some(view) = self.windower.window() {
            let (end_s, after_end_ms) = (view.t_end, view.after_end as f64 / fs * 1e3);
            let out = self.analyzer.analyze(&view);
            drop(view);
            self.windower.advance();
            self.on_window(out, block_at, end_s, after_end_ms);
        }
        let ws = self.windower.stats();
        self.pipe.samples_in = ws.samples_in;
        self.pipe.samples_lost = ws.samples_lost;
        self.pipe.gaps = ws.gaps;
        self.pipe.restarts = ws.restarts;
        self.pipe.captures = ws.captures;
        self.pipe.window_errors = self.analyzer.errors;
    }

    /// One window's results (`end_s`: its end on the pipeline clock; `after_end_ms`: signal
    /// past it that had arrived): count them, log a state change, emit to the sinks.
    fn on_window(&mut self, out: WindowOutput, block_at: Instant, end_s: f64, after_end_ms: f64) {
        let msg = out.health;
        let latency_ms = block_at.elapsed().as_secs_f64() * 1e3;
        self.pipe.latency_ms_last = latency_ms;
        self.pipe.latency_ms_max = self.pipe.latency_ms_max.max(latency_ms);
        self.pipe.after_end_ms_max = self.pipe.after_end_ms_max.max(after_end_ms);
        let budget = &mut self.pipe.last_window;
        budget.end_s = end_s;
        budget.speed_source.clone_from(&msg.speed_source);
        budget.after_end_ms = after_end_ms;
        budget.processing_ms = latency_ms;
        self.latencies.record(latency_ms);
        self.counts.count(&msg);
        if msg.state_changed {
            tracing::info!(
                "state -> {} at {:.1} s (confidence {:.2})",
                msg.state,
                msg.window.end_s,
                msg.confidence
            );
        }
        let json = serde_json::to_vec(&msg).unwrap_or_default();
        self.sinks.on_window(&WindowEvent {
            health: &msg,
            health_json: &json,
            features: out.features.as_ref(),
        });
        self.last_state = Some(msg.state.clone());
        self.pipe.windows += 1;
    }

    /// SIGHUP: re-read the config and load the model on a helper thread.
    pub fn request_reload(&mut self) {
        self.notifier.reloading();
        tracing::info!(
            "SIGHUP: reloading {}",
            self.config_path
                .as_ref()
                .map_or("the model".to_string(), |p| p.display().to_string())
        );
        self.reloader.start(
            self.config_path.clone(),
            Some(self.config.clone()),
            self.model_path.clone(),
            self.analyzer.policy().clone(),
            self.rig.clone(),
        );
    }

    /// Apply a reload that has finished, if one has.
    pub fn poll_reload(&mut self) {
        if let Some(r) = self.reloader.poll() {
            self.on_reload(r);
        }
    }

    /// A reload finished: swap the model and policy in between two windows, or keep the
    /// running ones when it failed.
    pub fn on_reload(&mut self, loaded: Result<Loaded>) {
        match loaded.and_then(|l| self.swap(l)) {
            Ok((config, needs)) => self.reloaded(config, needs),
            Err(e) => {
                self.model.reloads_rejected += 1;
                self.model.last_reload_error = Some(format!("{e:#}"));
                tracing::error!(
                    "reload rejected, keeping model {}: {e:#}",
                    self.analyzer.model_id()
                );
            }
        }
        self.notifier.reloaded(&self.running_line());
    }

    /// Swap the loaded model and policy in. Returns the new config, if the reload read one,
    /// and the sections whose changes need a restart.
    fn swap(&mut self, l: Loaded) -> Result<(Option<DaemonConfig>, Vec<&'static str>)> {
        let Loaded {
            model,
            model_id,
            model_path,
            policy,
            config,
            needs_restart,
        } = l;
        self.analyzer.swap(model, &model_id, policy)?;
        self.model_path = model_path;
        Ok((config, needs_restart))
    }

    /// The new model is in: count it, publish the new config.
    fn reloaded(&mut self, config: Option<DaemonConfig>, needs_restart: Vec<&'static str>) {
        let m = &mut self.model;
        m.reloads += 1;
        m.id = self.analyzer.model_id().to_string();
        m.sha256 = self.analyzer.model().meta().sha256.clone();
        if let Some(c) = config {
            self.sinks.on_config(&c);
            self.config = c;
        }
        if !needs_restart.is_empty() {
            tracing::warn!(
                "reload: changes to {:?} need a restart and were not applied",
                needs_restart
            );
        }
        // Loading the new model ran tract's parser and optimiser again.
        code_pages::end_of_phase("reload");
        tracing::info!(
            "reload: now using model {} ({})",
            self.model.id,
            &self.model.sha256[..self.model.sha256.len().min(12)]
        );
    }

    /// A stop was asked for.
    pub fn on_stop(&mut self) {
        self.notifier.stopping("stopping: closing sinks");
        tracing::info!("stop requested; finishing");
    }

    /// After every receive: backlog and lag, the watchdog, and a status message when due.
    /// `waiting`: blocks taken back to back from the queue.
    pub fn on_tick(&mut self, waiting: usize, stopping: bool) {
        self.backlog.update(waiting, &self.stats, &mut self.pipe);
        let connected = self.stats.connected.load(Ordering::Relaxed);
        self.notifier.tick(!connected || stopping);
        if self.last_status.elapsed() < self.status_every {
            return;
        }
        self.last_status = Instant::now();
        let phase = if stopping {
            Phase::Stopping
        } else if self.reloader.in_progress() {
            Phase::Reloading
        } else {
            Phase::Running
        };
        let st = self.status(phase, None);
        self.notifier.status(&st.systemd_line());
        self.sinks.on_status(&st);
    }

    /// The status message now; `finished`: how the source ended, once it has.
    fn status(&self, phase: Phase, finished: Option<&Result<()>>) -> StatusMessage {
        let sinks = self.sinks.report();
        let m = &self.rig.machine;
        StatusMessage {
            schema: status::SCHEMA.into(),
            schema_version: status::SCHEMA_VERSION,
            rig: m.id.clone(),
            asset: m.asset.clone(),
            point: m.point.clone(),
            time_ns: now_ns(),
            uptime_s: self.started.elapsed().as_secs_f64(),
            phase,
            software_version: env!("CARGO_PKG_VERSION").into(),
            source: super::source_status::source_status(
                &self.source.describe,
                &self.stats,
                finished,
            ),
            pipeline: self.pipe.clone(),
            model: self.model.clone(),
            sinks: sinks.dropped,
            publish: sinks.publish,
            recording: sinks.recording,
            state: self.last_state.clone(),
        }
    }

    /// The source has ended (`source_result`): last status, close the sinks, summarise.
    /// A source failure is an error unless a stop was asked for (`stopping`).
    pub fn finish(mut self, source_result: Result<()>, stopping: bool) -> Result<Summary> {
        if let Err(e) = &source_result {
            tracing::error!("source stopped: {e:#}");
        }
        self.notifier.stopping("stopping: closing sinks");
        let last = self.status(Phase::Finished, Some(&source_result));
        self.sinks.on_status(&last);
        let dropped = self.sinks.report().dropped;
        self.sinks.close();
        let wall_s = self.started.elapsed().as_secs_f64();
        let summary = Summary::new(&last, self.counts, &self.latencies, dropped, wall_s);
        match source_result {
            Err(e) if !stopping => {
                Err(e.context(format!("source {} failed", self.source.describe)))
            }
            _ => Ok(summary),
        }
    }
}

/// The analysis stage for this rig and source: the window cutter and the analyzer.
fn analysis(
    rig: &RigConfig,
    source: &SourceInfo,
    model: OnnxClassifier,
    model_path: &std::path::Path,
    config: &DaemonConfig,
    start_ns: u64,
) -> Result<(Analyzer, Windower)> {
    let fs = source.sample_rate;
    let analyzer = Analyzer::new(
        rig,
        fs,
        model,
        &reload::model_id(model_path),
        config.health.clone(),
        &source.absent,
        source.nominal_rpm,
        start_ns,
    )?;
    let mut windower = Windower::for_rig(
        &rig.speed,
        &rig.features,
        fs,
        rig.acceleration_channels().count(),
    )?;
    if source.capture_series {
        windower = windower.capture_series();
    }
    Ok((analyzer, windower))
}
