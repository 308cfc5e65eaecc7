//! The Zenoh sink, built from `[zenoh]`: health per window (and the classifier channel's
//! envelope order spectrum when `pipeline.spectrum` is on), status messages and the running
//! config, published from the publisher's own thread behind a bounded queue.

use super::config::DaemonConfig;
use super::queued_sink::{QueueSettings, QueuedSink, Worker};
use super::sink::{Sink, SinkConfig, SinkContext, SinkReport, WindowEvent};
use crate::publish::zenoh::{ZenohPublisher, ZenohSettings};
use crate::wire::spectrum::{self, SpectrumMessage};
use crate::wire::status::PublishStats;
use crate::wire::status::StatusMessage;
use anyhow::Result;

/// Messages for the Zenoh thread.
pub enum ZenohMsg {
    Health(Vec<u8>),
    Spectrum(Vec<u8>),
    Status(Vec<u8>),
    /// New running config for the `config` queryable.
    Config(Vec<u8>),
}

impl Worker for ZenohPublisher {
    type Msg = ZenohMsg;
    type Stats = PublishStats;

    fn work(&mut self, msg: ZenohMsg) {
        match msg {
            ZenohMsg::Health(b) => self.put_health(b),
            ZenohMsg::Spectrum(b) => self.put_spectrum(b),
            ZenohMsg::Status(b) => self.put_status(b),
            ZenohMsg::Config(b) => self.set_config(b),
        }
    }

    fn snapshot(&self, into: &mut PublishStats) {
        *into = self.stats();
    }

    fn wind_up(self) -> PublishStats {
        let stats = self.stats();
        self.close();
        stats
    }
}

/// The publisher behind its queue.
pub struct ZenohSink {
    queue: QueuedSink<ZenohPublisher>,
    /// Publish the spectrum on `.../spectrum` too.
    spectrum: bool,
    bin_width_order: f64,
}

impl SinkConfig for ZenohSettings {
    fn build(&self, cx: &SinkContext) -> Result<Option<Box<dyn Sink>>> {
        if !self.enabled {
            return Ok(None);
        }
        let m = &cx.rig.machine;
        let base_key = self.base_key(&m.id, &m.asset, &m.point);
        let config_json = serde_json::to_vec(cx.config).unwrap_or_default();
        let publisher = ZenohPublisher::open(self, &base_key, config_json)?;
        tracing::info!(
            "publishing on {base_key}/{{health,spectrum,status}} (zenoh {} {:?} listen {:?} connect {:?})",
            publisher.session().zid(),
            self.mode.as_str(),
            self.listen,
            self.connect
        );
        if let Some(t) = cx.wait_for_subscriber {
            if !publisher.wait_for_subscriber(t) {
                tracing::warn!("no subscriber on {base_key}/health after {t:?}; starting anyway");
            }
        }
        let settings = QueueSettings {
            thread: "rigmon-zenoh",
            capacity: cx.config.pipeline.sink_queue,
            delivery: cx.delivery,
            idle_every: None,
        };
        Ok(Some(Box::new(ZenohSink {
            queue: QueuedSink::spawn(publisher, settings)?,
            spectrum: cx.config.pipeline.spectrum,
            bin_width_order: cx.rig.features.bin_width_order,
        })))
    }
}

impl Sink for ZenohSink {
    fn on_window(&mut self, w: &WindowEvent) {
        self.queue.send(ZenohMsg::Health(w.health_json.to_vec()));
        let Some(fw) = w.features.filter(|_| self.spectrum) else {
            return;
        };
        let msg = w.health;
        let s = SpectrumMessage {
            schema: spectrum::SCHEMA.to_string(),
            schema_version: spectrum::SCHEMA_VERSION,
            rig: msg.rig.clone(),
            asset: msg.asset.clone(),
            point: msg.point.clone(),
            seq: msg.seq,
            bin_width_order: self.bin_width_order,
            window: fw,
        };
        self.queue.send(ZenohMsg::Spectrum(
            serde_json::to_vec(&s).unwrap_or_default(),
        ));
    }

    fn on_status(&mut self, status: &StatusMessage) {
        self.queue.send(ZenohMsg::Status(
            serde_json::to_vec(status).unwrap_or_default(),
        ));
    }

    fn on_config(&mut self, config: &DaemonConfig) {
        self.queue.send(ZenohMsg::Config(
            serde_json::to_vec(config).unwrap_or_default(),
        ));
    }

    fn report(&self, into: &mut SinkReport) {
        into.dropped.zenoh_dropped = self.queue.dropped();
        into.publish = Some(self.queue.stats());
    }

    fn close(self: Box<Self>) {
        self.queue.close();
    }
}
