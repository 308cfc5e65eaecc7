//! The daemon's recent history for late joiners: the last `[zenoh] history_windows` health
//! messages (default 1200 = 10 minutes at 2 windows/s) kept in memory and answered on
//! `<base>/recent`. A historian that was down, or that saw a gap in a point's `seq`, asks
//! `<base>/recent?run=<run start ns>;seq=[a..b]` (or several ranges in one request,
//! `seq=[a..b]|[c..d]`, or `_time=[..]`) and gets back exactly the messages it missed, as
//! long as they are still here; what is older is gone and the historian counts it as lost.
//! Read-only: the query payload is ignored.

use super::time_range::{TimeRange, PARAMETER as TIME};
use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use zenoh::Wait;

/// Windows kept by default: 10 minutes at the usual 2 windows/s.
pub const DEFAULT_WINDOWS: usize = 1200;
/// Key suffix of the queryable.
pub const SUFFIX: &str = "recent";

/// The fields of a health message the cache indexes by.
#[derive(Deserialize)]
struct Head {
    seq: u64,
    window: HeadWindow,
}

#[derive(Deserialize)]
struct HeadWindow {
    end_s: f64,
    end_ns: u64,
}

/// The wall-clock origin of a daemon run (its `start_ns`): the same for every window of one
/// run, different after a restart. Health messages carry `window.end_ns = start + end_s`.
pub fn run_start_ns(end_ns: u64, end_s: f64) -> u64 {
    end_ns.saturating_sub((end_s * 1e9).round() as u64)
}

/// Two run origins are the same run when they agree to the microsecond (a database keeps
/// times in µs; runs start seconds apart).
pub fn same_run(a: u64, b: u64) -> bool {
    a.abs_diff(b) < 2_000
}

struct Entry {
    seq: u64,
    end_ns: u64,
    run_start_ns: u64,
    json: Arc<[u8]>,
}

/// What a query asks for.
#[derive(Debug, Default, PartialEq)]
pub struct RecentQuery {
    pub run_start_ns: Option<u64>,
    /// Inclusive seq ranges (empty: any seq).
    pub seq: Vec<(u64, u64)>,
    pub time: Option<TimeRange>,
}

impl RecentQuery {
    /// Read `run=..;seq=[a..b]|[c..d];_time=[..]` from a selector's parameters.
    pub fn parse(params: &zenoh::query::Parameters, now_ns: u64) -> Result<Self> {
        let run_start_ns = params
            .get("run")
            .map(|r| r.parse::<u64>().map_err(|e| anyhow!("run={r:?}: {e}")))
            .transpose()?;
        let seq = match params.get("seq") {
            Some(v) => v.split('|').map(parse_seq).collect::<Result<Vec<_>>>()?,
            None => Vec::new(),
        };
        let time = params
            .get(TIME)
            .map(|t| TimeRange::parse(t, now_ns))
            .transpose()?;
        Ok(RecentQuery {
            run_start_ns,
            seq,
            time,
        })
    }

    /// The selector parameters for this query.
    pub fn to_parameters(&self) -> String {
        let mut p = Vec::new();
        if let Some(r) = self.run_start_ns {
            p.push(format!("run={r}"));
        }
        if !self.seq.is_empty() {
            let ranges: Vec<String> = self
                .seq
                .iter()
                .map(|(a, b)| format!("[{a}..{b}]"))
                .collect();
            p.push(format!("seq={}", ranges.join("|")));
        }
        if let Some(t) = self.time {
            p.push(format!("{TIME}={}", t.to_selector_value()));
        }
        p.join(";")
    }

    /// What the ring holds of the asked run, for a query by run and seq (the historian's);
    /// `None` for any other query.
    fn held(&self, ring: &VecDeque<Entry>) -> Option<Held> {
        let run = self.run_start_ns.filter(|_| !self.seq.is_empty())?;
        let seqs = ring.iter().filter(|e| same_run(run, e.run_start_ns)).fold(
            None,
            |r: Option<(u64, u64)>, e| {
                Some(r.map_or((e.seq, e.seq), |(a, b)| (a.min(e.seq), b.max(e.seq))))
            },
        );
        Some(Held {
            run_start_ns: run,
            seqs,
        })
    }

    fn matches(&self, e: &Entry) -> bool {
        self.run_start_ns
            .is_none_or(|r| same_run(r, e.run_start_ns))
            && (self.seq.is_empty() || self.seq.iter().any(|&(a, b)| (a..=b).contains(&e.seq)))
            && self.time.is_none_or(|t| t.contains(e.end_ns))
    }
}

/// The daemon's last word on a query for a run's seq ranges: the seqs of that run its ring
/// holds (`None`: none). Sent after the windows as an *error* reply, so that no consumer
/// takes it for a window; [`Held::parse`] reads it back. A window asked and not received that
/// the daemon holds was dropped on the way (ask again); one it does not hold is gone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Held {
    pub run_start_ns: u64,
    /// Lowest and highest seq of the run in the ring (inclusive).
    pub seqs: Option<(u64, u64)>,
}

/// The `schema` of a [`Held`] statement.
pub const HELD_SCHEMA: &str = "rigmon.recent.held";

#[derive(Serialize, Deserialize)]
struct HeldMessage {
    schema: String,
    #[serde(flatten)]
    held: Held,
}

impl Held {
    /// The statement's bytes (JSON with `schema` = [`HELD_SCHEMA`]).
    pub fn to_json(&self) -> Vec<u8> {
        let m = HeldMessage {
            schema: HELD_SCHEMA.to_string(),
            held: *self,
        };
        serde_json::to_vec(&m).unwrap_or_default()
    }

    /// A statement read back; `None` for any other error reply.
    pub fn parse(bytes: &[u8]) -> Option<Held> {
        serde_json::from_slice::<HeldMessage>(bytes)
            .ok()
            .filter(|m| m.schema == HELD_SCHEMA)
            .map(|m| m.held)
    }

    /// True when the daemon said it holds `seq` of the asked run.
    pub fn holds(&self, seq: u64) -> bool {
        self.seqs.is_some_and(|(a, b)| (a..=b).contains(&seq))
    }

    /// Send the statement as the query's last reply (an error reply).
    pub fn reply(&self, query: &zenoh::query::Query) {
        if let Err(e) = query.reply_err(self.to_json()).wait() {
            tracing::debug!("zenoh reply on {} failed: {e}", query.key_expr());
        }
    }
}

/// `[a..b]` (inclusive) or a single number.
fn parse_seq(s: &str) -> Result<(u64, u64)> {
    let inner = s.trim().trim_start_matches('[').trim_end_matches(']');
    let num = |v: &str| {
        v.trim()
            .parse::<u64>()
            .map_err(|e| anyhow!("seq={s:?}: {e}; write it like seq=[120..180]"))
    };
    match inner.split_once("..") {
        Some((a, b)) => {
            let (a, b) = (num(a)?, num(b)?);
            if b < a {
                bail!("seq={s:?}: the end is before the start");
            }
            Ok((a, b))
        }
        None => num(inner).map(|v| (v, v)),
    }
}

/// The ring of recent health messages and the queryable that serves it.
pub struct RecentHistory {
    entries: Arc<Mutex<VecDeque<Entry>>>,
    capacity: usize,
    _queryable: zenoh::query::Queryable<()>,
}

impl RecentHistory {
    /// Declare `<base>/recent` keeping `capacity` messages (None when `capacity` is 0).
    /// `answered` counts the queries that got at least one reply.
    pub fn declare(
        session: &zenoh::Session,
        base: &str,
        capacity: usize,
        answered: Arc<AtomicU64>,
    ) -> Result<Option<Self>> {
        if capacity == 0 {
            return Ok(None);
        }
        let entries: Arc<Mutex<VecDeque<Entry>>> =
            Arc::new(Mutex::new(VecDeque::with_capacity(capacity.min(4096))));
        let key = format!("{base}/{SUFFIX}");
        let store = entries.clone();
        let reply_key = key.clone();
        let queryable = session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let now = super::time_range::now_ns();
                let q = match RecentQuery::parse(query.parameters(), now) {
                    Ok(q) => q,
                    Err(e) => {
                        let _ = query.reply_err(format!("{e:#}")).wait();
                        return;
                    }
                };
                let (hits, held): (Vec<Arc<[u8]>>, Option<Held>) = match store.lock() {
                    Ok(g) => (
                        g.iter()
                            .filter(|e| q.matches(e))
                            .map(|e| e.json.clone())
                            .collect(),
                        q.held(&g),
                    ),
                    Err(_) => return,
                };
                if !hits.is_empty() {
                    answered.fetch_add(1, Ordering::Relaxed);
                }
                for json in hits {
                    if let Err(e) = query.reply(reply_key.clone(), json.to_vec()).wait() {
                        tracing::debug!("zenoh reply on {reply_key} failed: {e}");
                        break;
                    }
                }
                if let Some(h) = held {
                    h.reply(&query);
                }
            })
            .wait()
            .map_err(|e| anyhow!("zenoh: {e}"))
            .with_context(|| format!("declaring queryable {key}"))?;
        Ok(Some(RecentHistory {
            entries,
            capacity,
            _queryable: queryable,
        }))
    }

    /// Keep one health message (JSON); the oldest goes when the ring is full. A message the
    /// cache cannot index (no `seq`/`window`) is not kept.
    pub fn push(&self, json: &[u8]) {
        let Ok(h) = serde_json::from_slice::<Head>(json) else {
            return;
        };
        let entry = Entry {
            seq: h.seq,
            end_ns: h.window.end_ns,
            run_start_ns: run_start_ns(h.window.end_ns, h.window.end_s),
            json: Arc::from(json),
        };
        if let Ok(mut g) = self.entries.lock() {
            if g.len() == self.capacity {
                g.pop_front();
            }
            g.push_back(entry);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_parameters_round_trip_and_select() {
        let q = RecentQuery {
            run_start_ns: Some(42),
            seq: vec![(3, 5)],
            time: None,
        };
        let p = zenoh::query::Parameters::from(q.to_parameters());
        assert_eq!(RecentQuery::parse(&p, 0).unwrap(), q);
        let e = |seq, run| Entry {
            seq,
            end_ns: 100,
            run_start_ns: run,
            json: Arc::from(&b"{}"[..]),
        };
        assert!(q.matches(&e(4, 42)) && !q.matches(&e(6, 42)) && !q.matches(&e(4, 41_000)));
        assert!(
            q.matches(&e(4, 1042)),
            "a run origin read back from µs is the same run"
        );
        assert_eq!(parse_seq("7").unwrap(), (7, 7));
        let two = RecentQuery {
            run_start_ns: Some(42),
            seq: vec![(3, 5), (9, 9)],
            time: None,
        };
        assert_eq!(two.to_parameters(), "run=42;seq=[3..5]|[9..9]");
        let p = zenoh::query::Parameters::from(two.to_parameters());
        assert_eq!(RecentQuery::parse(&p, 0).unwrap(), two);
        assert!(two.matches(&e(9, 42)) && !two.matches(&e(7, 42)));
        assert!(parse_seq("[9..2]").is_err());
        assert_eq!(run_start_ns(5_500_000_123, 1.5), 4_000_000_123);
    }

    #[test]
    fn a_seq_query_gets_the_rings_word_on_what_it_holds() {
        let e = |seq, run| Entry {
            seq,
            end_ns: 100,
            run_start_ns: run,
            json: Arc::from(&b"{}"[..]),
        };
        let ring: VecDeque<Entry> = [e(7, 9_000_000), e(8, 42), e(9, 42), e(12, 42)].into();
        let q = RecentQuery {
            run_start_ns: Some(42),
            seq: vec![(1, 20)],
            time: None,
        };
        let held = q.held(&ring).unwrap();
        assert_eq!(held.seqs, Some((8, 12)));
        assert!(held.holds(8) && held.holds(12) && !held.holds(7) && !held.holds(13));
        assert_eq!(Held::parse(&held.to_json()), Some(held));
        assert_eq!(
            Held::parse(br#"{"schema":"other","run_start_ns":42}"#),
            None
        );
        let other_run = RecentQuery {
            run_start_ns: Some(5_000_000),
            ..q
        };
        assert_eq!(other_run.held(&ring).unwrap().seqs, None);
        let by_time = RecentQuery {
            run_start_ns: Some(42),
            seq: Vec::new(),
            time: None,
        };
        assert_eq!(
            by_time.held(&ring),
            None,
            "only a query by run and seq gets the word"
        );
    }
}
