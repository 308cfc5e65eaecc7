//! History back over Zenoh: the historian's queryable on `<prefix>/**/health` answers a `get`
//! that carries `_time=[..]` (queries without it are the daemons' to answer) with one reply
//! per stored window of every point the key expression matches, oldest first, rebuilt as a
//! `rigmon.health` message from the typed columns (the spectrum's DSP details are not
//! stored) plus the point's ISO 20816-3 zone limits (`iso_limits_mm_s`). More than `[history]
//! max_replies` windows is refused with an error reply naming the count.

use super::columns::{self, Read};
use super::database::Target;
use super::row::ns_of;
use super::status::Counters;
use anyhow::{anyhow, Result};
use rigmon_core::health::iso20816::Zone;
use rigmon_core::health::{Basis, UnknownReason};
use rigmon_core::model::departure::DepartureReading;
use rigmon_core::model::evidence::FamilyEvidence;
use rigmon_core::model::impulsiveness::Impulse;
use rigmon_core::model::indicators::{Indicator, Indicators, PerIndicator};
use rigmon_core::vocabulary::Condition;
use rigmon_core::wire::health::{
    FaultBands, HealthIndicators, HealthMessage, ModelInfo, QualityReport, WindowTimes, SCHEMA,
    SCHEMA_VERSION,
};
use rigmon_runtime::publish::time_range::{now_ns, TimeRange, PARAMETER as TIME};
use rigmon_runtime::publish::zenoh::error_text;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::SystemTime;
use tokio_postgres::{Client, Row};

/// Where the history query reads from ([`columns::select`] names the columns).
const FROM: &str =
    "FROM windows w JOIN points p USING (point_id) JOIN asset_tree t USING (point_id)
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

/// Columns `<prefix>rms`, `<prefix>crest`, `<prefix>kurtosis`, `<prefix>resonance`, when
/// all four are stored.
fn four(r: &Read, prefix: &str) -> Option<PerIndicator> {
    let mut a = [0.0; 4];
    for (v, i) in a.iter_mut().zip(Indicator::ALL) {
        *v = r.get::<Option<f32>>(&format!("{prefix}{}", i.as_str()))?;
    }
    Some(PerIndicator::from_array(a))
}

/// The health indicators and the departure test's reading, when stored.
fn indicators(r: &Read, run: u64) -> Option<HealthIndicators> {
    let v = four(r, "indicator_")?;
    let samples = r.get::<Option<i32>>("indicator_samples")?;
    Some(HealthIndicators {
        values: Indicators {
            rms: v.rms,
            crest: v.crest,
            kurtosis: v.kurtosis,
            resonance: v.resonance,
            samples: samples.max(0) as usize,
        },
        departure: departure(r, run),
    })
}

/// The departure test's reading, when stored.
fn departure(r: &Read, run: u64) -> Option<DepartureReading> {
    Some(DepartureReading {
        scores: four(r, "departure_score_")?,
        smoothed: four(r, "departure_smoothed_"),
        threshold: four(r, "departure_threshold_")?,
        leading: r
            .get::<Option<String>>("departure_leading")
            .and_then(|l| serde_json::from_value(serde_json::Value::String(l)).ok()),
        excess: r.get("departure_excess"),
        beyond_for: r.get::<Option<i32>>("departure_beyond_for")?.max(0) as usize,
        departed_since_s: r
            .get::<Option<SystemTime>>("departed_since")
            .map(|t| ns_of(t).saturating_sub(run) as f64 / 1e9),
    })
}

/// The fault-family evidence, when stored.
fn evidence(r: &Read) -> Option<FamilyEvidence> {
    Some(FamilyEvidence {
        outer_race: r.get::<Option<f32>>("evidence_outer_race")?,
        inner_race: r.get::<Option<f32>>("evidence_inner_race")?,
        ball: r.get::<Option<f32>>("evidence_ball")?,
    })
}

/// The impulsiveness, when stored.
fn impulse(r: &Read) -> Option<Impulse> {
    Some(Impulse {
        beyond_healthy: r.get::<Option<f32>>("impulse_beyond_healthy")?,
        beyond_gaussian: r.get::<Option<f32>>("impulse_beyond_gaussian")?,
    })
}

/// A fault order's harmonics 1-3 (`<family>_1`..`<family>_3`), when all are stored.
fn bands(r: &Read, family: &str) -> Vec<f32> {
    (1..=3)
        .map(|h| r.get::<Option<f32>>(&format!("{family}_{h}")))
        .collect::<Option<Vec<f32>>>()
        .unwrap_or_default()
}

/// The class probabilities: the four typed columns and `p_other`.
fn probabilities(r: &Read) -> BTreeMap<String, f32> {
    let mut p: BTreeMap<String, f32> = Condition::NAMES
        .iter()
        .filter_map(|l| Some((l.to_string(), r.get::<Option<f32>>(&format!("p_{l}"))?)))
        .collect();
    if let Some(serde_json::Value::Object(o)) = r.get::<Option<serde_json::Value>>("p_other") {
        for (l, v) in o {
            p.insert(l, v.as_f64().unwrap_or(f64::NAN) as f32);
        }
    }
    p
}

/// The quality flags and counts (not stored: the DSP details and the flat channels' names).
fn quality(r: &Read) -> QualityReport {
    let u = |c: &str| r.get::<i32>(c).max(0) as u32;
    QualityReport {
        ok: r.get("quality_ok"),
        flags: r
            .get::<Option<Vec<String>>>("quality_flags")
            .unwrap_or_default(),
        clipped_samples: u("clipped_samples"),
        nan_samples: u("nan_samples"),
        dropout_samples: u("dropout_samples"),
        missing_tacho_pulses: u("missing_tacho_pulses"),
        ..Default::default()
    }
}

/// The fault bands, their channel and the point's fault orders.
fn fault_bands(r: &Read) -> FaultBands {
    FaultBands {
        channel: r.get::<Option<String>>("band_channel").unwrap_or_default(),
        orders: r
            .get::<Option<serde_json::Value>>("band_orders")
            .and_then(|v| serde_json::from_value(v).ok())
            .unwrap_or_default(),
        bpfo: bands(r, "bpfo"),
        bpfi: bands(r, "bpfi"),
        two_bsf: bands(r, "two_bsf"),
        floor: r.get::<Option<f32>>("band_floor").unwrap_or(0.0),
    }
}

/// Rebuild the message of one row (see [`columns::select`]); adds `iso_limits_mm_s` when
/// known.
fn message_of(row: &Row) -> serde_json::Value {
    let r = Read(row);
    let key: String = r.get("key");
    // the column holds the type's names; any other text (a hand-edited row) is answered as stored
    let speed_source: String = r.get("speed_source");
    let mut parts = key.splitn(3, '/').map(str::to_string);
    let (rig, asset, point) = (
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
    );
    let end_ns = ns_of(r.get::<SystemTime>("time"));
    let window_s: f32 = r.get("window_s");
    let run = ns_of(r.get::<SystemTime>("run_start"));
    let start_ns = end_ns.saturating_sub((f64::from(window_s) * 1e9).round() as u64);
    let secs = |ns: u64| ns.saturating_sub(run) as f64 / 1e9;
    let m = HealthMessage {
        schema: SCHEMA.into(),
        schema_version: SCHEMA_VERSION,
        rig,
        asset,
        point,
        site: Some(r.get("site")),
        seq: r.get::<i64>("seq").max(0) as u64,
        window: WindowTimes {
            start_s: secs(start_ns),
            end_s: secs(end_ns),
            start_ns,
            end_ns,
        },
        publish_time_ns: ns_of(r.get::<SystemTime>("publish_time")),
        rpm: r.get("rpm"),
        speed_source: speed_source.parse().unwrap_or_default(),
        speed_confidence: r.get::<Option<f32>>("speed_confidence").map(f64::from),
        speed_rival_rpm: r.get("speed_rival_rpm"),
        quality: quality(&r),
        probabilities: probabilities(&r),
        window_state: r.get("window_state"),
        unknown_reason: reason(r.get("unknown_reason")),
        alarm_despite: reason(r.get("alarm_despite")),
        decision: basis(r.get("decision")),
        overruled: r.get("overruled"),
        evidence: evidence(&r),
        impulse: impulse(&r),
        indicators: indicators(&r, run),
        state: r.get("state"),
        state_since_s: secs(ns_of(r.get::<SystemTime>("state_since"))),
        state_changed: r.get("state_changed"),
        confidence: r.get("confidence"),
        novelty: r.get("novelty"),
        novelty_threshold: r.get("novelty_threshold"),
        baseline_distance: r.get("baseline_distance"),
        beyond_baseline: r.get("beyond_baseline"),
        fault_bands: fault_bands(&r),
        velocity_rms_mm_s: r.get::<Option<f32>>("velocity_rms_mm_s").map(f64::from),
        iso_zone: r
            .get::<Option<String>>("iso_zone")
            .and_then(|z| serde_json::from_value::<Zone>(serde_json::Value::String(z)).ok()),
        model: ModelInfo {
            id: r.get("model_name"),
            sha256: r.get("model_sha256"),
            labels: r.get("model_labels"),
            foreign: r.get::<Option<_>>("model_foreign").unwrap_or_default(),
        },
        calibration_id: r.get("calibration_id"),
        software_version: r
            .get::<Option<String>>("software_version")
            .unwrap_or_default(),
    };
    let mut v = serde_json::to_value(&m).unwrap_or_default();
    v["speed_source"] = serde_json::json!(speed_source);
    if let Some(l) = r.get::<Option<Vec<f32>>>("iso_limits_mm_s") {
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
    let sql = format!("{} {FROM} WHERE w.point_id = ANY($1) AND w.time >= $2 AND w.time < $3 ORDER BY w.point_id, w.time LIMIT $4", columns::select());
    let rows = client.query(&sql, &[&ids, &from, &until, &limit]).await?;
    if rows.len() as u64 > max {
        let n: i64 = client
            .query_one("SELECT count(*) FROM windows WHERE point_id = ANY($1) AND time >= $2 AND time < $3", &[&ids, &from, &until])
            .await?
            .get(0);
        return Err(anyhow!("{n} windows match {asked} in {t}, more than [history] max_replies = {max}; narrow the time range or the key expression"));
    }
    for r in &rows {
        let key: String = Read(r).get("key");
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
