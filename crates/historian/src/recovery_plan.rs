//! The recovery plan: which windows are still to be asked of which daemon, and when. Gaps
//! ([`super::recovery::Gap`]) are merged per point and run into seq ranges; a point's
//! request waits a grace period after its first gap, so a window that only arrives late (out
//! of order) is taken out of the plan by [`Plan::arrived`] and never asked for; then one
//! request per point covers all its missing ranges (up to `max_windows` windows), and at most
//! `in_flight` requests are out at once (the replies come back at the pace the historian
//! takes them: a request ends before the next one starts). Pure bookkeeping, no I/O: the
//! recovery task ([`super::recovery::run`]) sends the requests.

use super::losses::Ranges;
use rigmon_runtime::publish::recent::same_run;
use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

/// How the plan paces the requests (`[recovery]`).
#[derive(Debug, Clone, Copy)]
pub struct Pacing {
    /// Requests out at once.
    pub in_flight: usize,
    /// Windows asked in one request at most (the rest waits for the point's next turn).
    pub max_windows: u64,
    /// Ranges in one request at most (the selector stays short).
    pub max_ranges: usize,
    /// How long a gap waits for its windows to arrive late before they are asked for.
    pub grace: Duration,
}

impl Default for Pacing {
    fn default() -> Self {
        Pacing {
            in_flight: 8,
            max_windows: 240,
            max_ranges: 32,
            grace: Duration::from_secs(1),
        }
    }
}

/// One point's run, and whether its windows count as lost when not found (a gap after the
/// historian knew the point) or not (the backfill of a point seen for the first time).
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Target {
    /// `<machine>/<asset>/<point>`.
    pub key: String,
    pub run_start_ns: u64,
    pub counted: bool,
}

/// One request to a daemon's recent history.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    pub id: u64,
    pub target: Target,
    /// Inclusive seq ranges, ascending.
    pub ranges: Vec<(u64, u64)>,
}

impl Request {
    /// Windows asked.
    pub fn len(&self) -> u64 {
        self.ranges.iter().map(|(a, b)| b - a + 1).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    pub fn contains(&self, seq: u64) -> bool {
        self.ranges.iter().any(|&(a, b)| (a..=b).contains(&seq))
    }
}

#[derive(Debug, Default)]
struct Waiting {
    missing: Ranges,
    /// Not asked before this.
    due: Option<Instant>,
}

/// A request out, and the windows of it that arrived live meanwhile.
#[derive(Debug)]
struct Flying {
    request: Request,
    late: Vec<u64>,
}

/// The plan.
#[derive(Debug, Default)]
pub struct Plan {
    pacing: Pacing,
    waiting: HashMap<Target, Waiting>,
    /// Targets in the order they fall due (each at most once).
    queue: VecDeque<Target>,
    flying: HashMap<u64, Flying>,
    next_id: u64,
}

impl Plan {
    pub fn new(pacing: Pacing) -> Plan {
        Plan {
            pacing,
            ..Plan::default()
        }
    }

    /// Windows `first..=last` of `target` are missing (seen at `now`).
    pub fn add(&mut self, target: Target, first: u64, last: u64, now: Instant) {
        if first > last {
            return;
        }
        let w = self.waiting.entry(target.clone()).or_default();
        w.missing.insert(first, last);
        if w.due.is_none() {
            w.due = Some(now + self.pacing.grace);
            self.queue.push_back(target);
        }
    }

    /// Window `seq` of `key`'s run arrived live after all: it is not asked for (or, if its
    /// request is already out, not counted lost when the answer lacks it).
    pub fn arrived(&mut self, key: &str, run_start_ns: u64, seq: u64) {
        for counted in [true, false] {
            let t = Target {
                key: key.to_string(),
                run_start_ns,
                counted,
            };
            if let Some(w) = self.waiting.get_mut(&t) {
                w.missing.remove(seq);
            }
        }
        for f in self.flying.values_mut() {
            let t = &f.request.target;
            if t.key == key && t.run_start_ns == run_start_ns && f.request.contains(seq) {
                f.late.push(seq);
            }
        }
    }

    /// The next request to send at `now`, if one is due and fewer than `in_flight` are out.
    /// A point has one request out at a time; what did not fit in it waits for its next turn.
    pub fn next(&mut self, now: Instant) -> Option<Request> {
        if self.flying.len() >= self.pacing.in_flight {
            return None;
        }
        let busy = |plan: &Plan, t: &Target| plan.flying.values().any(|f| f.request.target == *t);
        for _ in 0..self.queue.len() {
            let t = self.queue.pop_front()?;
            let Some(w) = self.waiting.get_mut(&t) else {
                continue;
            };
            if w.missing.is_empty() {
                self.waiting.remove(&t);
                continue;
            }
            if w.due.is_some_and(|d| d > now) {
                // The queue is in the order gaps were found, i.e. due order.
                self.queue.push_front(t);
                return None;
            }
            if busy(self, &t) {
                self.queue.push_back(t);
                continue;
            }
            let w = self.waiting.get_mut(&t)?;
            let ranges = w
                .missing
                .take_front(self.pacing.max_windows, self.pacing.max_ranges);
            if w.missing.is_empty() {
                self.waiting.remove(&t);
            } else {
                self.queue.push_back(t.clone());
            }
            self.next_id += 1;
            let request = Request {
                id: self.next_id,
                target: t,
                ranges,
            };
            self.flying.insert(
                request.id,
                Flying {
                    request: request.clone(),
                    late: Vec::new(),
                },
            );
            return Some(request);
        }
        None
    }

    /// The parts of `first..=last` of `key`'s run neither waiting nor asked for now (a run
    /// told apart as the daemons do, [`same_run`]).
    pub fn unplanned(
        &self,
        key: &str,
        run_start_ns: u64,
        first: u64,
        last: u64,
    ) -> Vec<(u64, u64)> {
        let mut left = Ranges::of(first, last);
        let ours = |t: &Target| t.key == key && same_run(t.run_start_ns, run_start_ns);
        for (_, w) in self.waiting.iter().filter(|(t, _)| ours(t)) {
            for (f, l) in w.missing.iter() {
                left.subtract(f, l);
            }
        }
        for f in self.flying.values().filter(|f| ours(&f.request.target)) {
            for &(a, b) in &f.request.ranges {
                left.subtract(a, b);
            }
        }
        left.iter().collect()
    }

    /// Request `id` has ended; returns the seqs of it that arrived live while it was out.
    pub fn finished(&mut self, id: u64) -> Vec<u64> {
        self.flying.remove(&id).map(|f| f.late).unwrap_or_default()
    }

    /// When the next waiting request falls due (None: nothing waits).
    pub fn next_due(&self) -> Option<Instant> {
        self.queue
            .iter()
            .find_map(|t| self.waiting.get(t).and_then(|w| w.due))
    }

    /// Requests out now.
    pub fn in_flight(&self) -> usize {
        self.flying.len()
    }

    /// Windows waiting to be asked for.
    pub fn waiting_windows(&self) -> u64 {
        self.waiting.values().map(|w| w.missing.len()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(key: &str) -> Target {
        Target {
            key: key.into(),
            run_start_ns: 7,
            counted: true,
        }
    }

    /// Gaps of one point are merged into one request of ranges; at most `in_flight`
    /// requests are out; a window that arrives late is never asked for.
    #[test]
    fn ranges_merged_per_point_bounded_in_flight_late_arrivals_not_asked() {
        let grace = Duration::from_secs(1);
        let mut plan = Plan::new(Pacing {
            in_flight: 2,
            max_windows: 100,
            max_ranges: 8,
            grace,
        });
        let t0 = Instant::now();
        // Point a: three gaps, two of them touching; b and c one gap each.
        plan.add(target("a"), 5, 6, t0);
        plan.add(target("a"), 7, 7, t0);
        plan.add(target("a"), 10, 12, t0);
        plan.add(target("b"), 3, 3, t0);
        plan.add(target("c"), 20, 22, t0);
        // Within the grace period nothing is asked; a late window comes out of the plan.
        assert_eq!(plan.next(t0), None);
        plan.arrived("a", 7, 11);
        plan.arrived("b", 7, 3);
        assert_eq!(plan.waiting_windows(), 5 + 3, "a: 5-7, 10, 12; c: 20-22");
        let later = t0 + grace;
        let first = plan.next(later).expect("a is due");
        assert_eq!(first.target, target("a"));
        assert_eq!(
            first.ranges,
            [(5, 7), (10, 10), (12, 12)],
            "merged, 11 left out"
        );
        // b's only window arrived: no request for b at all.
        let second = plan.next(later).expect("c is due");
        assert_eq!(second.target, target("c"));
        assert_eq!(second.ranges, [(20, 22)]);
        assert_eq!(plan.in_flight(), 2);
        plan.add(target("d"), 1, 1, t0);
        assert_eq!(plan.next(later), None, "two out: the bound holds");
        // A window arriving live while its request is out is reported with the request.
        plan.arrived("c", 7, 21);
        assert_eq!(plan.finished(second.id), [21]);
        let third = plan.next(later).expect("one slot free");
        assert_eq!(third.target, target("d"));
        assert_eq!(plan.finished(first.id), Vec::<u64>::new());
        assert_eq!(plan.finished(third.id), Vec::<u64>::new());
        assert_eq!(plan.next(later), None);
        assert_eq!(plan.waiting_windows(), 0);
        assert_eq!(plan.next_due(), None);
    }

    /// A point with more missing windows than one request takes gets further requests, one
    /// at a time, behind the other points; a gap found meanwhile joins what waits.
    #[test]
    fn large_gaps_are_asked_in_turns() {
        let mut plan = Plan::new(Pacing {
            in_flight: 4,
            max_windows: 10,
            max_ranges: 8,
            grace: Duration::from_secs(1),
        });
        let t0 = Instant::now();
        plan.add(target("a"), 1, 25, t0);
        plan.add(target("b"), 1, 1, t0);
        let now = t0 + Duration::from_secs(1);
        let r1 = plan.next(now).unwrap();
        assert_eq!(
            (r1.target.key.as_str(), r1.ranges.clone()),
            ("a", vec![(1, 10)])
        );
        let r2 = plan.next(now).unwrap();
        assert_eq!(r2.target.key, "b");
        assert_eq!(plan.next(now), None, "a's next turn waits for its request");
        plan.finished(r1.id);
        let r3 = plan.next(now).unwrap();
        assert_eq!(r3.ranges, [(11, 20)]);
        plan.finished(r3.id);
        plan.add(target("a"), 30, 30, t0);
        let r4 = plan.next(now).unwrap();
        assert_eq!(
            r4.ranges,
            [(21, 25), (30, 30)],
            "the new gap joins what waits"
        );
        assert_eq!(r4.len(), 6);
    }
}
