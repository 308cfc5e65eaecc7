//! The holes a historian finds in its database when it starts: windows missing inside each
//! point's latest run among its stored windows of the last `[recovery] hole_scan_s`. A
//! historian stopped while it was still asking for a gap (in its grace period, or its answer
//! on the way) forgets it, and its successor's gap tracker starts at each point's newest
//! stored window; this search finds them again. It runs once, on its own connection, beside
//! the write loop (at 5,000 points the last 10 minutes are 6 million windows).

use super::recovery::Gap;
use super::row::ns_of;
use anyhow::{Context, Result};
use tokio_postgres::Client;

/// Each point's holes over the `span_s` seconds before its newest stored window (one index
/// range scan per point), as counted gaps.
pub async fn recent(client: &Client, span_s: f64) -> Result<Vec<Gap>> {
    let rows = client
        .query(
            "SELECT p.key, l.run_start, h.prev + 1, h.seq - 1
             FROM point_latest l JOIN points p USING (point_id)
             CROSS JOIN LATERAL (
               SELECT w.seq, lag(w.seq) OVER (ORDER BY w.time) AS prev
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
        .map(|r| Gap {
            key: r.get(0),
            run_start_ns: ns_of(r.get(1)),
            first: r.get::<_, i64>(2).max(1) as u64,
            last: r.get::<_, i64>(3).max(1) as u64,
            counted: true,
        })
        .collect())
}
