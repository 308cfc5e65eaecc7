//! One sink worker on its own thread behind a bounded queue. The pipeline never waits for a
//! slow sink when the source is live: a full queue drops the new message and counts it
//! (status topic `sinks.*_dropped`). Replays use [`Delivery::Wait`]. The Zenoh publisher and
//! the MCAP recorder are both run this way ([`Worker`]).

use anyhow::Result;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
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

/// What runs on a queued sink's thread.
pub trait Worker: Send + 'static {
    /// What the pipeline sends it.
    type Msg: Send + 'static;
    /// Its counters, readable from the pipeline thread while it runs.
    type Stats: Clone + Default + Send + 'static;
    /// Handle one message.
    fn work(&mut self, msg: Self::Msg);
    /// Called when no message came for [`QueueSettings::idle_every`].
    fn idle(&mut self) {}
    /// Copy the current counters into `into`.
    fn snapshot(&self, into: &mut Self::Stats);
    /// The queue is closed and drained: finish and return the last counters.
    fn wind_up(self) -> Self::Stats;
}

/// How a queued sink runs.
#[derive(Debug, Clone, Copy)]
pub struct QueueSettings {
    /// Thread name.
    pub thread: &'static str,
    /// Messages the queue holds.
    pub capacity: usize,
    pub delivery: Delivery,
    /// Call [`Worker::idle`] after this long without a message (None: never).
    pub idle_every: Option<Duration>,
}

/// A [`Worker`] on its own thread behind a bounded queue that counts what it drops.
pub struct QueuedSink<W: Worker> {
    tx: SyncSender<W::Msg>,
    delivery: Delivery,
    dropped: Arc<AtomicU64>,
    stats: Arc<Mutex<W::Stats>>,
    handle: JoinHandle<W::Stats>,
}

impl<W: Worker> QueuedSink<W> {
    /// Start the worker's thread.
    pub fn spawn(worker: W, settings: QueueSettings) -> Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<W::Msg>(settings.capacity);
        let stats = Arc::new(Mutex::new(W::Stats::default()));
        let st = stats.clone();
        let handle = std::thread::Builder::new()
            .name(settings.thread.into())
            .spawn(move || drive(worker, rx, st, settings.idle_every))?;
        Ok(QueuedSink {
            tx,
            delivery: settings.delivery,
            dropped: Arc::default(),
            stats,
            handle,
        })
    }

    /// Queue a message (waiting or dropping when the queue is full, as the delivery says).
    pub fn send(&self, msg: W::Msg) {
        match self.delivery {
            Delivery::Wait => {
                if self.tx.send(msg).is_err() {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                }
            }
            Delivery::DropNewest => match self.tx.try_send(msg) {
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

    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// The worker's counters as of its last message.
    pub fn stats(&self) -> W::Stats {
        self.stats.lock().map(|g| g.clone()).unwrap_or_default()
    }

    /// Drain the queue, let the worker finish, return its last counters.
    pub fn close(self) -> W::Stats {
        let QueuedSink { tx, handle, .. } = self;
        drop(tx);
        handle.join().unwrap_or_default()
    }
}

/// The worker thread: messages until the queue closes, idle calls in between.
fn drive<W: Worker>(
    mut worker: W,
    rx: Receiver<W::Msg>,
    stats: Arc<Mutex<W::Stats>>,
    idle_every: Option<Duration>,
) -> W::Stats {
    loop {
        let next = match idle_every {
            Some(t) => rx.recv_timeout(t),
            None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
        };
        match next {
            Ok(msg) => worker.work(msg),
            Err(RecvTimeoutError::Timeout) => worker.idle(),
            Err(RecvTimeoutError::Disconnected) => break,
        }
        if let Ok(mut g) = stats.lock() {
            worker.snapshot(&mut g);
        }
    }
    worker.wind_up()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::Receiver as Rx;

    /// Counts messages; blocks on `gate` before each one so a test can fill the queue.
    struct Counter {
        gate: Rx<()>,
        seen: u64,
        idles: u64,
    }

    impl Worker for Counter {
        type Msg = u64;
        type Stats = (u64, u64);
        fn work(&mut self, _msg: u64) {
            let _ = self.gate.recv();
            self.seen += 1;
        }
        fn idle(&mut self) {
            self.idles += 1;
        }
        fn snapshot(&self, into: &mut (u64, u64)) {
            *into = (self.seen, self.idles);
        }
        fn wind_up(self) -> (u64, u64) {
            (self.seen, self.idles)
        }
    }

    fn settings(delivery: Delivery, idle_every: Option<Duration>) -> QueueSettings {
        QueueSettings {
            thread: "test-sink",
            capacity: 2,
            delivery,
            idle_every,
        }
    }

    #[test]
    fn a_full_queue_drops_and_counts_when_live() {
        let (open, gate) = std::sync::mpsc::channel();
        let worker = Counter {
            gate,
            seen: 0,
            idles: 0,
        };
        let sink = QueuedSink::spawn(worker, settings(Delivery::DropNewest, None)).unwrap();
        // One message may be in the worker's hands, two in the queue; the rest are dropped.
        for i in 0..10 {
            sink.send(i);
        }
        let dropped = sink.dropped();
        assert!((7..=8).contains(&dropped), "dropped {dropped}");
        for _ in 0..10 {
            let _ = open.send(());
        }
        let (seen, _) = sink.close();
        assert_eq!(seen + dropped, 10);
    }

    #[test]
    fn replays_wait_and_lose_nothing_and_idle_runs_between_messages() {
        let (open, gate) = std::sync::mpsc::channel();
        for _ in 0..100 {
            open.send(()).unwrap();
        }
        let worker = Counter {
            gate,
            seen: 0,
            idles: 0,
        };
        let every = Some(Duration::from_millis(5));
        let sink = QueuedSink::spawn(worker, settings(Delivery::Wait, every)).unwrap();
        for i in 0..100 {
            sink.send(i);
        }
        // The worker reports its counters while it runs, idle calls included (an idle call
        // may also come between two messages when this thread is slow to send them).
        let t0 = std::time::Instant::now();
        while (sink.stats().0 < 100 || sink.stats().1 == 0)
            && t0.elapsed() < Duration::from_secs(10)
        {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(sink.stats().0, 100);
        assert_eq!(sink.dropped(), 0);
        let (seen, idles) = sink.close();
        assert_eq!(seen, 100);
        assert!(idles >= 1, "idle never ran");
    }
}
