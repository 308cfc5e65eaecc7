//! Alarms: the `events` table read back (`rigmon alarms`) and acknowledged (`rigmon ack`):
//! who, when, and a comment. An event is acknowledged once; a second `ack` says by whom it
//! already was.

use super::row::ns_of;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::time::SystemTime;
use tokio_postgres::{Client, Row};

/// One state-change event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    pub id: i64,
    pub time_ns: u64,
    pub site: String,
    /// `<machine>/<asset>/<point>`.
    pub point: String,
    pub from_state: Option<String>,
    pub to_state: String,
    /// How long `from_state` held, s.
    pub held_s: Option<f64>,
    pub confidence: f32,
    pub acked_ns: Option<u64>,
    pub acked_by: Option<String>,
    pub ack_comment: Option<String>,
}

/// Which events to list.
#[derive(Debug, Clone, Default)]
pub struct Filter {
    pub since: Option<SystemTime>,
    pub unacked_only: bool,
    /// Pattern on `<machine>/<asset>/<point>`: `*` matches anything, every other character
    /// itself (`%`, `_` and `\\` too: they are escaped for SQL LIKE).
    pub point: Option<String>,
    pub limit: i64,
}

const SELECT: &str = "SELECT e.event_id, e.time, t.site, t.key, e.from_state, e.to_state, e.held_s,
    e.confidence, e.acked_at, e.acked_by, e.ack_comment
FROM events e JOIN asset_tree t USING (point_id)";

fn alarm(r: &Row) -> Alarm {
    Alarm {
        id: r.get(0),
        time_ns: ns_of(r.get(1)),
        site: r.get(2),
        point: r.get(3),
        from_state: r.get(4),
        to_state: r.get(5),
        held_s: r.get(6),
        confidence: r.get(7),
        acked_ns: r.get::<_, Option<SystemTime>>(8).map(ns_of),
        acked_by: r.get(9),
        ack_comment: r.get(10),
    }
}

/// Events, newest first.
pub async fn list(client: &Client, f: &Filter) -> Result<Vec<Alarm>> {
    let since = f.since.unwrap_or(SystemTime::UNIX_EPOCH);
    let pattern = f.point.as_deref().map_or("%".to_string(), like_pattern);
    let sql = format!(
        "{SELECT} WHERE e.time >= $1 AND t.key LIKE $2 AND ($3 = false OR e.acked_at IS NULL)
         ORDER BY e.time DESC, e.event_id DESC LIMIT $4"
    );
    let rows = client
        .query(&sql, &[&since, &pattern, &f.unacked_only, &f.limit])
        .await?;
    Ok(rows.iter().map(alarm).collect())
}

/// A `*` pattern as SQL LIKE: the LIKE wildcards `%` and `_` (and the escape `\\`) in names
/// match only themselves.
pub fn like_pattern(p: &str) -> String {
    p.replace('\\', "\\\\")
        .replace('%', "\\%")
        .replace('_', "\\_")
        .replace('*', "%")
}

/// Acknowledge event `id` as `user` with `comment`.
pub async fn ack(client: &Client, id: i64, user: &str, comment: &str) -> Result<Alarm> {
    if user.trim().is_empty() {
        bail!("say who acknowledges: --user NAME");
    }
    let n = client
        .execute(
            "UPDATE events SET acked_at = now(), acked_by = $2, ack_comment = $3
             WHERE event_id = $1 AND acked_at IS NULL",
            &[&id, &user, &comment],
        )
        .await?;
    let row = client
        .query_opt(&format!("{SELECT} WHERE e.event_id = $1"), &[&id])
        .await?;
    let Some(row) = row else {
        bail!("no event {id}; `rigmon alarms` lists them with their ids");
    };
    let a = alarm(&row);
    if n == 0 {
        bail!(
            "event {id} was already acknowledged by {} ({}); nothing changed",
            a.acked_by.as_deref().unwrap_or("?"),
            a.ack_comment.as_deref().unwrap_or("")
        );
    }
    Ok(a)
}

/// One line for a terminal.
pub fn line(a: &Alarm) -> String {
    let when = humantime::format_rfc3339_millis(super::row::time_of(a.time_ns));
    let held = a.held_s.map_or("-".to_string(), |h| format!("{h:.1} s"));
    let ack = match (&a.acked_by, a.acked_ns) {
        (Some(by), Some(t)) => format!(
            "acked by {by} at {}{}",
            humantime::format_rfc3339_seconds(super::row::time_of(t)),
            a.ack_comment
                .as_deref()
                .filter(|c| !c.is_empty())
                .map(|c| format!(": {c}"))
                .unwrap_or_default()
        ),
        _ => "NOT ACKED".into(),
    };
    format!(
        "{:>6}  {when}  {}/{}  {} -> {}  (held {held}, confidence {:.0}%)  {ack}",
        a.id,
        a.site,
        a.point,
        a.from_state.as_deref().unwrap_or("-"),
        a.to_state,
        a.confidence * 100.0
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_patterns_escape_like_wildcards() {
        assert_eq!(like_pattern("lut-rig/*"), "lut-rig/%");
        assert_eq!(like_pattern("pump_1/*"), "pump\\_1/%");
        assert_eq!(like_pattern("100%/a\\b"), "100\\%/a\\\\b");
    }
}
