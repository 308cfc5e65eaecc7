//! The bounded buffer between Zenoh and the database: first-in first-out, `[buffer]
//! memory_messages` and at most `memory_mb` (message bytes: key and payload) in memory, then
//! the spill on disk ([`super::spill`], up to `spill_max_mb`), then dropping (counted,
//! published in the historian's status). Once
//! anything is spilled, newer messages queue behind it on disk until the spill is read back,
//! so the order never changes. A batch is only removed for good when the writer says it was
//! committed ([`Buffer::commit`]).

pub use super::incoming::{Incoming, Kind};
use super::spill::{Cursor, Spill};
use std::collections::VecDeque;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Where a batch came from, to commit it.
#[derive(Debug, Clone, Copy)]
pub enum Origin {
    Memory,
    Spill(Cursor),
}

/// A batch handed to the writer.
pub struct Batch {
    pub messages: Vec<Incoming>,
    pub origin: Origin,
}

struct Inner {
    memory: VecDeque<Incoming>,
    /// Bytes of the messages in `memory`.
    memory_bytes: u64,
    spill: Option<Spill>,
    /// True while the spill holds messages: newer ones queue behind them.
    spilling: bool,
    /// A batch is out with the writer and not yet committed.
    in_flight: bool,
}

/// Counters of the buffer, for the status.
#[derive(Debug, Default)]
pub struct BufferCounters {
    /// Messages kept (in memory or spilled) ...
    pub kept_total: AtomicU64,
    /// ... and handed on for good ([`Buffer::commit`]): when this reaches what `kept_total`
    /// was, everything kept by then is written ([`super::audit`]).
    pub committed_total: AtomicU64,
    pub spilled_total: AtomicU64,
    pub dropped: AtomicU64,
    pub spill_errors: AtomicU64,
}

/// The buffer.
pub struct Buffer {
    inner: Mutex<Inner>,
    memory_cap: usize,
    memory_max_bytes: u64,
    spill_max_bytes: u64,
    pub counters: BufferCounters,
    pub notify: tokio::sync::Notify,
    /// Where a dropped window is entered by its point and seq.
    ledger: Option<std::sync::Arc<super::losses::LossLedger>>,
}

/// What the buffer holds now.
#[derive(Debug, Clone, Copy, Default)]
pub struct Level {
    pub memory: u64,
    pub memory_bytes: u64,
    pub spilled: u64,
    pub spill_bytes: u64,
    /// Damaged stretches of the spill skipped (each lost at least one message), their bytes.
    pub damaged: u64,
    pub damaged_bytes: u64,
}

impl Buffer {
    /// A buffer of at most `memory_cap` messages and `memory_max_bytes` in memory, with its
    /// spill in `spill_dir` (None: no spill, drop when memory is full).
    pub fn open(
        memory_cap: usize,
        memory_max_bytes: u64,
        spill_dir: Option<&Path>,
        spill_max_bytes: u64,
    ) -> anyhow::Result<Buffer> {
        let spill = spill_dir.map(Spill::open).transpose()?;
        let spilling = spill.as_ref().is_some_and(|s| !s.is_empty());
        if let Some(s) = spill.as_ref().filter(|_| spilling) {
            tracing::info!(
                "{} messages left in the spill by an earlier run are written first",
                s.records()
            );
        }
        Ok(Buffer {
            inner: Mutex::new(Inner {
                memory: VecDeque::new(),
                memory_bytes: 0,
                spill,
                spilling,
                in_flight: false,
            }),
            memory_cap,
            memory_max_bytes,
            spill_max_bytes,
            counters: BufferCounters::default(),
            notify: tokio::sync::Notify::new(),
            ledger: None,
        })
    }

    /// Enter every health window this buffer drops in `ledger` (by point and seq).
    pub fn with_ledger(mut self, ledger: std::sync::Arc<super::losses::LossLedger>) -> Self {
        self.ledger = Some(ledger);
        self
    }

    fn enter_dropped(&self, m: &Incoming) {
        if let (Kind::Health, Some(l)) = (m.kind, self.ledger.as_ref()) {
            l.dropped(&m.payload);
        }
    }

    /// Take a message (from Zenoh's callback thread; never blocks on the database). False
    /// when it was dropped (memory and spill full, or the spill failed): a health window is
    /// then in the loss ledger.
    pub fn push(&self, m: Incoming) -> bool {
        let Ok(mut g) = self.inner.lock() else {
            return false;
        };
        let size = m.size();
        let mut dropped = None;
        if !g.spilling
            && g.memory.len() < self.memory_cap
            && g.memory_bytes + size <= self.memory_max_bytes
        {
            g.memory_bytes += size;
            g.memory.push_back(m);
        } else if let Some(s) = g
            .spill
            .as_mut()
            .filter(|s| s.bytes() < self.spill_max_bytes)
        {
            match s.append(&m) {
                Ok(()) => {
                    g.spilling = true;
                    self.counters.spilled_total.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => {
                    let n = self.counters.spill_errors.fetch_add(1, Ordering::Relaxed) + 1;
                    if n == 1 || n.is_power_of_two() {
                        tracing::error!("cannot spill ({n} errors so far): {e:#}");
                    }
                    self.counters.dropped.fetch_add(1, Ordering::Relaxed);
                    dropped = Some(m);
                }
            }
        } else {
            dropped = Some(m);
            let n = self.counters.dropped.fetch_add(1, Ordering::Relaxed) + 1;
            if n == 1 || n.is_power_of_two() {
                tracing::warn!("buffer and spill full: {n} messages dropped so far (raise [buffer] memory_messages / spill_max_mb)");
            }
        }
        drop(g);
        let kept = dropped.is_none();
        if kept {
            self.counters.kept_total.fetch_add(1, Ordering::Relaxed);
        }
        if let Some(m) = dropped {
            self.enter_dropped(&m);
        }
        self.notify.notify_one();
        kept
    }

    /// Messages waiting (memory + spill).
    pub fn level(&self) -> Level {
        self.inner
            .lock()
            .map(|g| Level {
                memory: g.memory.len() as u64,
                memory_bytes: g.memory_bytes,
                spilled: g.spill.as_ref().map_or(0, |s| s.records()),
                spill_bytes: g.spill.as_ref().map_or(0, |s| s.bytes()),
                damaged: g.spill.as_ref().map_or(0, |s| s.damage().0),
                damaged_bytes: g.spill.as_ref().map_or(0, |s| s.damage().1),
            })
            .unwrap_or_default()
    }

    /// Up to `max` of the oldest messages, and from memory at most `max_bytes` of them (at
    /// least one; memory first: it is older than the spill). The
    /// batch stays owed until [`commit`](Self::commit); taking again before that returns the
    /// same spill records, so callers retry the batch they hold instead. The spill is read
    /// outside the lock (a copy of its read position, [`Spill::reader`]): the Zenoh callbacks
    /// that [`push`](Self::push) never wait for the disk reads of a batch.
    pub fn take(&self, max: usize, max_bytes: u64) -> Batch {
        let empty = || Batch {
            messages: Vec::new(),
            origin: Origin::Memory,
        };
        let reader = {
            let mut g = self.inner.lock().expect("buffer lock");
            g.in_flight = true;
            if !g.memory.is_empty() {
                return Self::take_memory(&mut g, max, max_bytes);
            }
            match g.spill.as_ref().filter(|_| g.spilling) {
                Some(s) => s.reader(),
                None => return empty(),
            }
        };
        let read = reader.peek(max);
        if let Some(s) = self.inner.lock().expect("buffer lock").spill.as_ref() {
            s.absorb(&reader);
        }
        match read {
            Ok((messages, c)) => Batch {
                messages,
                origin: Origin::Spill(c),
            },
            Err(e) => {
                tracing::error!("reading the spill: {e:#}");
                empty()
            }
        }
    }

    fn take_memory(g: &mut Inner, max: usize, max_bytes: u64) -> Batch {
        let mut n = 0;
        let mut bytes = 0;
        for m in g.memory.iter().take(max) {
            bytes += m.size();
            if n > 0 && bytes > max_bytes {
                break;
            }
            n += 1;
        }
        let messages: Vec<Incoming> = g.memory.drain(..n).collect();
        g.memory_bytes -= messages.iter().map(Incoming::size).sum::<u64>();
        Batch {
            messages,
            origin: Origin::Memory,
        }
    }

    /// The batch is in the database (or was rejected for good): forget it.
    pub fn commit(&self, batch: &Batch) {
        let mut g = self.inner.lock().expect("buffer lock");
        g.in_flight = false;
        self.counters
            .committed_total
            .fetch_add(batch.messages.len() as u64, Ordering::Relaxed);
        if let Origin::Spill(c) = batch.origin {
            if let Some(s) = g.spill.as_mut() {
                if let Err(e) = s.commit(c, batch.messages.len() as u64) {
                    tracing::error!("committing the spill: {e:#}");
                }
                if s.is_empty() {
                    g.spilling = false;
                }
            }
        }
    }

    /// Memory and spill both empty.
    pub fn is_empty(&self) -> bool {
        let l = self.level();
        l.memory == 0 && l.spilled == 0
    }

    /// On a stop with the database out of reach: move what is in memory to the spill so a
    /// restart writes it. Returns how many could not be kept.
    pub fn persist(&self, pending: Vec<Incoming>) -> u64 {
        let mut g = self.inner.lock().expect("buffer lock");
        let mut rest: Vec<Incoming> = pending;
        rest.extend(g.memory.drain(..));
        g.memory_bytes = 0;
        let Some(s) = g.spill.as_mut() else {
            drop(g);
            for m in &rest {
                self.enter_dropped(m);
            }
            return rest.len() as u64;
        };
        // What is in memory may be older than what is spilled already; it goes behind it.
        // Rows carry their own times and the primary key drops repeats, so only the order
        // in which a restart writes them changes.
        let mut lost = Vec::new();
        for m in &rest {
            if s.append(m).is_err() {
                lost.push(m);
            }
        }
        drop(g);
        for m in &lost {
            self.enter_dropped(m);
        }
        lost.len() as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(i: u8) -> Incoming {
        Incoming {
            kind: Kind::Health,
            key: "k".into(),
            payload: vec![i],
            recovered: false,
        }
    }

    #[test]
    fn memory_then_spill_then_drop_in_order() {
        let d = tempfile::tempdir().unwrap();
        let b = Buffer::open(2, 1 << 20, Some(d.path()), 60).unwrap();
        for i in 0..6 {
            assert!(b.push(m(i)), "kept");
        }
        // 2 in memory; each spilled record is 12 + 3 + 1 + 1 = 17 bytes: 4 fit under 60 bytes.
        let l = b.level();
        assert_eq!((l.memory, l.spilled), (2, 4));
        assert_eq!(b.counters.dropped.load(Ordering::Relaxed), 0);
        assert!(!b.push(m(6)), "push says it dropped");
        assert_eq!(b.counters.dropped.load(Ordering::Relaxed), 1);
        let mut seen = Vec::new();
        loop {
            let batch = b.take(3, u64::MAX);
            if batch.messages.is_empty() {
                break;
            }
            seen.extend(batch.messages.iter().map(|m| m.payload[0]));
            b.commit(&batch);
        }
        assert_eq!(seen, [0, 1, 2, 3, 4, 5]);
        assert!(b.is_empty());
        b.push(m(9));
        assert_eq!(
            b.level().memory,
            1,
            "back to memory once the spill is read back"
        );
    }

    /// Issue 38, F8: memory is bounded by bytes, not only by messages. Before, 30 messages
    /// of 20 MB were all held in memory (681 MB) under `memory_messages = 20000`.
    #[test]
    fn memory_is_bounded_by_bytes_and_the_rest_spills() {
        let d = tempfile::tempdir().unwrap();
        let b = Buffer::open(20_000, 10 << 20, Some(d.path()), 1 << 40).unwrap();
        let big = |i: u8| Incoming {
            kind: Kind::Health,
            key: "k".into(),
            payload: vec![i; 2 << 20],
            recovered: false,
        };
        for i in 0..30 {
            b.push(big(i));
        }
        let l = b.level();
        assert_eq!((l.memory, l.spilled), (4, 26), "4 x 2 MB fit under 10 MB");
        assert!(l.memory_bytes <= 10 << 20, "{}", l.memory_bytes);
        let batch = b.take(100, u64::MAX);
        assert_eq!(batch.messages.len(), 4);
        assert_eq!(b.level().memory_bytes, 0);
        b.commit(&batch);
        let mut n = 4;
        loop {
            let batch = b.take(7, u64::MAX);
            if batch.messages.is_empty() {
                break;
            }
            assert_eq!(batch.messages[0].payload[0], n as u8, "in order");
            n += batch.messages.len();
            b.commit(&batch);
        }
        assert_eq!(n, 30);
    }
}
