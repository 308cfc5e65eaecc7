//! The health message: one JSON object per window, published on
//! `rigmon/<rig>/<asset>/<point>/health`, printed by `rigmon replay --json` and read back by
//! `rigmon watch`. The schema is versioned (`schema = "rigmon.health"`, `schema_version`);
//! fields are only ever added within a version, so readers must ignore unknown fields.

use crate::health::iso20816::Zone;
use crate::health::{Basis, UnknownReason};
use crate::model::departure::DepartureReading;
use crate::model::evidence::FamilyEvidence;
use crate::model::impulsiveness::Impulse;
use crate::model::indicators::Indicators;
use crate::vocabulary::{QualityFlag, SpeedSourceKind};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Schema name carried in every message.
pub const SCHEMA: &str = "rigmon.health";
/// Current schema version.
pub const SCHEMA_VERSION: u32 = 1;

/// One window's health.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HealthMessage {
    pub schema: String,
    pub schema_version: u32,
    pub rig: String,
    pub asset: String,
    pub point: String,
    /// The rig file's `[machine] site`, when it names one (added in schema version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub site: Option<String>,
    /// Window counter since the daemon started (gaps mean windows were not computed).
    pub seq: u64,
    pub window: WindowTimes,
    /// Wall-clock time the message was built, ns since the Unix epoch.
    pub publish_time_ns: u64,
    /// Shaft speed over the window (None when it could not be determined).
    pub rpm: Option<f64>,
    /// Where the speed came from.
    pub speed_source: SpeedSourceKind,
    /// For a speed read from the vibration: how sure the tracker is (0-1; below 0.5 the
    /// window carries the `speed_uncertain` flag: its class comes from the speed-free
    /// evidence alone, an impulsive window an alarm, any other `unknown`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_confidence: Option<f64>,
    /// Half or twice the speed, when the vibration supports it nearly as well, rpm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_rival_rpm: Option<f64>,
    pub quality: QualityReport,
    /// Class probabilities by label (model order in `model.labels`).
    pub probabilities: BTreeMap<String, f32>,
    /// This window's own state (a label or `unknown`).
    pub window_state: String,
    /// Why the window is `unknown`, when it is.
    pub unknown_reason: Option<UnknownReason>,
    /// The window keeps its fault class (an alarm) although it would be `unknown` for this
    /// reason (`novelty`, `low_confidence`): it stands beyond the machine's healthy baseline
    /// or the classifier is sure of a fault. Absent otherwise (added in schema version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alarm_despite: Option<UnknownReason>,
    /// What decided the window's class: `model` (the classifier), `confirmed` (the
    /// classifier's fault, its fault-family bins beyond the machine's healthy level) or
    /// `evidence` (the fault family the spectrum points at, overruling the classifier;
    /// `overruled` names the classifier's class). Added in schema version 1.
    #[serde(default)]
    pub decision: Basis,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub overruled: Option<String>,
    /// Standard deviations by which each fault family's bins (BPFO, BPFI, 2xBSF and their
    /// second harmonics) stand above the machine's healthy level (aligned models only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub evidence: Option<FamilyEvidence>,
    /// How far the classifier channel's excess kurtosis (mean over the last windows) stands
    /// above the machine's healthy windows and above Gaussian noise, in standard deviations
    /// (aligned models carrying the kurtosis baseline only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub impulse: Option<Impulse>,
    /// The classifier channel's speed-free health indicators and, against the machine's
    /// healthy baseline, the departure test (added in schema version 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indicators: Option<HealthIndicators>,
    /// The smoothed state (k-of-n voting with dwell time).
    pub state: String,
    /// Window-end time (s, sample clock) at which `state` was entered.
    pub state_since_s: f64,
    /// True on the window that changed `state`.
    pub state_changed: bool,
    /// Mean probability of `state` over the vote history (share of unknown votes for `unknown`).
    pub confidence: f32,
    /// Novelty score of the window and the threshold above which it counts as novel.
    pub novelty: f32,
    pub novelty_threshold: f32,
    /// Distance from the machine's healthy baseline and whether it exceeds the baseline's
    /// threshold (aligned models only; absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_distance: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beyond_baseline: Option<bool>,
    pub fault_bands: FaultBands,
    /// Broadband velocity RMS 10-1000 Hz of the classifier channel, mm/s.
    pub velocity_rms_mm_s: Option<f64>,
    /// ISO 20816-3 zone of that velocity (advisory only).
    pub iso_zone: Option<Zone>,
    pub model: ModelInfo,
    /// Calibration that produced the rig file / model (None when uncalibrated).
    pub calibration_id: Option<String>,
    /// rigmon version that produced the message.
    pub software_version: String,
}

/// Window position on the sample clock and in wall time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindowTimes {
    /// Start and end on the sample clock, s since the first sample of the source.
    pub start_s: f64,
    pub end_s: f64,
    /// Start and end in ns since the Unix epoch (source start time + sample clock).
    pub start_ns: u64,
    pub end_ns: u64,
}

/// Data quality of one window. `ok` is false when any flag is set.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct QualityReport {
    pub ok: bool,
    /// Flag names: `clipping`, `dropout`, `nan`, `flat`, `missing_tacho_pulses`, `no_speed`,
    /// `tacho_lost`, `speed_out_of_range`, `features_failed`, `dc_offset` (advisory).
    pub flags: Vec<String>,
    /// Samples at the channel's clipping level (runs of >= 3 equal extreme samples).
    pub clipped_samples: u32,
    /// Non-finite samples (replaced by 0 before the feature pipeline).
    pub nan_samples: u32,
    /// Samples lost on the sample clock inside the window.
    pub dropout_samples: u32,
    /// Channels that are flat (dead sensor or cable).
    pub flat_channels: Vec<String>,
    /// Tacho pulses missing (repaired or not) inside the window.
    pub missing_tacho_pulses: u32,
    /// The feature pipeline's own quality report (speed tracking details).
    #[serde(default)]
    pub dsp: serde_json::Value,
}

impl QualityReport {
    /// Set a flag once (and `ok = false`).
    pub fn flag(&mut self, flag: QualityFlag) {
        let name = flag.as_str();
        if !self.flags.iter().any(|f| f == name) {
            self.flags.push(name.to_string());
        }
        self.ok = false;
    }
}

/// Envelope-order-spectrum amplitudes at the bearing's fault orders and their harmonics.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FaultBands {
    /// Channel the amplitudes come from (the classifier channel).
    pub channel: String,
    /// Fault orders (multiples of shaft speed).
    pub orders: BTreeMap<String, f64>,
    /// Bin RMS at harmonic 1, 2, 3 of each fault order, in the channel's unit.
    pub bpfo: Vec<f32>,
    pub bpfi: Vec<f32>,
    pub two_bsf: Vec<f32>,
    /// Median bin RMS of the spectrum (the floor the fault bands stand out from).
    pub floor: f32,
}

/// One window's health indicators and the departure test's reading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HealthIndicators {
    /// RMS, crest factor, excess kurtosis, resonance-band RMS of the classifier channel
    /// ([`crate::model::indicators`]).
    pub values: Indicators,
    /// Against the machine's healthy baseline (models carrying the indicator baseline;
    /// [`crate::model::departure`]): once `departed_since_s` is set the state is held at a
    /// fault.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub departure: Option<DepartureReading>,
}

/// Which model produced the probabilities.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    /// File stem of the ONNX model (e.g. "lut-rig").
    pub id: String,
    /// SHA-256 of the ONNX file.
    pub sha256: String,
    pub labels: Vec<String>,
    /// How the model differs from the rig it serves (rig id, axis, bearing orders, low-pass,
    /// window: `"rig_id: model cwru-de, rig file lut-rig"`), when a model trained for another
    /// rig was allowed on purpose (`[model] allow_foreign`); absent otherwise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub foreign: Vec<String>,
}

impl HealthMessage {
    /// One line for a terminal: time, smoothed state, confidence, window state,
    /// probabilities, speed, velocity/zone and quality.
    pub fn line(&self) -> String {
        let mut s = String::with_capacity(160);
        let _ = write!(
            s,
            "{:>8.1}s  {:<10} {:>4.0}%  win {:<10}",
            self.window.end_s,
            self.state,
            self.confidence * 100.0,
            self.window_state
        );
        if let Some(r) = self.alarm_despite {
            let _ = write!(s, " (alarm despite {})", r.as_str());
        }
        if let Some(m) = &self.overruled {
            let _ = write!(s, " (evidence overrules {m})");
        }
        s.push_str("  p[");
        for (i, label) in self.model.labels.iter().enumerate() {
            let p = self.probabilities.get(label).copied().unwrap_or(f32::NAN);
            if i > 0 {
                s.push(' ');
            }
            let _ = write!(s, "{} {:.2}", short(label), p);
        }
        s.push(']');
        match self.rpm {
            Some(r) => {
                let _ = write!(s, "  {r:>6.0} rpm {}", self.speed_source);
            }
            None => {
                let _ = write!(s, "  {:>6} rpm {}", "-", self.speed_source);
            }
        }
        if let Some(v) = self.velocity_rms_mm_s {
            let zone = self.iso_zone.map_or("-".to_string(), |z| format!("{z:?}"));
            let _ = write!(s, "  v {v:.2} mm/s {zone}");
        }
        if self.quality.ok {
            s.push_str("  ok");
        } else {
            let _ = write!(s, "  {}", self.quality.flags.join(","));
        }
        if let Some(r) = self.order_resolution() {
            let _ = write!(s, "  res {r:.2} ord");
        }
        let departure = self.indicators.and_then(|i| i.departure);
        if let Some(t) = departure.and_then(|d| d.departed_since_s) {
            let _ = write!(s, "  departed at {t:.0} s");
        }
        if !self.model.foreign.is_empty() {
            s.push_str("  FOREIGN MODEL");
        }
        s
    }

    /// The order resolution the window's envelope order spectrum had (1 / revolutions in the
    /// window), from the feature pipeline's report, when the window was order-tracked.
    pub fn order_resolution(&self) -> Option<f64> {
        self.quality
            .dsp
            .get("order_resolution")
            .and_then(serde_json::Value::as_f64)
            .filter(|r| *r > 0.0)
    }

    /// The Zenoh key suffix-free address `<rig>/<asset>/<point>`.
    pub fn address(&self) -> String {
        format!("{}/{}/{}", self.rig, self.asset, self.point)
    }
}

/// Short label for terminal lines: "healthy" -> "h", "outer_race" -> "or".
fn short(label: &str) -> String {
    label.split('_').filter_map(|w| w.chars().next()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn sample() -> HealthMessage {
        let labels: Vec<String> = ["healthy", "outer_race"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        HealthMessage {
            schema: SCHEMA.into(),
            schema_version: SCHEMA_VERSION,
            rig: "lut-rig".into(),
            asset: "shaft".into(),
            point: "nde".into(),
            site: None,
            seq: 3,
            window: WindowTimes {
                start_s: 1.5,
                end_s: 2.5,
                start_ns: 1_500_000_000,
                end_ns: 2_500_000_000,
            },
            publish_time_ns: 5,
            rpm: Some(588.0),
            speed_source: SpeedSourceKind::Tacho,
            speed_confidence: None,
            speed_rival_rpm: None,
            quality: QualityReport {
                ok: true,
                ..Default::default()
            },
            probabilities: [
                ("healthy".to_string(), 0.1),
                ("outer_race".to_string(), 0.9),
            ]
            .into(),
            window_state: "outer_race".into(),
            unknown_reason: None,
            alarm_despite: Some(UnknownReason::Novelty),
            decision: Basis::Confirmed,
            overruled: None,
            evidence: Some(FamilyEvidence {
                outer_race: 9.5,
                inner_race: 0.3,
                ball: -1.0,
            }),
            impulse: Some(Impulse {
                beyond_healthy: 7.5,
                beyond_gaussian: 6.0,
            }),
            indicators: None,
            state: "outer_race".into(),
            state_since_s: 2.0,
            state_changed: false,
            confidence: 0.9,
            novelty: 0.2,
            novelty_threshold: 1.0,
            baseline_distance: Some(7.5),
            beyond_baseline: Some(true),
            fault_bands: FaultBands::default(),
            velocity_rms_mm_s: Some(1.9),
            iso_zone: Some(Zone::B),
            model: ModelInfo {
                id: "lut-rig".into(),
                sha256: "ab".into(),
                labels,
                foreign: Vec::new(),
            },
            calibration_id: None,
            software_version: "0.1.0".into(),
        }
    }

    #[test]
    fn json_round_trip_and_line() {
        let m = sample();
        let text = serde_json::to_string(&m).unwrap();
        assert!(text.contains("\"schema\":\"rigmon.health\""), "{text}");
        let back: HealthMessage = serde_json::from_str(&text).unwrap();
        assert_eq!(back, m);
        let line = m.line();
        assert!(
            line.contains("outer_race")
                && line.contains("or 0.90")
                && line.contains("588 rpm")
                && line.contains("B"),
            "{line}"
        );
        let mut q = QualityReport {
            ok: true,
            ..Default::default()
        };
        q.flag(QualityFlag::Nan);
        q.flag(QualityFlag::Nan);
        assert_eq!(q.flags, ["nan"]);
        assert!(!q.ok);
        assert!(line.contains("alarm despite novelty"), "{line}");
    }

    #[test]
    fn messages_without_the_optional_alarm_fields_still_read() {
        // A message written before `alarm_despite` / `baseline_*` existed, or by an unaligned
        // model, carries none of them: they are optional, absent when empty.
        let mut m = sample();
        m.alarm_despite = None;
        m.baseline_distance = None;
        m.beyond_baseline = None;
        m.evidence = None;
        let text = serde_json::to_string(&m).unwrap();
        for key in [
            "alarm_despite",
            "baseline_distance",
            "beyond_baseline",
            "evidence",
            "overruled",
        ] {
            assert!(!text.contains(key), "{key} in {text}");
        }
        let back: HealthMessage = serde_json::from_str(&text).unwrap();
        assert_eq!(back, m);
        let with = serde_json::to_value(sample()).unwrap();
        assert_eq!(with["alarm_despite"], "novelty");
        assert_eq!(with["beyond_baseline"], true);
        assert_eq!(with["decision"], "confirmed");
        assert_eq!(with["evidence"]["outer_race"], 9.5);
        // a message from before `decision` existed reads as decided by the model
        let mut old = with.clone();
        old.as_object_mut().unwrap().remove("decision");
        let back: HealthMessage = serde_json::from_value(old).unwrap();
        assert_eq!(back.decision, Basis::Model);
        let mut overruled = sample();
        overruled.overruled = Some("healthy".into());
        assert!(overruled.line().contains("evidence overrules healthy"));
    }
}
