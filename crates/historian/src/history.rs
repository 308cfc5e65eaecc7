//! History back over Zenoh: the historian's queryable on `<prefix>/**/health` answers a `get`
//! that carries `_time=[..]` (queries without it are the daemons' to answer) with one reply
//! per stored window of every point the key expression matches, oldest first, rebuilt as a
//! `rigmon.health` message from the typed columns (the spectrum's DSP details are not
//! stored) plus the point's ISO 20816-3 zone limits (`iso_limits_mm_s`). More than `[history]
//! max_replies` windows is refused with an error reply naming the count.

use super::database::Target;
use super::row::ns_of;
use super::status::Counters;
use anyhow::{anyhow, Result};
use rigmon_core::health::iso20816::Zone;
use rigmon_core::health::{Basis, UnknownReason};
use rigmon_core::model::evidence::FamilyEvidence;
use rigmon_core::model::impulsiveness::Impulse;
use rigmon_core::vocabulary::Condition;
use rigmon_core::wire::health::{
    FaultBands, HealthMessage, ModelInfo, QualityReport, WindowTimes, SCHEMA, SCHEMA_VERSION,
};
use rigmon_runtime::publish::time_range::{now_ns, TimeRange, PARAMETER as TIME};
use rigmon_runtime::publish::zenoh::error_text;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::SystemTime;
use tokio_postgres::{Client, Row};

/// The columns read back, in the order [`message_of`] takes them.
const SELECT: &str = "SELECT p.key, t.site, w.time, w.window_s, w.run_start, w.seq, w.publish_time,
    w.state, w.state_since, w.state_changed, w.confidence, w.window_state, w.unknown_reason,
    w.alarm_despite, mo.name, mo.sha256, mo.labels, w.p_healthy, w.p_outer_race, w.p_inner_race,
    w.p_ball, w.p_other, w.novelty, w.novelty_threshold, w.baseline_distance, w.beyond_baseline,
    w.rpm, w.speed_source, w.velocity_rms_mm_s, w.iso_zone,
    w.bpfo_1, w.bpfo_2, w.bpfo_3, w.bpfi_1, w.bpfi_2, w.bpfi_3, w.two_bsf_1, w.two_bsf_2,
    w.two_bsf_3, w.band_floor, w.quality_ok, w.quality_flags, w.clipped_samples,
    w.nan_samples, w.dropout_samples, w.missing_tacho_pulses,
    p.band_channel, p.band_orders, p.calibration_id, p.software_version, p.iso_limits_mm_s,
    w.decision, w.overruled, w.evidence_outer_race, w.evidence_inner_race, w.evidence_ball,
    w.speed_confidence, w.speed_rival_rpm, w.model_foreign, w.impulse_beyond_healthy,
    w.impulse_beyond_gaussian
FROM windows w JOIN points p USING (point_id) JOIN asset_tree t USING (point_id)
JOIN models mo USING (model_id)";

/// One point as the queryable matches keys against it.
struct PointKey {
    id: i32,
    key: String,
}

fn basis(s: String) -> Basis {
    serde_json::from_value(serde_json::Value::String(s)).unwrap_or_default()
}

fn reason(s: Option<String>) -> Option<UnknownReason> {
    s.and_then(|v| serde_json::from_value(serde_json::Value::String(v)).ok())
}

/// The fault-family evidence (columns `from`..`from + 3`), when stored.
fn evidence(r: &Row, from: usize) -> Option<FamilyEvidence> {
    Some(FamilyEvidence {
        outer_race: r.get::<_, Option<f32>>(from)?,
        inner_race: r.get::<_, Option<f32>>(from + 1)?,
        ball: r.get::<_, Option<f32>>(from + 2)?,
    })
}

/// The impulsiveness (columns `from`, `from + 1`), when stored.
fn impulse(r: &Row, from: usize) -> Option<Impulse> {
    Some(Impulse {
        beyond_healthy: r.get::<_, Option<f32>>(from)?,
        beyond_gaussian: r.get::<_, Option<f32>>(from + 1)?,
    })
}

fn bands(r: &Row, from: usize) -> Vec<f32> {
    (from..from + 3)
        .map(|i| r.get::<_, Option<f32>>(i))
        .collect::<Option<Vec<f32>>>()
        .unwrap_or_default()
}

/// Rebuild the message of one row (see [`SELECT`]); adds `iso_limits_mm_s` when known.
fn message_of(r: &Row) -> serde_json::Value {
    let key: String = r.get(0);
    let mut parts = key.splitn(3, '/').map(str::to_string);
    let (rig, asset, point) = (
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
    );
    let end_ns = ns_of(r.get::<_, SystemTime>(2));
    let window_s: f32 = r.get(3);
    let run = ns_of(r.get::<_, SystemTime>(4));
    let start_ns = end_ns.saturating_sub((f64::from(window_s) * 1e9).round() as u64);
    let secs = |ns: u64| ns.saturating_sub(run) as f64 / 1e9;
    let labels: Vec<String> = r.get(16);
    let mut probabilities: BTreeMap<String, f32> = (Condition::NAMES.iter().enumerate())
        .filter_map(|(i, l)| Some((l.to_string(), r.get::<_, Option<f32>>(17 + i)?)))
        .collect();
    if let Some(serde_json::Value::Object(o)) = r.get::<_, Option<serde_json::Value>>(21) {
        for (l, p) in o {
            probabilities.insert(l, p.as_f64().unwrap_or(f64::NAN) as f32);
        }
    }
    let flags: Option<Vec<String>> = r.get(41);
    let u = |i: usize| r.get::<_, i32>(i).max(0) as u32;
    let orders: BTreeMap<String, f64> = r
        .get::<_, Option<serde_json::Value>>(47)
        .and_then(|v| serde_json::from_value(v).ok())
        .unwrap_or_default();
    let m = HealthMessage {
        schema: SCHEMA.into(),
        schema_version: SCHEMA_VERSION,
        rig,
        asset,
        point,
        site: Some(r.get(1)),
        seq: r.get::<_, i64>(5).max(0) as u64,
        window: WindowTimes {
            start_s: secs(start_ns),
            end_s: secs(end_ns),
            start_ns,
            end_ns,
        },
        publish_time_ns: ns_of(r.get::<_, SystemTime>(6)),
        rpm: r.get(26),
        speed_source: r.get(27),
        speed_confidence: r.get::<_, Option<f32>>(56).map(f64::from),
        speed_rival_rpm: r.get(57),
        quality: QualityReport {
            ok: r.get(40),
            flags: flags.unwrap_or_default(),
            clipped_samples: u(42),
            nan_samples: u(43),
            dropout_samples: u(44),
            missing_tacho_pulses: u(45),
            ..Default::default()
        },
        probabilities,
        window_state: r.get(11),
        unknown_reason: reason(r.get(12)),
        alarm_despite: reason(r.get(13)),
        decision: basis(r.get(51)),
        overruled: r.get(52),
        evidence: evidence(r, 53),
        impulse: impulse(r, 59),
        indicators: None,
        state: r.get(7),
        state_since_s: secs(ns_of(r.get::<_, SystemTime>(8))),
        state_changed: r.get(9),
        confidence: r.get(10),
        novelty: r.get(22),
        novelty_threshold: r.get(23),
        baseline_distance: r.get(24),
        beyond_baseline: r.get(25),
        fault_bands: FaultBands {
            channel: r.get::<_, Option<String>>(46).unwrap_or_default(),
            orders,
            bpfo: bands(r, 30),
            bpfi: bands(r, 33),
            two_bsf: bands(r, 36),
            floor: r.get::<_, Option<f32>>(39).unwrap_or(0.0),
        },
        velocity_rms_mm_s: r.get::<_, Option<f32>>(28).map(f64::from),
        iso_zone: r
            .get::<_, Option<String>>(29)
            .and_then(|z| serde_json::from_value::<Zone>(serde_json::Value::String(z)).ok()),
        model: ModelInfo {
            id: r.get(14),
            sha256: r.get(15),
            labels,
            foreign: r.get::<_, Option<Vec<String>>>(58).unwrap_or_default(),
        },
        calibration_id: r.get(48),
        software_version: r.get::<_, Option<String>>(49).unwrap_or_default(),
    };
    let mut v = serde_json::to_value(&m).unwrap_or_default();
    if let Some(l) = r.get::<_, Option<Vec<f32>>>(50) {
        v["iso_limits_mm_s"] = serde_json::json!(l);
    }
    v
}

/// Answer one query: Ok(None) when it is not a history query (no `_time`).
async fn answer(
    client: &Client,
    prefix: &str,
    query: &zenoh::query::Query,
    max: u64,
    counters: &Counters,
) -> Result<()> {
    let Some(t) = query.parameters().get(TIME) else {
        return Ok(());
    };
    let range = TimeRange::parse(t, now_ns())?;
    let points: Vec<PointKey> = client
        .query("SELECT point_id, key FROM points", &[])
        .await?
        .iter()
        .map(|r| PointKey {
            id: r.get(0),
            key: r.get(1),
        })
        .collect();
    let asked = query.key_expr();
    let mut ids = Vec::new();
    for p in &points {
        // A stored key that is no valid key expression (written before admission checked
        // names) is skipped, not allowed to break every query.
        match zenoh::key_expr::KeyExpr::try_from(format!("{prefix}/{}/health", p.key)) {
            Ok(ke) if asked.intersects(&ke) => ids.push(p.id),
            Ok(_) => {}
            Err(e) => tracing::debug!(
                "point {:?} skipped in history answers: not a key ({})",
                p.key,
                error_text(&e)
            ),
        }
    }
    Counters::add(&counters.queries_answered, 1);
    if ids.is_empty() {
        return Ok(());
    }
    let from = super::row::time_of(range.from_ns.unwrap_or(0));
    let until = super::row::time_of(range.until_ns.unwrap_or(u64::MAX / 2));
    let limit = i64::try_from(max).unwrap_or(i64::MAX - 1) + 1;
    let sql = format!("{SELECT} WHERE w.point_id = ANY($1) AND w.time >= $2 AND w.time < $3 ORDER BY w.point_id, w.time LIMIT $4");
    let rows = client.query(&sql, &[&ids, &from, &until, &limit]).await?;
    if rows.len() as u64 > max {
        let n: i64 = client
            .query_one("SELECT count(*) FROM windows WHERE point_id = ANY($1) AND time >= $2 AND time < $3", &[&ids, &from, &until])
            .await?
            .get(0);
        return Err(anyhow!("{n} windows match {asked} in {t}, more than [history] max_replies = {max}; narrow the time range or the key expression"));
    }
    for r in &rows {
        let key: String = r.get(0);
        let payload = serde_json::to_vec(&message_of(r))?;
        query
            .reply(format!("{prefix}/{key}/health"), payload)
            .await
            .map_err(|e| anyhow!("{}", error_text(&e)))?;
    }
    Counters::add(&counters.history_rows_sent, rows.len() as u64);
    Ok(())
}

/// The queryable's task: one database connection of its own (reconnected when lost).
pub async fn serve(
    session: zenoh::Session,
    prefix: String,
    target: Target,
    max: u64,
    counters: Arc<Counters>,
) -> Result<()> {
    let key = format!("{prefix}/**/health");
    let queryable = session
        .declare_queryable(key.clone())
        .await
        .map_err(|e| anyhow!("declaring the history queryable {key}: {e}"))?;
    let mut client: Option<Client> = None;
    while let Ok(query) = queryable.recv_async().await {
        if query.parameters().get(TIME).is_none() {
            continue;
        }
        if client.as_ref().is_none_or(|c| c.is_closed()) {
            client = match target.connect().await {
                Ok(c) => Some(c),
                Err(e) => {
                    let _ = query
                        .reply_err(format!(
                            "the historian cannot reach its database now: {e:#}"
                        ))
                        .await;
                    continue;
                }
            };
        }
        if let Some(c) = client.as_ref() {
            if let Err(e) = answer(c, &prefix, &query, max, &counters).await {
                tracing::info!("history query {} refused: {e:#}", query.selector());
                let _ = query.reply_err(format!("{e:#}")).await;
            }
        }
    }
    Ok(())
}
