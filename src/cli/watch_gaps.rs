//! `rigmon watch`'s account of the windows it missed on the way. Zenoh drops a health
//! message when a send queue stays full (the fleet's congestion policy, `FLEET_CONGESTION`);
//! the drop shows as a gap in the point's `seq` when its next window arrives. The gap is
//! asked of the daemon's recent history (`<base>/recent?run=..;seq=[a..b]`, what the
//! historian asks) and what comes back is printed like a live window; what does not is said
//! by point and seq range, and counted in the summary at the end. Nothing goes missing from
//! the watcher's output without a line saying so.

use crate::historian::recovery::{Gap, Tracker};
use crate::publish::recent::{run_start_ns, same_run, RecentQuery, SUFFIX};
use crate::publish::time_range::now_ns;
use crate::publish::zenoh::ZenohSubscriber;
use crate::wire::health::HealthMessage;
use std::time::Duration;

/// How long the daemon is given to answer for a gap.
const ASK_TIMEOUT: Duration = Duration::from_secs(2);

/// The gaps seen so far and what became of them.
pub struct MissedWindows {
    tracker: Tracker,
    /// Windows missed on the way and recovered from the daemons' recent history.
    pub recovered: u64,
    /// Windows missed on the way that no daemon had any more (or that did not answer).
    pub lost: Vec<Gap>,
}

impl MissedWindows {
    /// Following every point's run from now: a run that starts later is expected whole.
    pub fn new() -> MissedWindows {
        MissedWindows {
            tracker: Tracker::default().listening_since(now_ns()),
            recovered: 0,
            lost: Vec::new(),
        }
    }

    /// A live health message `m` came on `key`: the windows before it that did not come,
    /// fetched from its daemon, in seq order (empty when nothing was missed).
    pub fn before(
        &mut self,
        sub: &ZenohSubscriber,
        key: &str,
        m: &HealthMessage,
    ) -> Vec<(String, Vec<u8>)> {
        let run = run_start_ns(m.window.end_ns, m.window.end_s);
        let Some(gap) = self.tracker.observe(key, run, m.seq).filter(|g| g.counted) else {
            return Vec::new();
        };
        let got = ask(sub, key, &gap);
        self.recovered += got.len() as u64;
        let missing = gap.len() - got.len() as u64;
        if missing > 0 {
            tracing::warn!(
                "{key}: {missing} of the {} windows seq {}..{} did not come and are not in the daemon's recent history (dropped on the way, zenoh's congestion policy; the daemon gone or its history past them)",
                gap.len(),
                gap.first,
                gap.last
            );
            self.lost.push(gap);
        } else {
            tracing::info!(
                "{key}: windows seq {}..{} did not come; fetched from the daemon's recent history",
                gap.first,
                gap.last
            );
        }
        got.into_iter()
            .map(|(_, json)| (key.to_string(), json))
            .collect()
    }

    /// The closing account, when anything was missed.
    pub fn summary(&self) -> Option<String> {
        let lost: u64 = self.lost.iter().map(Gap::len).sum();
        if self.recovered == 0 && lost == 0 {
            return None;
        }
        let ranges: Vec<String> = self
            .lost
            .iter()
            .map(|g| format!("{} seq {}..{}", g.key, g.first, g.last))
            .collect();
        Some(format!(
            "{} windows missed on the way were fetched from the daemons' recent history; {lost} are lost{}{}",
            self.recovered,
            if ranges.is_empty() { "" } else { ": " },
            ranges.join(", ")
        ))
    }
}

impl Default for MissedWindows {
    fn default() -> Self {
        MissedWindows::new()
    }
}

/// The gap's windows from the recent history of the daemon publishing on `key` (its health
/// key), in seq order, each once.
fn ask(sub: &ZenohSubscriber, key: &str, gap: &Gap) -> Vec<(u64, Vec<u8>)> {
    let Some(base) = key.strip_suffix("/health") else {
        return Vec::new();
    };
    let query = RecentQuery {
        run_start_ns: Some(gap.run_start_ns),
        seq: vec![(gap.first, gap.last)],
        time: None,
    };
    let selector = format!("{base}/{SUFFIX}?{}", query.to_parameters());
    let replies = match sub.get(&selector, ASK_TIMEOUT) {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!("{key}: asking {selector} for the missed windows failed: {e:#}");
            return Vec::new();
        }
    };
    let mut got: Vec<(u64, Vec<u8>)> = replies
        .into_iter()
        .filter_map(|(_, json)| {
            let m = serde_json::from_slice::<HealthMessage>(&json).ok()?;
            let run = run_start_ns(m.window.end_ns, m.window.end_s);
            let wanted = (gap.first..=gap.last).contains(&m.seq) && same_run(run, gap.run_start_ns);
            wanted.then_some((m.seq, json))
        })
        .collect();
    got.sort_by_key(|(seq, _)| *seq);
    got.dedup_by_key(|(seq, _)| *seq);
    got
}
