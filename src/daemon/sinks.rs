//! Sink threads behind bounded queues: the Zenoh publisher and the MCAP recorder. The
//! pipeline never waits for a slow sink when the source is live: a full queue drops the new
//! message and counts it (status topic `sinks.*_dropped`). Replays use [`Delivery::Wait`].

use crate::publish::zenoh::{PublishStats, ZenohPublisher};
use crate::recorder::{RecordEvent, RecordStats, Recorder};
use anyhow::Result;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// What a sink does when its queue is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Wait for room (replays: nothing may be lost, nothing is live).
    Wait,
    /// Drop the new message and count it (live sources: never stall the pipeline).
    DropNewest,
}

struct Queue<T> {
    tx: SyncSender<T>,
    delivery: Delivery,
    dropped: Arc<AtomicU64>,
}

impl<T> Queue<T> {
    fn send(&self, t: T) {
        match self.delivery {
            Delivery::Wait => {
                if self.tx.send(t).is_err() {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
            Delivery::DropNewest => match self.tx.try_send(t) {
                Ok(()) => {}
                Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {
                    let n = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                    if n == 1 || n.is_power_of_two() {
                        tracing::warn!("a sink is falling behind: {n} messages dropped so far");
                    }
                }
            },
        }
    }
}

/// Messages for the Zenoh thread.
pub enum ZenohMsg {
    Health(Vec<u8>),
    Spectrum(Vec<u8>),
    Status(Vec<u8>),
    /// New running config for the `config` queryable.
    Config(Vec<u8>),
}

/// The Zenoh publisher on its own thread.
pub struct ZenohSink {
    queue: Queue<ZenohMsg>,
    stats: Arc<Mutex<PublishStats>>,
    handle: JoinHandle<()>,
}

impl ZenohSink {
    pub fn spawn(
        mut publisher: ZenohPublisher,
        capacity: usize,
        delivery: Delivery,
    ) -> Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<ZenohMsg>(capacity);
        let stats = Arc::new(Mutex::new(PublishStats::default()));
        let st = stats.clone();
        let handle = std::thread::Builder::new()
            .name("rigmon-zenoh".into())
            .spawn(move || {
                while let Ok(m) = rx.recv() {
                    match m {
                        ZenohMsg::Health(b) => publisher.put_health(b),
                        ZenohMsg::Spectrum(b) => publisher.put_spectrum(b),
                        ZenohMsg::Status(b) => publisher.put_status(b),
                        ZenohMsg::Config(b) => publisher.set_config(b),
                    }
                    if let Ok(mut g) = st.lock() {
                        *g = publisher.stats();
                    }
                }
                publisher.close();
            })?;
        Ok(ZenohSink {
            queue: Queue {
                tx,
                delivery,
                dropped: Arc::default(),
            },
            stats,
            handle,
        })
    }

    pub fn send(&self, m: ZenohMsg) {
        self.queue.send(m);
    }

    pub fn dropped(&self) -> u64 {
        self.queue.dropped.load(Ordering::Relaxed)
    }

    pub fn stats(&self) -> PublishStats {
        self.stats.lock().map(|g| *g).unwrap_or_default()
    }

    /// Drain the queue, close the session.
    pub fn close(self) {
        drop(self.queue.tx);
        let _ = self.handle.join();
    }
}

/// The recorder on its own thread (flushing chunks on time even when idle).
pub struct RecordSink {
    queue: Queue<RecordEvent>,
    stats: Arc<Mutex<RecordStats>>,
    handle: JoinHandle<RecordStats>,
}

impl RecordSink {
    pub fn spawn(
        mut recorder: Recorder,
        capacity: usize,
        delivery: Delivery,
        flush_s: f64,
    ) -> Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<RecordEvent>(capacity);
        let stats = Arc::new(Mutex::new(RecordStats::default()));
        let st = stats.clone();
        let tick = Duration::from_secs_f64((flush_s / 2.0).clamp(0.05, 1.0));
        let handle = std::thread::Builder::new()
            .name("rigmon-record".into())
            .spawn(move || {
                loop {
                    match rx.recv_timeout(tick) {
                        Ok(ev) => recorder.handle(ev),
                        Err(RecvTimeoutError::Timeout) => recorder.tick(),
                        Err(RecvTimeoutError::Disconnected) => break,
                    }
                    if let Ok(mut g) = st.lock() {
                        g.clone_from(recorder.stats());
                    }
                }
                recorder.finish()
            })?;
        Ok(RecordSink {
            queue: Queue {
                tx,
                delivery,
                dropped: Arc::default(),
            },
            stats,
            handle,
        })
    }

    pub fn send(&self, ev: RecordEvent) {
        self.queue.send(ev);
    }

    pub fn dropped(&self) -> u64 {
        self.queue.dropped.load(Ordering::Relaxed)
    }

    pub fn stats(&self) -> RecordStats {
        self.stats.lock().map(|g| g.clone()).unwrap_or_default()
    }

    /// Drain the queue and finish the files cleanly.
    pub fn close(self) -> RecordStats {
        drop(self.queue.tx);
        self.handle.join().unwrap_or_default()
    }
}
