//! The recording sink, built from `[recording]`: raw blocks, features and health to MCAP
//! segments ([`crate::recorder`]), written on the recorder's own thread behind a bounded queue
//! that also closes chunks on time when no message comes.

use super::intake::SourceInfo;
use super::queued_sink::{QueueSettings, QueuedSink, Worker};
use super::sink::{Sink, SinkConfig, SinkContext, SinkReport, WindowEvent};
use crate::acquire::SampleBlock;
use crate::config::{ChannelConfig, ChannelKind, RigConfig, SpeedConfig};
use crate::recorder::{RecordConfig, RecordEvent, RecordStats, Recorder};
use crate::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
use crate::recording::Provenance;
use anyhow::Result;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

/// The recorder on its own thread.
impl Worker for Recorder {
    type Msg = RecordEvent;
    type Stats = RecordStats;

    fn work(&mut self, msg: RecordEvent) {
        self.handle(msg);
    }

    fn idle(&mut self) {
        self.tick();
    }

    fn snapshot(&self, into: &mut RecordStats) {
        into.clone_from(self.stats());
    }

    fn wind_up(self) -> RecordStats {
        self.finish()
    }
}

/// The recorder behind its queue.
pub struct RecordSink {
    queue: QueuedSink<Recorder>,
}

impl SinkConfig for RecordConfig {
    fn build(&self, cx: &SinkContext) -> Result<Option<Box<dyn Sink>>> {
        if !self.enabled {
            return Ok(None);
        }
        let info = recording_info(cx.rig, cx.source, cx.start_ns);
        let recorder = Recorder::new(self.clone(), info, &cx.rig.machine.id)?;
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
                unit: c.unit.clone(),
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
        .map(|c| c.unit.clone())
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
