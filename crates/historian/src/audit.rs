//! The historian audits its own database: at start, and again whenever it has caught up
//! (nothing in memory beyond a batch, nothing spilled, nothing to ask) and `[recovery]
//! audit_every_s` has passed, it searches each point's stored windows for holes
//! ([`super::holes`]) and asks the daemons for every missing window the loss ledger does not
//! already name, like any gap: recovered, or counted lost by point and seq range. The gap
//! tracker names every window it sees missing; the audit is the check that does not depend
//! on it (a window it never saw missing, whatever the reason, is found here and said: a
//! warning with the point and seq range, and `recovery.audit_found` in the status).
//!
//! Each search looks back over the time since the previous one (plus [`OVERLAP`]), at most
//! `[recovery] hole_scan_s`: a hole older than that was there to be found by the previous
//! search, which ran only when nothing was in flight. A hole found is checked again once
//! everything the buffer held at the end of the search is written (a window recovered just
//! before may have been on its way), and what the ledger or the plan already names is left
//! out: what is left is a window no gap named.

use super::buffer::Buffer;
use super::config::RecoverySettings;
use super::database::Target;
use super::recovery::{Gap, Missing};
use super::status::Counters;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Added to the time since the previous search (window times trail the clock by a hop and
/// by the publish-to-commit latency).
pub const OVERLAP: Duration = Duration::from_secs(30);

/// How long the holes found wait for the buffer's messages to be written before they are
/// checked again (the historian had caught up when the search began).
const WRITTEN_WITHIN: Duration = Duration::from_secs(60);

/// A search that could not be done (no connection, the buffer not written in time) is tried
/// again after this long.
const RETRY: Duration = Duration::from_secs(30);

/// What the audit watches and feeds.
pub struct Auditor {
    pub target: Target,
    pub buffer: Arc<Buffer>,
    pub counters: Arc<Counters>,
    pub missing: Arc<Missing>,
    pub settings: RecoverySettings,
    /// The most a batch takes (the memory a historian that keeps up holds at most).
    pub batch_rows: u64,
    /// When the historian began listening (ns since the Unix epoch).
    pub listening_since_ns: u64,
}

impl Auditor {
    /// Caught up: at most a batch in memory, nothing spilled, nothing waiting or out.
    fn caught_up(&self) -> bool {
        let level = self.buffer.level();
        level.spilled == 0
            && level.memory <= self.batch_rows
            && self.missing.level() == (0, 0)
            && self.counters.db_connected.load(Ordering::Relaxed)
    }

    /// The search at start (once the database is connected), then one after every
    /// `audit_every_s` in which the historian is caught up; until the task is aborted.
    pub async fn run(self) {
        let span_max = self.settings.hole_scan_s;
        if span_max <= 0.0 || !self.settings.enabled {
            return;
        }
        let every = Duration::from_secs_f64(self.settings.audit_every_s);
        // The start of the last search that completed (the next looks back to it), and of
        // the last one tried (a failed one is tried again after RETRY).
        let (mut searched, mut tried): (Option<Instant>, Option<Instant>) = (None, None);
        loop {
            let connected = self.counters.db_connected.load(Ordering::Relaxed);
            let due = match (searched, tried) {
                (None, None) => connected,
                (None, Some(t)) => connected && t.elapsed() >= RETRY,
                (Some(t), tried) => {
                    let paced = tried.is_none_or(|x| x.elapsed() >= RETRY.min(every));
                    !every.is_zero() && t.elapsed() >= every && paced && self.caught_up()
                }
            };
            if !due {
                tokio::time::sleep(Duration::from_millis(250)).await;
                continue;
            }
            let span = searched.map_or(span_max, |t| {
                (t.elapsed() + OVERLAP).as_secs_f64().min(span_max)
            });
            let now = Instant::now();
            tried = Some(now);
            self.counters.auditing.store(true, Ordering::Relaxed);
            if self.search(span, searched.is_none()).await {
                searched = Some(now);
            }
            self.counters.auditing.store(false, Ordering::Relaxed);
            if every.is_zero() && searched.is_some() {
                return;
            }
        }
    }

    /// One search over `span` seconds; what it finds goes into the recovery plan. False when
    /// it could not be done (tried again after [`RETRY`]).
    async fn search(&self, span: f64, at_start: bool) -> bool {
        let found = match self.target.connect().await {
            Ok(client) => self.holes(&client, span, at_start).await,
            Err(e) => Err(e),
        };
        Counters::add(&self.counters.audits, 1);
        let gaps = match found {
            Ok(g) => g,
            Err(e) => {
                tracing::warn!(
                    "{e:#}; the holes in the database are searched again in {} s",
                    RETRY.as_secs()
                );
                return false;
            }
        };
        let windows: u64 = gaps.iter().map(Gap::len).sum();
        let Some(example) = gaps.first() else {
            return true;
        };
        if at_start {
            tracing::info!(
                "{windows} windows missing in {} holes within the last {span:.0} s of the database (a stopped historian's gaps): asked of their daemons",
                gaps.len()
            );
        } else {
            tracing::warn!(
                "audit: {windows} windows missing in {} holes of the database that no gap named (e.g. {} seqs {}..{} of run {}): asked of their daemons, counted lost if they have them no more",
                gaps.len(),
                example.key,
                example.first,
                example.last,
                example.run_start_ns
            );
        }
        Counters::add(&self.counters.audit_found, windows);
        for g in gaps {
            Counters::add(&self.counters.gaps, 1);
            self.missing.gap(g);
        }
        true
    }

    /// The holes of the last `span` s that are still missing once everything the buffer held
    /// at the end of the search is written (a window recovered just before the search may
    /// still have been on its way), named neither in the loss ledger nor in the plan. At
    /// start the holes are asked for at once (a spill left by the last run may fill some:
    /// those come back as duplicates): the buffer may hold minutes of backlog then.
    async fn holes(
        &self,
        client: &tokio_postgres::Client,
        span: f64,
        at_start: bool,
    ) -> anyhow::Result<Vec<Gap>> {
        let holes = super::holes::recent(client, span, self.listening_since_ns).await?;
        if at_start {
            return Ok(self.unlisted(holes.into_iter().map(|h| h.gap).collect()));
        }
        if holes.is_empty() {
            return Ok(Vec::new());
        }
        let c = &self.buffer.counters;
        let kept = c.kept_total.load(Ordering::Relaxed);
        let t0 = Instant::now();
        while c.committed_total.load(Ordering::Relaxed) < kept {
            if t0.elapsed() > WRITTEN_WITHIN {
                anyhow::bail!(
                    "the audit found {} holes but the buffer was not written within {} s to check them",
                    holes.len(),
                    WRITTEN_WITHIN.as_secs()
                );
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let missing = super::holes::still_missing(client, holes).await?;
        Ok(self.unlisted(missing))
    }

    /// The holes' parts neither the loss ledger names (those were asked and lost) nor the
    /// recovery plan is asking for now.
    fn unlisted(&self, holes: Vec<Gap>) -> Vec<Gap> {
        let ledger = &self.counters.losses;
        let mut out = Vec::new();
        for g in holes {
            for (a, b) in ledger.unlisted(&g.key, g.run_start_ns, g.first, g.last) {
                for (first, last) in self.missing.unplanned(&g.key, g.run_start_ns, a, b) {
                    out.push(Gap {
                        first,
                        last,
                        ..g.clone()
                    });
                }
            }
        }
        out
    }
}
