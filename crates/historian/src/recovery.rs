//! Nothing missed without a count: every daemon numbers its windows (`seq`, from 1 per run;
//! a run is told apart by its clock origin, [`run_start_ns`](rigmon_runtime::publish::recent::run_start_ns)).
//! The [`Tracker`] follows each point's run and highest `seq`, seeded at start from what the
//! database already holds, and turns every jump into a [`Gap`]; the gaps go into the
//! [`recovery plan`](super::recovery_plan) (merged per point, a grace period for late
//! windows, a bounded number of requests out), and [`run`] asks each daemon's recent history
//! (`<base>/recent?run=..;seq=[a..b]|[c..d]`) for exactly those windows and feeds the answers
//! back into the buffer. Windows still missing afterwards are counted as lost, exactly.
//! Bound: a daemon keeps `[zenoh] history_windows` windows (default 1200 = 10 min at 2/s), so a
//! historian down for less than that loses nothing. Not recoverable: windows a daemon
//! published and then forgot because it restarted while the historian was down (its old run's
//! tail); the new run is recovered from its first window.

use super::buffer::{Buffer, Incoming, Kind};
use super::config::RecoverySettings;
use super::losses::LossLedger;
use super::recovery_plan::{Pacing, Plan, Request, Target};
use super::status::Counters;
use rigmon_runtime::publish::recent::{same_run, Held, RecentQuery, SUFFIX};
use rigmon_runtime::publish::zenoh::FLEET_CONGESTION;
use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Points silent for this long have their tail asked of their daemon, once per silence
/// ([`Tracker::silent_tails`]).
pub const TAIL_SILENCE: Duration = Duration::from_secs(5);

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
    /// When its newest window came (or the tracker learnt of the point).
    seen: Instant,
    /// Its tail was asked for since then ([`Tracker::silent_tails`]).
    tail_asked: bool,
}

impl Track {
    fn new(run_start_ns: u64, high: u64) -> Track {
        Track {
            run_start_ns,
            high,
            seen: Instant::now(),
            tail_asked: false,
        }
    }
}

/// Each point's run and highest seq.
#[derive(Debug, Default)]
pub struct Tracker {
    points: HashMap<String, Track>,
    /// When the historian began listening (ns since the Unix epoch): a point seen for the
    /// first time whose run started later should have arrived whole, so its missing first
    /// windows are counted (lost if not recovered); a run that started before is a
    /// backfill, never counted. `None`: every first sight is a backfill.
    listening_since_ns: Option<u64>,
}

impl Tracker {
    /// Start from the database's last window per point (key -> (run start ns, seq)).
    pub fn seeded(last: HashMap<String, (u64, u64)>) -> Tracker {
        Tracker {
            points: last
                .into_iter()
                .map(|(k, (run_start_ns, high))| (k, Track::new(run_start_ns, high)))
                .collect(),
            listening_since_ns: None,
        }
    }

    /// The tracker of a historian that began listening at `ns` (ns since the Unix epoch).
    pub fn listening_since(mut self, ns: u64) -> Tracker {
        self.listening_since_ns = Some(ns);
        self
    }

    /// True when `seq` of this run is older than the point's newest window (it arrives
    /// late, out of order).
    pub fn is_late(&self, key: &str, run_start_ns: u64, seq: u64) -> bool {
        self.points
            .get(key)
            .is_some_and(|t| same_run(t.run_start_ns, run_start_ns) && seq < t.high)
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
                if seq > before {
                    (t.seen, t.tail_asked) = (Instant::now(), false);
                }
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
                *t = Track::new(run_start_ns, seq);
                gap(1, seq.saturating_sub(1), true)
            }
            None => {
                self.points
                    .insert(key.to_string(), Track::new(run_start_ns, seq));
                let counted = self.listening_since_ns.is_some_and(|t| run_start_ns >= t);
                gap(1, seq.saturating_sub(1), counted)
            }
        }
    }

    /// The tail of every point silent for `idle` since its newest window, asked once per
    /// silence: the `n` windows after its newest as a gap that is not counted (they may
    /// never have been made: the daemon stopped). A window dropped on the way with no later
    /// window behind it opens no gap; asking the daemon's recent history for the tail
    /// brings it back while the daemon still has it.
    pub fn silent_tails(&mut self, idle: Duration, n: u64) -> Vec<Gap> {
        let now = Instant::now();
        let mut out = Vec::new();
        for (key, t) in &mut self.points {
            if t.tail_asked || now.duration_since(t.seen) < idle || n == 0 {
                continue;
            }
            t.tail_asked = true;
            let Some(first) = t.high.checked_add(1) else {
                continue;
            };
            out.push(Gap {
                key: key.clone(),
                run_start_ns: t.run_start_ns,
                first,
                last: first.saturating_add(n - 1),
                counted: false,
            });
        }
        out
    }
}

/// The recovery plan shared by the write loop (gaps in, late windows out) and the recovery
/// task (requests out), and the bell that wakes the task.
#[derive(Debug, Default)]
pub struct Missing {
    plan: Mutex<Plan>,
    wake: tokio::sync::Notify,
}

impl Missing {
    pub fn new(pacing: Pacing) -> Missing {
        Missing {
            plan: Mutex::new(Plan::new(pacing)),
            wake: tokio::sync::Notify::new(),
        }
    }

    fn plan(&self) -> std::sync::MutexGuard<'_, Plan> {
        self.plan.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A gap the tracker found: into the plan, asked for after the grace period.
    pub fn gap(&self, g: Gap) {
        let target = Target {
            key: g.key,
            run_start_ns: g.run_start_ns,
            counted: g.counted,
        };
        self.plan().add(target, g.first, g.last, Instant::now());
        self.wake.notify_one();
    }

    /// The parts of `first..=last` of `key`'s run the plan is not asking for already.
    pub fn unplanned(
        &self,
        key: &str,
        run_start_ns: u64,
        first: u64,
        last: u64,
    ) -> Vec<(u64, u64)> {
        self.plan().unplanned(key, run_start_ns, first, last)
    }

    /// A live window that arrived after a later one of its point (out of order).
    pub fn arrived(&self, key: &str, run_start_ns: u64, seq: u64) {
        self.plan().arrived(key, run_start_ns, seq);
    }

    /// Windows waiting to be asked for, and requests out.
    pub fn level(&self) -> (u64, u64) {
        let p = self.plan();
        (p.waiting_windows(), p.in_flight() as u64)
    }
}

/// What one request's answer brought.
struct Answer {
    got: HashSet<u64>,
    /// The daemon's word on what it holds of the run (`None`: not heard: an older daemon,
    /// no daemon, or the word was dropped on the way).
    held: Option<Held>,
    /// The query ended by its timeout (replies or their end were dropped on the way, or the
    /// daemon is slow to answer): a congested link, not a daemon with nothing to say.
    timed_out: bool,
}

/// Ask a daemon's recent history for `ranges` of `target`; push what comes into the buffer.
/// Ends as soon as every asked window came (a dropped end-of-replies does not hold it up).
async fn ask(
    session: &zenoh::Session,
    prefix: &str,
    target: &Target,
    ranges: &[(u64, u64)],
    buffer: &Buffer,
    timeout: Duration,
) -> Answer {
    let query = RecentQuery {
        run_start_ns: Some(target.run_start_ns),
        seq: ranges.to_vec(),
        time: None,
    };
    let want: u64 = ranges.iter().map(|(a, b)| b - a + 1).sum();
    let selector = format!("{prefix}/{}/{SUFFIX}?{}", target.key, query.to_parameters());
    let mut answer = Answer {
        got: HashSet::new(),
        held: None,
        timed_out: false,
    };
    let t0 = Instant::now();
    // Every reply has the same key: no consolidation, or only the last would be kept.
    // Replies travel with the query's congestion control: `Drop`, so that replies queued to a
    // historian that reads slowly cannot close its transport (`Block` would, after 5 s; see
    // `FLEET_CONGESTION`); a dropped reply is asked again, then counted lost by seq range.
    let replies = session
        .get(selector.clone())
        .congestion_control(FLEET_CONGESTION)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(timeout)
        .await;
    let replies = match replies {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!("asking {selector} for missed windows failed: {e}");
            return answer;
        }
    };
    while (answer.got.len() as u64) < want {
        let Ok(reply) = replies.recv_async().await else {
            answer.timed_out = t0.elapsed() >= timeout.mul_f64(0.9);
            break;
        };
        let sample = match reply.result() {
            Ok(sample) => sample,
            Err(e) => {
                let word = Held::parse(&e.payload().to_bytes());
                answer.held = word.filter(|h| same_run(h.run_start_ns, target.run_start_ns));
                continue;
            }
        };
        let payload = sample.payload().to_bytes().into_owned();
        let Some(seq) =
            seq_of(&payload).filter(|s| ranges.iter().any(|&(a, b)| (a..=b).contains(s)))
        else {
            continue;
        };
        // Only a window the buffer kept is recovered: one it had to drop (memory and
        // spill full) is in the loss ledger and must stay there.
        if !answer.got.contains(&seq)
            && buffer.push(Incoming {
                kind: Kind::Health,
                key: format!("{prefix}/{}/health", target.key),
                payload,
                recovered: true,
            })
        {
            answer.got.insert(seq);
        }
    }
    answer
}

/// The `seq` of a health message, read without decoding the rest.
fn seq_of(payload: &[u8]) -> Option<u64> {
    #[derive(serde::Deserialize)]
    struct Seq {
        seq: u64,
    }
    serde_json::from_slice::<Seq>(payload).ok().map(|s| s.seq)
}

/// Answers that end without the daemon's word on what it holds ([`Held`]) before the windows
/// still missing are counted lost (no daemon answers, or an older one that says nothing).
const SILENT_ATTEMPTS: u32 = 3;

/// Asks at most, in all: a window the daemon says it holds, or whose query times out, and
/// whose reply is dropped every time (a congested link) is counted lost after the last, some
/// 4-6 minutes after the first: inside the daemons' default recent history (10 minutes), so
/// a window is asked for as long as its daemon can be expected to hold it.
const MAX_ATTEMPTS: u32 = 12;

/// The wait before asking again: 1 s after the first answer, doubling up to 32 s, so a
/// congested link gets room and a daemon that still holds the windows is asked while it does.
fn backoff(attempt: u32) -> Duration {
    Duration::from_secs(1 << attempt.saturating_sub(1).min(5))
}

/// Send one request, asking again (after [`backoff`]) for what did not come as long as the
/// daemon says it still holds it or the query timed out (up to [`MAX_ATTEMPTS`]), or the
/// answer ended without its word (up to [`SILENT_ATTEMPTS`]); what came is recovered, what arrived live meanwhile is late, the
/// rest is lost (the daemon no longer has it, or never answered).
async fn recover(ctx: Arc<Ctx>, request: Request) {
    let Ctx {
        session,
        prefix,
        buffer,
        counters,
        missing,
        timeout,
        enabled,
    } = &*ctx;
    let target = &request.target;
    Counters::add(&counters.requested, request.len());
    let mut ranges = request.ranges.clone();
    let mut got: HashSet<u64> = HashSet::new();
    let mut silent = 0;
    for attempt in (1..=MAX_ATTEMPTS).filter(|_| *enabled) {
        let a = ask(session, prefix, target, &ranges, buffer, *timeout).await;
        got.extend(a.got);
        silent += u32::from(a.held.is_none() && !a.timed_out);
        ranges = still_held(&uncovered(&ranges, &got), a.held);
        if ranges.is_empty() || silent >= SILENT_ATTEMPTS || attempt == MAX_ATTEMPTS {
            break;
        }
        Counters::add(
            &counters.asked_again,
            ranges.iter().map(|(a, b)| b - a + 1).sum(),
        );
        tokio::time::sleep(backoff(attempt)).await;
    }
    let late: HashSet<u64> = missing
        .plan()
        .finished(request.id)
        .into_iter()
        .filter(|s| !got.contains(s))
        .collect();
    missing.wake.notify_one();
    Counters::add(&counters.late, late.len() as u64);
    let found = got.len() as u64;
    let lost = request.len().saturating_sub(found + late.len() as u64);
    if target.counted {
        got.extend(&late);
        enter(&counters.losses, &request, &got);
        Counters::add(&counters.recovered, found);
        Counters::add(&counters.lost, lost);
        if lost > 0 {
            tracing::warn!(
                "{}: windows {:?} of run {} missed; {found} recovered, {lost} lost (older than the daemon's recent history, or the daemon is gone)",
                target.key, request.ranges, target.run_start_ns
            );
        } else {
            tracing::debug!(
                "{}: windows {:?} missed and recovered",
                target.key,
                request.ranges
            );
        }
    } else {
        Counters::add(&counters.backfilled, found);
        Counters::add(&counters.not_backfilled, lost);
    }
}

/// The seqs of `ranges` not in `got`, as ranges.
fn uncovered(ranges: &[(u64, u64)], got: &HashSet<u64>) -> Vec<(u64, u64)> {
    let mut out: Vec<(u64, u64)> = Vec::new();
    for &(a, b) in ranges {
        for s in a..=b {
            if got.contains(&s) {
                continue;
            }
            match out.last_mut() {
                Some(last) if last.1 + 1 == s => last.1 = s,
                _ => out.push((s, s)),
            }
        }
    }
    out
}

/// The part of `ranges` worth asking again: all of it when the daemon said nothing, else
/// what it said it holds (the rest is gone).
fn still_held(ranges: &[(u64, u64)], held: Option<Held>) -> Vec<(u64, u64)> {
    let Some(h) = held else {
        return ranges.to_vec();
    };
    let Some((lo, hi)) = h.seqs else {
        return Vec::new();
    };
    ranges
        .iter()
        .map(|&(a, b)| (a.max(lo), b.min(hi)))
        .filter(|(a, b)| a <= b)
        .collect()
}

/// Enter a counted request in the loss ledger: what was found (or arrived live) comes out
/// of it, the rest of each range goes in.
fn enter(ledger: &LossLedger, request: &Request, got: &HashSet<u64>) {
    let (key, run) = (&request.target.key, request.target.run_start_ns);
    for &(first, last) in &request.ranges {
        let mut found: Vec<u64> = got
            .iter()
            .copied()
            .filter(|s| (first..=last).contains(s))
            .collect();
        found.sort_unstable();
        let mut next = first;
        for &seq in &found {
            ledger.recovered(key, run, seq);
            if seq > next {
                ledger.add(key, run, next, seq - 1);
            }
            next = seq.saturating_add(1);
        }
        if next <= last && (found.last() != Some(&u64::MAX)) {
            ledger.add(key, run, next, last);
        }
    }
}

/// What every request needs.
struct Ctx {
    session: zenoh::Session,
    prefix: String,
    buffer: Arc<Buffer>,
    counters: Arc<Counters>,
    missing: Arc<Missing>,
    timeout: Duration,
    /// `[recovery] enabled`: false, every gap is counted lost without asking.
    enabled: bool,
}

/// The recovery task: sends each request of the plan as it falls due, at most the plan's
/// `in_flight` at once, each in its own task.
pub async fn run(
    session: zenoh::Session,
    prefix: String,
    missing: Arc<Missing>,
    buffer: Arc<Buffer>,
    counters: Arc<Counters>,
    settings: RecoverySettings,
) {
    let ctx = Arc::new(Ctx {
        session,
        prefix,
        buffer,
        counters,
        missing: missing.clone(),
        timeout: Duration::from_secs_f64(settings.query_timeout_s),
        enabled: settings.enabled,
    });
    loop {
        let now = Instant::now();
        while let Some(request) = missing.plan().next(now) {
            tokio::spawn(recover(ctx.clone(), request));
        }
        let wait = missing
            .plan()
            .next_due()
            .map_or(Duration::from_secs(1), |d| d.saturating_duration_since(now))
            .clamp(Duration::from_millis(10), Duration::from_secs(1));
        let _ = tokio::time::timeout(wait, missing.wake.notified()).await;
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
        let request = Request {
            id: 1,
            target: Target {
                key: "m/a/p".into(),
                run_start_ns: 9,
                counted: true,
            },
            ranges: vec![(10, 19), (30, 31)],
        };
        ledger.add("m/a/p", 9, 12, 12);
        enter(&ledger, &request, &[12, 13, 17, 30].into());
        enter(&ledger, &request, &[12, 13, 17, 30].into());
        let s = ledger.summary(10);
        let got: Vec<(u64, u64)> = s.ranges.iter().map(|r| (r.first, r.last)).collect();
        assert_eq!(got, [(10, 11), (14, 16), (18, 19), (31, 31)]);
        assert_eq!(s.windows, 8);
        enter(&ledger, &request, &(10..=31).collect());
        assert_eq!(ledger.total(), 0, "all recovered after all");
        assert_eq!(
            uncovered(&request.ranges, &[10, 11, 15, 31].into()),
            [(12, 14), (16, 19), (30, 30)]
        );
    }

    /// Asked again: what the daemon said it holds, all of it when it said nothing, nothing
    /// when it holds none of the run; the waits double from 1 s to 32 s.
    #[test]
    fn what_is_asked_again_is_what_the_daemon_still_holds() {
        let ranges = [(3, 5), (9, 12), (40, 41)];
        let held = |seqs| Held {
            run_start_ns: 7,
            seqs,
        };
        assert_eq!(still_held(&ranges, None), ranges);
        assert_eq!(
            still_held(&ranges, Some(held(Some((4, 10))))),
            [(4, 5), (9, 10)]
        );
        assert!(still_held(&ranges, Some(held(None))).is_empty());
        let waits: Vec<u64> = (1..MAX_ATTEMPTS).map(|a| backoff(a).as_secs()).collect();
        assert_eq!(waits, [1, 2, 4, 8, 16, 32, 32, 32, 32, 32, 32]);
        let total: u64 = waits.iter().sum();
        assert!(
            total < 600,
            "asked again within the daemons' default recent history"
        );
    }

    /// A point first seen with its window 1 missing: counted when its run started after the
    /// historian began listening (the window should have come), a backfill otherwise.
    #[test]
    fn a_new_points_missing_first_windows_count_when_its_run_began_after_the_historian() {
        let mut t = Tracker::default().listening_since(1_000);
        let after = t.observe("m/a/new", 2_000, 3).unwrap();
        assert_eq!((after.first, after.last, after.counted), (1, 2, true));
        let before = t.observe("m/a/old", 500, 3).unwrap();
        assert_eq!((before.first, before.last, before.counted), (1, 2, false));
        let mut plain = Tracker::default();
        assert!(!plain.observe("m/a/new", 2_000, 3).unwrap().counted);
    }

    /// A point gone silent has its tail asked once (uncounted), again only after a newer
    /// window came and it fell silent anew.
    #[test]
    fn a_silent_points_tail_is_asked_once_per_silence() {
        let mut t = Tracker::default();
        t.observe("m/a/p", 7, 1);
        t.observe("m/a/p", 7, 2);
        assert!(t.silent_tails(Duration::from_secs(3600), 8).is_empty());
        let tails = t.silent_tails(Duration::ZERO, 8);
        assert_eq!(tails.len(), 1);
        let g = &tails[0];
        assert_eq!(
            (g.first, g.last, g.counted, g.run_start_ns),
            (3, 10, false, 7)
        );
        assert!(
            t.silent_tails(Duration::ZERO, 8).is_empty(),
            "once per silence"
        );
        t.observe("m/a/p", 7, 3);
        assert_eq!(t.silent_tails(Duration::ZERO, 8)[0].first, 4);
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
