//! The holes in the historian's database: windows missing inside each point's latest run
//! among its stored windows of the last `span_s` seconds, and a run's first windows when its
//! first stored window (within the span) is not window 1. A historian
//! stopped while it was still asking for a gap (in its grace period, or its answer on the
//! way) forgets it, and its successor's gap tracker starts at each point's newest stored
//! window; a window the gap tracker never saw missing (whatever the reason) leaves a hole
//! too. The [`super::audit`] searches for them at start and whenever the historian has
//! caught up, on a connection of its own beside the write loop (at 5,000 points the last 10
//! minutes are 6 million windows).

use super::recovery::Gap;
use super::row::ns_of;
use anyhow::{Context, Result};
use std::time::SystemTime;
use tokio_postgres::Client;

/// A hole: the gap it makes, and the stored windows' times on either side of it (the run's
/// start before a run's first windows), to check it again cheaply ([`still_missing`]).
#[derive(Debug, Clone)]
pub struct Hole {
    pub gap: Gap,
    run_start: SystemTime,
    after: SystemTime,
    before: SystemTime,
}

/// Each point's holes over the `span_s` seconds before its newest stored window (one index
/// range scan per point, and one index probe for the first window in the span). A hole
/// inside the stored windows is a counted gap; the first windows of a run are counted when
/// the run began after `listening_since_ns` (the historian was listening), else a backfill.
pub async fn recent(client: &Client, span_s: f64, listening_since_ns: u64) -> Result<Vec<Hole>> {
    let rows = client
        .query(
            "SELECT p.key, l.run_start, h.prev + 1, h.seq - 1, coalesce(h.prev_time, l.run_start), h.time
             FROM point_latest l JOIN points p USING (point_id)
             CROSS JOIN LATERAL (
               SELECT w.seq, w.time, lag(w.time) OVER (ORDER BY w.time) AS prev_time,
                      coalesce(lag(w.seq) OVER (ORDER BY w.time),
                               CASE WHEN (SELECT o.run_start FROM windows o
                                          WHERE o.point_id = l.point_id AND o.time < w.time
                                          ORDER BY o.time DESC LIMIT 1)
                                         IS DISTINCT FROM l.run_start
                                    THEN 0 END) AS prev
               FROM windows w
               WHERE w.point_id = l.point_id AND w.run_start = l.run_start
                 AND w.time >= l.time - make_interval(secs => $1) AND w.time <= l.time) h
             WHERE h.seq > h.prev + 1",
            &[&span_s],
        )
        .await
        .context("looking for holes in the recent windows")?;
    Ok(rows
        .iter()
        .map(|r| {
            let run_start: SystemTime = r.get(1);
            let run_start_ns = ns_of(run_start);
            let first = r.get::<_, i64>(2).max(1) as u64;
            Hole {
                gap: Gap {
                    key: r.get(0),
                    run_start_ns,
                    first,
                    last: r.get::<_, i64>(3).max(1) as u64,
                    counted: first > 1 || run_start_ns >= listening_since_ns,
                },
                run_start,
                after: r.get(4),
                before: r.get(5),
            }
        })
        .collect())
}

/// The parts of `holes` still missing now (a window written since the search fills its
/// part): one index range scan per hole, between the stored windows around it.
pub async fn still_missing(client: &Client, holes: Vec<Hole>) -> Result<Vec<Gap>> {
    let keys: Vec<&str> = holes.iter().map(|h| h.gap.key.as_str()).collect();
    let runs: Vec<SystemTime> = holes.iter().map(|h| h.run_start).collect();
    let after: Vec<SystemTime> = holes.iter().map(|h| h.after).collect();
    let before: Vec<SystemTime> = holes.iter().map(|h| h.before).collect();
    let rows = client
        .query(
            "SELECT h.i, w.seq
             FROM unnest($1::text[], $2::timestamptz[], $3::timestamptz[], $4::timestamptz[])
                  WITH ORDINALITY AS h(k, run, t0, t1, i)
             JOIN points p ON p.key = h.k
             JOIN windows w ON w.point_id = p.point_id AND w.run_start = h.run
                           AND w.time > h.t0 AND w.time < h.t1",
            &[&keys, &runs, &after, &before],
        )
        .await
        .context("checking the holes found again")?;
    let mut filled: Vec<Vec<u64>> = vec![Vec::new(); holes.len()];
    for r in &rows {
        let i = r.get::<_, i64>(0) as usize;
        if let Some(f) = i.checked_sub(1).and_then(|i| filled.get_mut(i)) {
            f.push(r.get::<_, i64>(1).max(0) as u64);
        }
    }
    let mut out = Vec::new();
    for (h, mut f) in holes.into_iter().zip(filled) {
        f.sort_unstable();
        let mut next = h.gap.first;
        for seq in f.into_iter().chain([h.gap.last.saturating_add(1)]) {
            if seq > next && next <= h.gap.last {
                out.push(Gap {
                    first: next,
                    last: (seq - 1).min(h.gap.last),
                    ..h.gap.clone()
                });
            }
            next = next.max(seq.saturating_add(1));
        }
    }
    Ok(out)
}
