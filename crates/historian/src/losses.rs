//! The ledger of windows the historian could not keep, per point, run and seq range: a window
//! dropped because memory and spill were full ([`super::buffer`]) is entered at once (its
//! point and seq read from the message); a gap the daemon's recent history could not fill
//! ([`super::recovery`]) is entered as it is found missing, and a window recovered later is
//! taken out again. A set, not a counter: the same window found missing twice is one loss.
//! Its total and ranges go into the historian's status (all of them in the last status, the
//! first [`STATUS_RANGES`] while running) and each new range into the log, so no window is
//! lost without its point and seq range being said.

use rigmon_runtime::publish::recent::{run_start_ns, same_run};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Mutex;

/// Ranges listed in a running status (the last status lists every range).
pub const STATUS_RANGES: usize = 100;
/// Ranges logged per call of [`LossLedger::log_new`]; the rest are summed up in one line.
const LOG_RANGES: usize = 50;

/// Windows lost from one point's run: `first..=last`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LostRange {
    /// `<machine>/<asset>/<point>`.
    pub point: String,
    pub run_start_ns: u64,
    pub first: u64,
    pub last: u64,
}

/// Inclusive ranges of seq, disjoint and not touching (also the recovery plan's missing
/// windows, [`super::recovery_plan`]).
#[derive(Debug, Default, Clone)]
pub(crate) struct Ranges(BTreeMap<u64, u64>);

impl Ranges {
    /// Add `first..=last`; returns how many seqs were new.
    pub(crate) fn insert(&mut self, mut first: u64, mut last: u64) -> u64 {
        let before = self.len();
        // Merge with every range that overlaps or touches.
        let lo = first.saturating_sub(1);
        let touching: Vec<(u64, u64)> = self
            .0
            .range(..=last.saturating_add(1))
            .rev()
            .take_while(|(_, &l)| l >= lo)
            .map(|(&f, &l)| (f, l))
            .collect();
        for (f, l) in touching {
            self.0.remove(&f);
            first = first.min(f);
            last = last.max(l);
        }
        self.0.insert(first, last);
        self.len() - before
    }

    /// Take `seq` out; true when it was in.
    pub(crate) fn remove(&mut self, seq: u64) -> bool {
        let Some((&f, &l)) = self.0.range(..=seq).next_back() else {
            return false;
        };
        if l < seq {
            return false;
        }
        self.0.remove(&f);
        if f < seq {
            self.0.insert(f, seq - 1);
        }
        if seq < l {
            self.0.insert(seq + 1, l);
        }
        true
    }

    /// `first..=last` (nothing when `first > last`).
    pub(crate) fn of(first: u64, last: u64) -> Ranges {
        let mut r = Ranges::default();
        if first <= last {
            r.insert(first, last);
        }
        r
    }

    /// The ranges, ascending.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (u64, u64)> + '_ {
        self.0.iter().map(|(&f, &l)| (f, l))
    }

    /// Take `first..=last` out.
    pub(crate) fn subtract(&mut self, first: u64, last: u64) {
        let hit: Vec<(u64, u64)> = self
            .0
            .range(..=last)
            .rev()
            .take_while(|(_, &l)| l >= first)
            .map(|(&f, &l)| (f, l))
            .collect();
        for (f, l) in hit {
            self.0.remove(&f);
            if f < first {
                self.0.insert(f, first - 1);
            }
            if l > last {
                self.0.insert(last + 1, l);
            }
        }
    }

    pub(crate) fn len(&self) -> u64 {
        self.0.iter().map(|(f, l)| l - f + 1).sum()
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Take out the lowest ranges, at most `max_windows` windows in at most `max_ranges`
    /// ranges (at least one window when not empty).
    pub(crate) fn take_front(&mut self, max_windows: u64, max_ranges: usize) -> Vec<(u64, u64)> {
        let mut out = Vec::new();
        let mut left = max_windows.max(1);
        while left > 0 && out.len() < max_ranges.max(1) {
            let Some((f, l)) = self.0.pop_first() else {
                break;
            };
            let end = l.min(f.saturating_add(left - 1));
            if end < l {
                self.0.insert(end + 1, l);
            }
            left -= end - f + 1;
            out.push((f, end));
        }
        out
    }
}

#[derive(Debug, Default)]
struct Inner {
    lost: BTreeMap<(String, u64), Ranges>,
    /// Entered since the last [`LossLedger::log_new`].
    fresh: BTreeMap<(String, u64), Ranges>,
    total: u64,
}

/// What the status says about losses.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LostSummary {
    /// Windows lost (each once).
    pub windows: u64,
    /// Points that lost any.
    pub points: u64,
    /// The ranges (the first [`STATUS_RANGES`] while running, all in the last status).
    pub ranges: Vec<LostRange>,
    /// Ranges not listed here.
    pub ranges_left_off: u64,
}

/// The ledger (shared by the buffer, the recovery task and the status).
#[derive(Debug, Default)]
pub struct LossLedger {
    inner: Mutex<Inner>,
}

impl LossLedger {
    /// Windows `first..=last` of `point`'s run are lost.
    pub fn add(&self, point: &str, run_start_ns: u64, first: u64, last: u64) {
        if first > last {
            return;
        }
        let Ok(mut g) = self.inner.lock() else { return };
        let k = (point.to_string(), run_start_ns);
        let new = g.lost.entry(k.clone()).or_default().insert(first, last);
        if new > 0 {
            g.total += new;
            g.fresh.entry(k).or_default().insert(first, last);
        }
    }

    /// The parts of `first..=last` of `point`'s run not in the ledger (a run told apart as
    /// the daemons do, [`same_run`]: a run start read back from the database is rounded to
    /// the microsecond).
    pub fn unlisted(
        &self,
        point: &str,
        run_start_ns: u64,
        first: u64,
        last: u64,
    ) -> Vec<(u64, u64)> {
        let mut left = Ranges::of(first, last);
        let Ok(g) = self.inner.lock() else {
            return left.iter().collect();
        };
        for ((p, run), r) in &g.lost {
            if p == point && same_run(*run, run_start_ns) {
                for (&f, &l) in r.0.range(..=last) {
                    if l >= first {
                        left.subtract(f.max(first), l.min(last));
                    }
                }
            }
        }
        left.iter().collect()
    }

    /// Window `seq` was recovered after all.
    pub fn recovered(&self, point: &str, run_start_ns: u64, seq: u64) {
        let Ok(mut g) = self.inner.lock() else { return };
        let k = (point.to_string(), run_start_ns);
        if g.lost.get_mut(&k).is_some_and(|r| r.remove(seq)) {
            g.total -= 1;
            if let Some(r) = g.fresh.get_mut(&k) {
                r.remove(seq);
            }
        }
    }

    /// A health message that could not be kept: entered by its point and seq (a message
    /// that is no health message cannot be: the gap tracker finds it when the point's next
    /// window arrives). Returns false when the payload named no window.
    pub fn dropped(&self, payload: &[u8]) -> bool {
        match identify(payload) {
            Some((point, run, seq)) => {
                self.add(&point, run, seq, seq);
                true
            }
            None => false,
        }
    }

    /// Windows lost so far.
    pub fn total(&self) -> u64 {
        self.inner.lock().map_or(0, |g| g.total)
    }

    /// The summary, listing at most `max` ranges.
    pub fn summary(&self, max: usize) -> LostSummary {
        let Ok(g) = self.inner.lock() else {
            return LostSummary::default();
        };
        let mut ranges = Vec::new();
        let mut count = 0u64;
        let mut points = std::collections::BTreeSet::new();
        for ((point, run), r) in &g.lost {
            if !r.0.is_empty() {
                points.insert(point.as_str());
            }
            for (&first, &last) in &r.0 {
                count += 1;
                if ranges.len() < max {
                    ranges.push(LostRange {
                        point: point.clone(),
                        run_start_ns: *run,
                        first,
                        last,
                    });
                }
            }
        }
        LostSummary {
            windows: g.total,
            points: points.len() as u64,
            ranges_left_off: count - ranges.len() as u64,
            ranges,
        }
    }

    /// Log the ranges entered since the last call (one line each, at most 50, then a sum).
    pub fn log_new(&self) {
        let fresh = match self.inner.lock() {
            Ok(mut g) => std::mem::take(&mut g.fresh),
            Err(_) => return,
        };
        let mut lines = 0;
        let (mut more, mut more_windows) = (0u64, 0u64);
        for ((point, run), r) in &fresh {
            for (&first, &last) in &r.0 {
                if lines < LOG_RANGES {
                    tracing::warn!(
                        "lost: {point} run {run} windows {first}..={last} ({} windows): not in the database and not recoverable",
                        last - first + 1
                    );
                    lines += 1;
                } else {
                    more += 1;
                    more_windows += last - first + 1;
                }
            }
        }
        if more > 0 {
            tracing::warn!("lost: {more} more ranges ({more_windows} windows), listed in the historian's status (lost.ranges)");
        }
    }
}

/// The few fields that name a health window (the rest of the message is skipped unread).
#[derive(Deserialize)]
struct Ident {
    rig: String,
    asset: String,
    point: String,
    seq: u64,
    window: IdentWindow,
}

#[derive(Deserialize)]
struct IdentWindow {
    end_s: f64,
    end_ns: u64,
}

/// `(<machine>/<asset>/<point>, run start ns, seq)` of a health message.
pub fn identify(payload: &[u8]) -> Option<(String, u64, u64)> {
    let m: Ident = serde_json::from_slice(payload).ok()?;
    let run = run_start_ns(m.window.end_ns, m.window.end_s);
    Some((format!("{}/{}/{}", m.rig, m.asset, m.point), run, m.seq))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_merge_split_and_count_each_window_once() {
        let l = LossLedger::default();
        l.add("m/a/p", 7, 5, 9);
        l.add("m/a/p", 7, 10, 12);
        l.add("m/a/p", 7, 3, 6);
        l.add("m/a/p", 7, 20, 20);
        assert_eq!(l.total(), 11, "3..=12 and 20");
        l.add("m/a/p", 7, 4, 11);
        assert_eq!(l.total(), 11, "found missing twice is one loss");
        l.recovered("m/a/p", 7, 8);
        l.recovered("m/a/p", 7, 8);
        l.recovered("m/a/p", 7, 30);
        l.add("n/a/p", 1, 1, 1);
        let s = l.summary(10);
        assert_eq!((s.windows, s.points, s.ranges_left_off), (11, 2, 0));
        let got: Vec<(&str, u64, u64)> = s
            .ranges
            .iter()
            .map(|r| (r.point.as_str(), r.first, r.last))
            .collect();
        assert_eq!(
            got,
            [
                ("m/a/p", 3, 7),
                ("m/a/p", 9, 12),
                ("m/a/p", 20, 20),
                ("n/a/p", 1, 1)
            ]
        );
        let s = l.summary(1);
        assert_eq!((s.ranges.len(), s.ranges_left_off), (1, 3));
        l.log_new();
    }

    #[test]
    fn what_the_ledger_does_not_list_is_left_of_a_range() {
        let l = LossLedger::default();
        l.add("m/a/p", 7_000_000, 5, 9);
        l.add("m/a/p", 7_000_000, 20, 20);
        l.add("m/a/q", 7_000_000, 1, 100);
        // The same run read back rounded to the microsecond.
        assert_eq!(
            l.unlisted("m/a/p", 7_000_400, 1, 30),
            [(1, 4), (10, 19), (21, 30)]
        );
        assert_eq!(l.unlisted("m/a/p", 7_000_400, 6, 8), []);
        // Another run of the point has lost nothing.
        assert_eq!(l.unlisted("m/a/p", 9_000_000, 6, 8), [(6, 8)]);
        assert_eq!(l.unlisted("m/a/p", 7_000_000, 9, 5), []);
    }

    #[test]
    fn a_dropped_health_message_is_entered_by_its_point_and_seq() {
        let l = LossLedger::default();
        let m = serde_json::json!({"rig": "m", "asset": "a", "point": "p", "seq": 42,
            "window": {"end_s": 21.5, "end_ns": 1_000_021_500_000_000u64}, "other": [1, 2]});
        assert!(l.dropped(m.to_string().as_bytes()));
        assert!(!l.dropped(b"{\"schema\": \"rigmon.status\"}"));
        let s = l.summary(10);
        assert_eq!(s.windows, 1);
        assert_eq!(
            (
                s.ranges[0].point.as_str(),
                s.ranges[0].first,
                s.ranges[0].run_start_ns
            ),
            ("m/a/p", 42, 1_000_000_000_000_000)
        );
    }
}
