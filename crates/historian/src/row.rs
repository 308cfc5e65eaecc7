//! One health message as one `windows` row: the typed values (the table of columns and how
//! each is written is [`super::columns`]), the point it belongs to in the asset tree, the
//! model that produced it and, on a state change, the full JSON for the event.

use anyhow::{bail, Result};
use rigmon_core::health::UnknownReason;
use rigmon_core::vocabulary::Condition;
use rigmon_core::wire::health::{HealthIndicators, HealthMessage};
use rigmon_runtime::publish::recent::run_start_ns;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// The model a row was classified by (`models` table).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ModelKey {
    pub name: String,
    pub sha256: String,
    pub labels: Vec<String>,
}

/// Where a point sits in the asset tree, and what describes it (`points` table).
#[derive(Debug, Clone, PartialEq)]
pub struct PointInfo {
    pub site: String,
    pub machine: String,
    pub asset: String,
    pub point: String,
    pub band_channel: String,
    pub band_orders: serde_json::Value,
    pub calibration_id: Option<String>,
    pub software_version: String,
}

impl PointInfo {
    fn of(m: &HealthMessage, default_site: &str) -> PointInfo {
        PointInfo {
            site: m.site.clone().unwrap_or_else(|| default_site.to_string()),
            machine: m.rig.clone(),
            asset: m.asset.clone(),
            point: m.point.clone(),
            band_channel: m.fault_bands.channel.clone(),
            band_orders: serde_json::to_value(&m.fault_bands.orders).unwrap_or_default(),
            calibration_id: m.calibration_id.clone(),
            software_version: m.software_version.clone(),
        }
    }

    /// `<machine>/<asset>/<point>`, as on Zenoh.
    pub fn key(&self) -> String {
        format!("{}/{}/{}", self.machine, self.asset, self.point)
    }
}

/// One window, ready to COPY once `point_id` and `model_id` are known.
#[derive(Debug, Clone)]
pub struct WindowRow {
    pub point: PointInfo,
    pub model: ModelKey,
    pub point_id: i32,
    pub model_id: i32,
    pub time: SystemTime,
    pub end_ns: u64,
    pub window_s: f32,
    pub run_start_ns: u64,
    pub seq: u64,
    pub publish_ns: u64,
    pub state: String,
    pub state_since: SystemTime,
    pub state_changed: bool,
    pub confidence: f32,
    pub window_state: String,
    pub unknown_reason: Option<String>,
    pub alarm_despite: Option<String>,
    /// p_healthy, p_outer_race, p_inner_race, p_ball.
    pub p: [Option<f32>; 4],
    pub p_other: Option<serde_json::Value>,
    pub novelty: f32,
    pub novelty_threshold: f32,
    pub baseline_distance: Option<f32>,
    pub beyond_baseline: Option<bool>,
    pub rpm: Option<f64>,
    pub speed_source: String,
    pub velocity: Option<f32>,
    pub iso_zone: Option<String>,
    /// bpfo 1-3, bpfi 1-3, two_bsf 1-3.
    pub bands: [Option<f32>; 9],
    pub band_floor: Option<f32>,
    pub quality_ok: bool,
    pub quality_flags: Option<Vec<String>>,
    pub counts: [i32; 4],
    /// What decided the class: `model`, `confirmed`, `evidence` or `impulsive`.
    pub decision: &'static str,
    pub overruled: Option<String>,
    /// Fault-family evidence: outer race, inner race, ball (all or none).
    pub evidence: [Option<f32>; 3],
    pub speed_confidence: Option<f32>,
    pub speed_rival_rpm: Option<f64>,
    /// How an allowed foreign model differs from the rig (None when it is the rig's own).
    pub model_foreign: Option<Vec<String>>,
    /// Impulsiveness: beyond healthy, beyond Gaussian (both or none).
    pub impulse: [Option<f32>; 2],
    /// The health indicators and the departure test's reading.
    pub indicators: IndicatorColumns,
    /// The whole message, kept for the state-change event.
    pub message: Option<serde_json::Value>,
}

/// The health indicators and the departure test's reading as stored: each value only when
/// finite; the four indicator values all or none, as the scores, the smoothed scores and
/// the thresholds (all None when the message carried none).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndicatorColumns {
    /// RMS, crest, kurtosis, resonance-band RMS.
    pub values: [Option<f32>; 4],
    pub samples: Option<i32>,
    pub scores: [Option<f32>; 4],
    pub smoothed: [Option<f32>; 4],
    pub threshold: [Option<f32>; 4],
    pub leading: Option<&'static str>,
    pub excess: Option<f32>,
    pub beyond_for: Option<i32>,
    /// When the machine departed from its healthy baseline.
    pub departed_since: Option<SystemTime>,
}

/// All four finite, or none.
fn four(a: [f32; 4]) -> [Option<f32>; 4] {
    if a.iter().all(|v| v.is_finite()) {
        a.map(Some)
    } else {
        [None; 4]
    }
}

impl IndicatorColumns {
    fn of(h: Option<HealthIndicators>, run_start_ns: u64, end_ns: u64) -> Self {
        let Some(h) = h else {
            return Self::default();
        };
        let v = h.values;
        let values = four([v.rms, v.crest, v.kurtosis, v.resonance]);
        let mut c = IndicatorColumns {
            values,
            samples: values[0].and(i32::try_from(v.samples).ok()),
            ..Default::default()
        };
        if let Some(d) = h.departure {
            c.scores = four(d.scores.to_array());
            c.smoothed = d.smoothed.map_or([None; 4], |s| four(s.to_array()));
            c.threshold = four(d.threshold.to_array());
            c.leading = d.leading.map(|l| l.as_str());
            c.excess = d.excess.and_then(finite);
            c.beyond_for = Some(i32::try_from(d.beyond_for).unwrap_or(i32::MAX));
            c.departed_since = d
                .departed_since_s
                .filter(|s| s.is_finite())
                .map(|s| since(run_start_ns, s, end_ns));
        }
        c
    }
}

/// ns since the epoch as a time (PostgreSQL keeps µs).
pub fn time_of(ns: u64) -> SystemTime {
    UNIX_EPOCH + Duration::from_nanos(ns)
}

/// A time as ns since the epoch.
pub fn ns_of(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

fn finite(v: f32) -> Option<f32> {
    v.is_finite().then_some(v)
}

fn band(v: &[f32], i: usize) -> Option<f32> {
    v.get(i).copied().and_then(finite)
}

/// When the state began: `state_since_s` into the run, at the latest the window's end.
fn since(run_start_ns: u64, state_since_s: f64, end_ns: u64) -> SystemTime {
    time_of(
        run_start_ns
            .saturating_add((state_since_s.max(0.0) * 1e9).round() as u64)
            .min(end_ns),
    )
}

fn clamp_i32(v: u32) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

impl WindowRow {
    /// Read one health message (JSON). `default_site` is used when the rig file names none.
    pub fn parse(payload: &[u8], default_site: &str) -> Result<WindowRow> {
        let m: HealthMessage = serde_json::from_slice(payload)
            .map_err(|e| anyhow::anyhow!("not a rigmon.health message: {e}"))?;
        if m.schema != rigmon_core::wire::health::SCHEMA {
            bail!("schema {:?} where rigmon.health was expected", m.schema);
        }
        let message = m
            .state_changed
            .then(|| serde_json::from_slice::<serde_json::Value>(payload).ok())
            .flatten();
        Ok(Self::from_message(m, default_site, message))
    }

    fn from_message(
        m: HealthMessage,
        default_site: &str,
        message: Option<serde_json::Value>,
    ) -> Self {
        let run_start_ns = run_start_ns(m.window.end_ns, m.window.end_s);
        let prob = |l: &str| m.probabilities.get(l).copied().and_then(finite);
        let others: serde_json::Map<String, serde_json::Value> = m
            .probabilities
            .iter()
            .filter(|(l, _)| !Condition::NAMES.contains(&l.as_str()))
            .map(|(l, p)| (l.clone(), serde_json::json!(p)))
            .collect();
        let fb = &m.fault_bands;
        let q = &m.quality;
        let label = |r: Option<UnknownReason>| r.map(|r| r.as_str().to_string());
        WindowRow {
            point: PointInfo::of(&m, default_site),
            model: ModelKey {
                name: m.model.id.clone(),
                sha256: m.model.sha256.clone(),
                labels: m.model.labels.clone(),
            },
            point_id: 0,
            model_id: 0,
            time: time_of(m.window.end_ns),
            end_ns: m.window.end_ns,
            window_s: (m.window.end_s - m.window.start_s) as f32,
            run_start_ns,
            seq: m.seq,
            publish_ns: m.publish_time_ns,
            state_since: since(run_start_ns, m.state_since_s, m.window.end_ns),
            state: m.state,
            state_changed: m.state_changed,
            confidence: m.confidence,
            window_state: m.window_state,
            unknown_reason: label(m.unknown_reason),
            alarm_despite: label(m.alarm_despite),
            p: [
                prob(Condition::NAMES[0]),
                prob(Condition::NAMES[1]),
                prob(Condition::NAMES[2]),
                prob(Condition::NAMES[3]),
            ],
            p_other: (!others.is_empty()).then_some(serde_json::Value::Object(others)),
            novelty: m.novelty,
            novelty_threshold: m.novelty_threshold,
            baseline_distance: m.baseline_distance.and_then(finite),
            beyond_baseline: m.beyond_baseline,
            rpm: m.rpm.filter(|r| r.is_finite()),
            speed_source: m.speed_source.as_str().to_owned(),
            velocity: m
                .velocity_rms_mm_s
                .filter(|v| v.is_finite())
                .map(|v| v as f32),
            iso_zone: m
                .iso_zone
                .and_then(|z| serde_json::to_value(z).ok())
                .and_then(|v| v.as_str().map(str::to_string)),
            bands: {
                let families = [&fb.bpfo, &fb.bpfi, &fb.two_bsf];
                std::array::from_fn(|k| band(families[k / 3], k % 3))
            },
            band_floor: (!fb.bpfo.is_empty()).then_some(fb.floor).and_then(finite),
            quality_ok: q.ok,
            quality_flags: (!q.flags.is_empty()).then(|| q.flags.clone()),
            counts: [
                clamp_i32(q.clipped_samples),
                clamp_i32(q.nan_samples),
                clamp_i32(q.dropout_samples),
                clamp_i32(q.missing_tacho_pulses),
            ],
            decision: m.decision.as_str(),
            overruled: m.overruled,
            evidence: m.evidence.map_or([None; 3], |e| {
                [Some(e.outer_race), Some(e.inner_race), Some(e.ball)]
            }),
            speed_confidence: m
                .speed_confidence
                .filter(|c| c.is_finite())
                .map(|c| c as f32),
            speed_rival_rpm: m.speed_rival_rpm.filter(|r| r.is_finite()),
            model_foreign: (!m.model.foreign.is_empty()).then_some(m.model.foreign),
            impulse: m
                .impulse
                .filter(|i| i.beyond_healthy.is_finite() && i.beyond_gaussian.is_finite())
                .map_or([None; 2], |i| {
                    [Some(i.beyond_healthy), Some(i.beyond_gaussian)]
                }),
            indicators: IndicatorColumns::of(m.indicators, run_start_ns, m.window.end_ns),
            message,
        }
    }

    /// The converted values the COPY borrows ([`super::columns::copy_values`]).
    pub fn times(&self) -> RowTimes {
        RowTimes {
            run_start: time_of(self.run_start_ns),
            seq: i64::try_from(self.seq).unwrap_or(i64::MAX),
            publish: time_of(self.publish_ns),
        }
    }
}

/// Values converted for the database, kept beside the row while it is written.
pub struct RowTimes {
    pub run_start: SystemTime,
    pub seq: i64,
    pub publish: SystemTime,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_maps_to_typed_columns() {
        let msg = serde_json::json!({
            "schema": "rigmon.health", "schema_version": 1,
            "rig": "lut-rig", "asset": "shaft", "point": "nde", "seq": 7,
            "window": {"start_s": 3.0, "end_s": 4.0, "start_ns": 1_000_003_000_000_000u64, "end_ns": 1_000_004_000_000_000u64},
            "publish_time_ns": 1_000_004_010_000_000u64, "rpm": 588.0, "speed_source": "tacho",
            "quality": {"ok": false, "flags": ["clipping"], "clipped_samples": 4, "nan_samples": 0,
                        "dropout_samples": 0, "flat_channels": [], "missing_tacho_pulses": 0},
            "probabilities": {"healthy": 0.1, "outer_race": 0.9, "misalignment": 0.0},
            "window_state": "outer_race", "unknown_reason": null, "state": "outer_race",
            "state_since_s": 4.0, "state_changed": true, "confidence": 0.9, "novelty": 0.2,
            "novelty_threshold": 1.0,
            "fault_bands": {"channel": "vertical", "orders": {"bpfo": 4.4}, "bpfo": [1.0, 0.5, 0.25],
                            "bpfi": [0.1, 0.1, 0.1], "two_bsf": [0.2, 0.2, 0.2], "floor": 0.05},
            "velocity_rms_mm_s": 1.9, "iso_zone": "B",
            "model": {"id": "lut-rig", "sha256": "ab", "labels": ["healthy", "outer_race"],
                      "foreign": ["rig_id: model cwru-de, rig file lut-rig"]},
            "calibration_id": null, "software_version": "0.1.0",
            "decision": "evidence", "overruled": "healthy",
            "evidence": {"outer_race": 9.5, "inner_race": 0.25, "ball": -1.0},
            "speed_confidence": 0.75, "speed_rival_rpm": 294.0,
            "impulse": {"beyond_healthy": 12.5, "beyond_gaussian": 7.0}
        });
        let r = WindowRow::parse(msg.to_string().as_bytes(), "lab").unwrap();
        assert_eq!(r.point.key(), "lut-rig/shaft/nde");
        assert_eq!(r.point.site, "lab");
        assert_eq!(r.run_start_ns, 1_000_000_000_000_000);
        assert_eq!(r.state_since, time_of(1_000_004_000_000_000));
        assert_eq!(r.p, [Some(0.1), Some(0.9), None, None]);
        assert!(r.p_other.as_ref().unwrap().get("misalignment").is_some());
        assert_eq!(r.iso_zone.as_deref(), Some("B"));
        assert_eq!(r.bands[0], Some(1.0));
        assert_eq!(
            r.quality_flags.as_deref(),
            Some(&["clipping".to_string()][..])
        );
        assert!(r.message.is_some(), "state changes keep the full JSON");
        assert_eq!(
            (r.decision, r.overruled.as_deref()),
            ("evidence", Some("healthy"))
        );
        assert_eq!(r.evidence, [Some(9.5), Some(0.25), Some(-1.0)]);
        assert_eq!(r.impulse, [Some(12.5), Some(7.0)]);
        assert_eq!(
            (r.speed_confidence, r.speed_rival_rpm),
            (Some(0.75), Some(294.0))
        );
        assert_eq!(
            r.model_foreign.as_deref(),
            Some(&["rig_id: model cwru-de, rig file lut-rig".to_string()][..])
        );
        assert_eq!(r.indicators, IndicatorColumns::default());
        // a message from before these fields existed: decided by the model, the rest absent
        let mut old = msg.clone();
        for key in [
            "decision",
            "overruled",
            "evidence",
            "speed_confidence",
            "speed_rival_rpm",
            "impulse",
        ] {
            old.as_object_mut().unwrap().remove(key);
        }
        old["model"].as_object_mut().unwrap().remove("foreign");
        let r = WindowRow::parse(old.to_string().as_bytes(), "lab").unwrap();
        assert_eq!((r.decision, r.overruled), ("model", None));
        assert_eq!(r.evidence, [None; 3]);
        assert_eq!(r.impulse, [None; 2]);
        assert_eq!((r.speed_confidence, r.speed_rival_rpm), (None, None));
        assert_eq!(r.model_foreign, None);
        let e = WindowRow::parse(b"{\"schema\":\"rigmon.status\"}", "lab").unwrap_err();
        assert!(e.to_string().contains("rigmon.health"), "{e}");
    }
}
