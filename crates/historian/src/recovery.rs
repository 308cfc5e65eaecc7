//! Nothing missed without a count: every daemon numbers its windows (`seq`, from 1 per run;
//! a run is told apart by its clock origin, [`run_start_ns`](rigmon_runtime::publish::recent::run_start_ns)).
//! The [`Tracker`] follows each point's run and highest `seq`, seeded at start from what the
//! database already holds, and turns every jump into a [`Gap`]; [`recover`] asks the daemon's
//! recent history (`<base>/recent?run=..;seq=[a..b]`) for exactly those windows and feeds the
//! answers back into the buffer. Windows still missing afterwards are counted as lost, exactly.
//! Bound: a daemon keeps `[zenoh] history_windows` windows (default 1200 = 10 min at 2/s), so a
//! historian down for less than that loses nothing. Not recoverable: windows a daemon
//! published and then forgot because it restarted while the historian was down (its old run's
//! tail); the new run is recovered from its first window.

use super::buffer::{Buffer, Incoming, Kind};
use super::losses::LossLedger;
use super::status::Counters;
use rigmon_runtime::publish::recent::{same_run, RecentQuery, SUFFIX};
use rigmon_runtime::publish::zenoh::FLEET_CONGESTION;
use std::collections::{HashMap, HashSet};
use std::sync::Arc;
use std::time::Duration;

/// Windows missing from one point's run (inclusive seq range).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Gap {
    /// `<machine>/<asset>/<point>`.
    pub key: String,
    pub run_start_ns: u64,
    pub first: u64,
    pub last: u64,
    /// Missing after the historian knew the point (lost if not recovered); false for the
    /// backfill of a point seen for the first time.
    pub counted: bool,
}

impl Gap {
    pub fn len(&self) -> u64 {
        self.last.saturating_sub(self.first).saturating_add(1)
    }

    pub fn is_empty(&self) -> bool {
        false
    }
}

#[derive(Debug, Clone, Copy)]
struct Track {
    run_start_ns: u64,
    high: u64,
}

/// Each point's run and highest seq.
#[derive(Debug, Default)]
pub struct Tracker {
    points: HashMap<String, Track>,
}

impl Tracker {
    /// Start from the database's last window per point (key -> (run start ns, seq)).
    pub fn seeded(last: HashMap<String, (u64, u64)>) -> Tracker {
        Tracker {
            points: last
                .into_iter()
                .map(|(k, (run_start_ns, high))| (k, Track { run_start_ns, high }))
                .collect(),
        }
    }

    /// A live window arrived; returns the gap it reveals, if any.
    pub fn observe(&mut self, key: &str, run_start_ns: u64, seq: u64) -> Option<Gap> {
        let gap = |first: u64, last: u64, counted: bool| {
            (first <= last).then(|| Gap {
                key: key.to_string(),
                run_start_ns,
                first,
                last,
                counted,
            })
        };
        match self.points.get_mut(key) {
            Some(t) if same_run(t.run_start_ns, run_start_ns) => {
                let before = t.high;
                t.high = t.high.max(seq);
                // Keep the daemon's own value (the database's is rounded to µs).
                t.run_start_ns = run_start_ns;
                // Checked: a seq near 2^64 (refused by admission anyway) must not wrap.
                match before.checked_add(1) {
                    Some(next) if seq > next => gap(next, seq - 1, true),
                    _ => None,
                }
            }
            // A late window of an older run: nothing to follow.
            Some(t) if run_start_ns < t.run_start_ns => None,
            // The daemon restarted: its new run from window 1.
            Some(t) => {
                *t = Track {
                    run_start_ns,
                    high: seq,
                };
                gap(1, seq.saturating_sub(1), true)
            }
            None => {
                self.points.insert(
                    key.to_string(),
                    Track {
                        run_start_ns,
                        high: seq,
                    },
                );
                gap(1, seq.saturating_sub(1), false)
            }
        }
    }
}

/// Fetch one gap from the daemon's recent history into the buffer; update the counters.
pub async fn recover(
    session: &zenoh::Session,
    prefix: &str,
    gap: Gap,
    buffer: &Buffer,
    counters: &Counters,
    timeout: Duration,
) {
    let query = RecentQuery {
        run_start_ns: Some(gap.run_start_ns),
        seq: Some((gap.first, gap.last)),
        time: None,
    };
    let selector = format!("{prefix}/{}/{SUFFIX}?{}", gap.key, query.to_parameters());
    Counters::add(&counters.requested, gap.len());
    let mut got: HashSet<u64> = HashSet::new();
    // Every reply has the same key: no consolidation, or only the last would be kept.
    // Replies travel with the query's congestion control: `Drop`, so that replies queued to a
    // historian that reads slowly cannot close its transport (`Block` would, after 5 s; see
    // `FLEET_CONGESTION`); a dropped reply is a window counted lost with its seq range.
    let replies = session
        .get(selector.clone())
        .congestion_control(FLEET_CONGESTION)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(timeout)
        .await;
    match replies {
        Ok(replies) => {
            while let Ok(reply) = replies.recv_async().await {
                let Ok(sample) = reply.result() else { continue };
                let payload = sample.payload().to_bytes().into_owned();
                let seq = serde_json::from_slice::<serde_json::Value>(&payload)
                    .ok()
                    .and_then(|v| v["seq"].as_u64());
                let Some(seq) = seq.filter(|s| (gap.first..=gap.last).contains(s)) else {
                    continue;
                };
                // Only a window the buffer kept is recovered: one it had to drop (memory and
                // spill full) is in the loss ledger and must stay there.
                if !got.contains(&seq)
                    && buffer.push(Incoming {
                        kind: Kind::Health,
                        key: format!("{prefix}/{}/health", gap.key),
                        payload,
                        recovered: true,
                    })
                {
                    got.insert(seq);
                }
            }
        }
        Err(e) => tracing::warn!("asking {selector} for missed windows failed: {e}"),
    }
    let found = got.len() as u64;
    let missing = gap.len().saturating_sub(found);
    if gap.counted {
        enter(&counters.losses, &gap, &got);
        Counters::add(&counters.recovered, found);
        Counters::add(&counters.lost, missing);
        if missing > 0 {
            tracing::warn!(
                "{}: windows {}..={} of run {} missed; {found} recovered, {missing} lost (older than the daemon's recent history, or the daemon is gone)",
                gap.key, gap.first, gap.last, gap.run_start_ns
            );
        } else {
            tracing::info!(
                "{}: windows {}..={} missed and recovered",
                gap.key,
                gap.first,
                gap.last
            );
        }
    } else {
        Counters::add(&counters.backfilled, found);
        Counters::add(&counters.not_backfilled, missing);
    }
}

/// Enter a counted gap in the loss ledger: what was found comes out of it, the rest goes in.
fn enter(ledger: &LossLedger, gap: &Gap, got: &HashSet<u64>) {
    let mut found: Vec<u64> = got.iter().copied().collect();
    found.sort_unstable();
    let mut next = gap.first;
    for &seq in &found {
        ledger.recovered(&gap.key, gap.run_start_ns, seq);
        if seq > next {
            ledger.add(&gap.key, gap.run_start_ns, next, seq - 1);
        }
        next = seq.saturating_add(1);
    }
    if next <= gap.last && (found.last() != Some(&u64::MAX)) {
        ledger.add(&gap.key, gap.run_start_ns, next, gap.last);
    }
}

/// The task that works through the gaps in order.
pub async fn run(
    session: zenoh::Session,
    prefix: String,
    mut gaps: tokio::sync::mpsc::UnboundedReceiver<Gap>,
    buffer: Arc<Buffer>,
    counters: Arc<Counters>,
    timeout: Duration,
) {
    while let Some(gap) = gaps.recv().await {
        recover(&session, &prefix, gap, &buffer, &counters, timeout).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_within_a_run_after_a_restart_and_for_new_points() {
        // Seeded from the database: the run origin in µs.
        let mut t = Tracker::seeded([("m/a/p".to_string(), (100_000_000, 10))].into());
        assert_eq!(
            t.observe("m/a/p", 100_000_123, 11),
            None,
            "same run to the µs"
        );
        let g = t.observe("m/a/p", 100_000_123, 15).unwrap();
        assert_eq!((g.first, g.last, g.counted), (12, 14, true));
        assert_eq!(
            g.run_start_ns, 100_000_123,
            "asks with the daemon's own value"
        );
        assert_eq!(
            t.observe("m/a/p", 100_000_123, 13),
            None,
            "a late window fills, no new gap"
        );
        assert_eq!(t.observe("m/a/p", 50_000_000, 99), None, "older run");
        let g = t.observe("m/a/p", 200_000_000, 4).unwrap();
        assert_eq!(
            (g.run_start_ns, g.first, g.last, g.counted),
            (200_000_000, 1, 3, true)
        );
        assert_eq!(t.observe("m/a/p", 200_000_000, 5), None);
        let g = t.observe("n/a/p", 7, 30).unwrap();
        assert_eq!((g.first, g.last, g.counted), (1, 29, false));
        assert_eq!(t.observe("o/a/p", 7, 1), None);
    }

    /// What a gap's daemon still had comes out of the loss ledger, the rest goes in, by seq
    /// range; the same gap found twice is entered once.
    #[test]
    fn a_gap_enters_the_ledger_by_seq_range_less_what_was_recovered() {
        let ledger = LossLedger::default();
        let gap = Gap {
            key: "m/a/p".into(),
            run_start_ns: 9,
            first: 10,
            last: 19,
            counted: true,
        };
        ledger.add("m/a/p", 9, 12, 12);
        enter(&ledger, &gap, &[12, 13, 17].into());
        enter(&ledger, &gap, &[12, 13, 17].into());
        let s = ledger.summary(10);
        let got: Vec<(u64, u64)> = s.ranges.iter().map(|r| (r.first, r.last)).collect();
        assert_eq!(got, [(10, 11), (14, 16), (18, 19)]);
        assert_eq!(s.windows, 7);
        enter(&ledger, &gap, &(10..=19).collect());
        assert_eq!(ledger.total(), 0, "all recovered after all");
    }

    /// Issue 38, F2: a forged seq of 2^64-1 wrapped `high + 1` to 0, so every later window
    /// opened a gap from 0 (161,765 windows re-requested in 10 s). The arithmetic is checked
    /// now (and admission refuses such a seq before it reaches the tracker).
    #[test]
    fn a_seq_at_the_top_of_u64_opens_no_wrapped_gaps() {
        let mut t = Tracker::default();
        assert_eq!(t.observe("m/a/p", 1, 1), None);
        let g = t.observe("m/a/p", 1, u64::MAX).unwrap();
        assert_eq!((g.first, g.last), (2, u64::MAX - 1));
        assert_eq!(g.len(), u64::MAX - 2);
        for seq in 2..50 {
            assert_eq!(t.observe("m/a/p", 1, seq), None, "seq {seq}");
        }
        assert_eq!(t.observe("m/a/p", 1, u64::MAX), None);
        let whole = Gap {
            key: "k".into(),
            run_start_ns: 0,
            first: 0,
            last: u64::MAX,
            counted: true,
        };
        assert_eq!(whole.len(), u64::MAX, "saturates, never wraps to 0");
    }
}
