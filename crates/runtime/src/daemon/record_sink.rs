//! The recording sink, built from `[recording]`: raw blocks, features and health to MCAP
//! segments ([`crate::recorder`]), written on the recorder's own thread behind a bounded queue
//! that also closes chunks on time when no message comes. A recorder that cannot start (its
//! folder cannot be created) never stops monitoring: it is counted and reported as `failed`
//! like a write error, and tried again every [`RETRY`] ([`RecorderSlot`]).

use super::intake::SourceInfo;
use super::queued_sink::{QueueSettings, QueuedSink, Worker};
use super::sink::{Sink, SinkConfig, SinkContext, SinkReport, WindowEvent};
use crate::acquire::SampleBlock;
use crate::config::{ChannelConfig, ChannelKind, RigConfig, SpeedConfig};
use crate::recorder::{RecordConfig, RecordEvent, Recorder};
use crate::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
use crate::recording::Provenance;
use crate::wire::status::RecordStats;
use anyhow::Result;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How long a recorder that could not start waits before it tries again.
pub const RETRY: Duration = Duration::from_secs(5);

/// The recorder, once it could start, and what starting it needs until then.
pub struct RecorderSlot {
    recorder: Option<Recorder>,
    cfg: RecordConfig,
    info: RecordingInfo,
    stem: String,
    next_try: Instant,
    /// Counters while the recorder cannot start ([`Recorder::new`] failed, e.g. its folder
    /// cannot be created): failures, the reason, events dropped meanwhile.
    waiting: RecordStats,
}

impl RecorderSlot {
    /// Start the recorder now, or wait and retry when it cannot start.
    pub fn start(cfg: RecordConfig, info: RecordingInfo, stem: &str) -> Self {
        let mut slot = RecorderSlot {
            recorder: None,
            cfg,
            info,
            stem: stem.to_string(),
            next_try: Instant::now(),
            waiting: RecordStats::default(),
        };
        slot.try_start();
        slot
    }

    /// When not started and the retry is due: try to start the recorder.
    fn try_start(&mut self) {
        if self.recorder.is_some() || Instant::now() < self.next_try {
            return;
        }
        match Recorder::new(self.cfg.clone(), self.info.clone(), &self.stem) {
            Ok(r) => {
                if self.waiting.write_errors > 0 {
                    tracing::info!("recording to {} after all", self.cfg.dir.display());
                }
                self.recorder = Some(r);
            }
            Err(e) => {
                let msg = format!("{e:#}");
                let w = &mut self.waiting;
                w.write_errors += 1;
                if w.write_errors <= 3 || w.write_errors.is_power_of_two() {
                    tracing::error!("recording: {msg}; monitoring continues without recording, retrying in {RETRY:?} (failure {})", w.write_errors);
                }
                w.failed = Some(format!("{}: {msg}", self.cfg.dir.display()));
                w.last_error = Some(msg);
                self.next_try = Instant::now() + RETRY;
            }
        }
    }
}

/// The recorder on its own thread.
impl Worker for RecorderSlot {
    type Msg = RecordEvent;
    type Stats = RecordStats;

    fn work(&mut self, msg: RecordEvent) {
        self.try_start();
        match &mut self.recorder {
            Some(r) => r.handle(msg),
            None => self.waiting.dropped += 1,
        }
    }

    fn idle(&mut self) {
        self.try_start();
        if let Some(r) = &mut self.recorder {
            r.tick();
        }
    }

    fn snapshot(&self, into: &mut RecordStats) {
        match &self.recorder {
            Some(r) => into.clone_from(r.stats()),
            None => into.clone_from(&self.waiting),
        }
    }

    fn wind_up(self) -> RecordStats {
        match self.recorder {
            Some(r) => r.finish(),
            None => self.waiting,
        }
    }
}

/// The recorder behind its queue.
pub struct RecordSink {
    queue: QueuedSink<RecorderSlot>,
}

impl SinkConfig for RecordConfig {
    fn build(&self, cx: &SinkContext) -> Result<Option<Box<dyn Sink>>> {
        if !self.enabled {
            return Ok(None);
        }
        let info = recording_info(cx.rig, cx.source, cx.start_ns);
        let recorder = RecorderSlot::start(self.clone(), info, &cx.rig.machine.id);
        let settings = QueueSettings {
            thread: "rigmon-record",
            capacity: cx.config.pipeline.sink_queue,
            delivery: cx.delivery,
            // Chunks close every `flush_s` even when nothing comes.
            idle_every: Some(Duration::from_secs_f64(
                (self.flush_s / 2.0).clamp(0.05, 1.0),
            )),
        };
        Ok(Some(Box::new(RecordSink {
            queue: QueuedSink::spawn(recorder, settings)?,
        })))
    }
}

/// What the raw layout says about the recording: the rig's acceleration channels, its tacho
/// and the source's rate and nominal speed. The tacho follows what the source delivers as
/// well as the rig's `[speed]` (which says what the daemon computes speed from): a recording
/// replayed with `source = "fixed"` may still hold an analog tacho, and the recorder keeps it.
fn recording_info(rig: &RigConfig, source: &SourceInfo, start_ns: u64) -> RecordingInfo {
    let tacho = match &rig.speed {
        SpeedConfig::Tacho { .. } => TachoInfo::Analog {
            unit: tacho_unit(&rig.speed, &rig.channels),
        },
        _ if source.analog_tacho => TachoInfo::Analog {
            unit: tacho_unit(&rig.speed, &rig.channels),
        },
        SpeedConfig::Edges { .. } => TachoInfo::Edges,
        _ => TachoInfo::None,
    };
    RecordingInfo {
        sample_rate: source.sample_rate,
        start_time_ns: start_ns,
        channels: rig
            .acceleration_channels()
            .map(|c| ChannelInfo {
                name: c.name.clone(),
                axis: c.axis.clone(),
                unit: c.unit.to_string(),
            })
            .collect(),
        tacho,
        rpm: source.nominal_rpm,
        provenance: Provenance {
            source_path: source.describe.clone(),
            format: "rigmon-daemon".into(),
            notes: Vec::new(),
        },
        metadata: BTreeMap::from([("rig_id".to_string(), rig.machine.id.clone())]),
    }
}

/// The unit of the rig's analog tacho: `[speed]`'s tacho channel's, else the first channel of
/// kind tacho, else volts.
fn tacho_unit(speed: &SpeedConfig, channels: &[ChannelConfig]) -> String {
    let named = match speed {
        SpeedConfig::Tacho { channel, .. } => channels.iter().find(|c| &c.name == channel),
        _ => None,
    };
    named
        .or_else(|| channels.iter().find(|c| c.kind == ChannelKind::Tacho))
        .map(|c| c.unit.to_string())
        .unwrap_or_else(|| "V".into())
}

impl Sink for RecordSink {
    fn on_block(&mut self, block: &Arc<SampleBlock>) {
        self.queue.send(RecordEvent::Block(block.clone()));
    }

    fn on_window(&mut self, w: &WindowEvent) {
        let t_ns = w.health.window.end_ns;
        if let Some(fw) = w.features {
            self.queue.send(RecordEvent::Features {
                t_ns,
                json: serde_json::to_vec(fw).unwrap_or_default(),
            });
        }
        self.queue.send(RecordEvent::Health {
            t_ns,
            json: w.health_json.to_vec(),
        });
    }

    fn report(&self, into: &mut SinkReport) {
        into.dropped.record_dropped = self.queue.dropped();
        into.recording = Some(self.queue.stats());
    }

    fn close(self: Box<Self>) {
        let st = self.queue.close();
        if st.write_errors > 0 {
            tracing::warn!(
                "recording had {} write errors; last: {}",
                st.write_errors,
                st.last_error.unwrap_or_default()
            );
        }
    }
}
