//! The machine's healthy baseline an alignment stores in a model (metadata key `alignment`),
//! typed and read once, when the model is loaded: the gate (how far a window may stand from
//! the healthy windows and still be called healthy), the spread of the healthy windows'
//! features (the unit of the fault-family evidence), their impulsiveness (excess kurtosis) and
//! their health indicators. Every reader (the daemon, scoring, adapt's report) asks this type;
//! no one parses the JSON by key. Models aligned by older versions lack the later parts: those
//! read as None, and what rests on them stays off.

use super::evidence::BaselineSpread;
use super::impulsiveness::ImpulseBaseline;
use super::indicators::IndicatorBaseline;
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

/// What an alignment did and the healthy baseline it fitted.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Alignment {
    /// Measured healthy windows the reference was taken from.
    pub windows: usize,
    /// The recordings they came from (as given).
    #[serde(default)]
    pub records: Vec<String>,
    /// RMS over the features of the applied shift (natural-log units: 1.0 = a factor e).
    #[serde(default)]
    pub shift_rms: f32,
    /// The feature with the largest shift, and that shift.
    #[serde(default)]
    pub largest_shift_feature: usize,
    #[serde(default)]
    pub largest_shift: f32,
    /// Distance beyond which a window cannot be called healthy
    /// ([`super::baseline::HealthyBaseline`]); None in alignments that did not store it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_threshold: Option<f32>,
    /// 1 / pooled spread of the healthy windows (the unit of `baseline_deviation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_inv_spread: Option<f32>,
    /// The healthy windows' excess kurtosis (None when their kurtosis was not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub healthy_kurtosis: Option<ImpulseBaseline>,
    /// The healthy windows' health indicators (stored by `adapt`; None otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub healthy_indicators: Option<IndicatorBaseline>,
}

impl Alignment {
    /// Read the metadata text (`what` names the model file for the error).
    pub fn from_text(text: &str, what: &str) -> Result<Alignment> {
        serde_json::from_str(text).with_context(|| {
            format!("{what}: the model's `alignment` metadata is not a rigmon alignment ({text:.200}); align the model again (`rigmon align` or `rigmon adapt`)")
        })
    }

    /// The metadata text.
    pub fn to_text(&self) -> String {
        serde_json::to_string(self).expect("an alignment serialises")
    }

    /// The healthy-baseline gate (the distance beyond which a window is not healthy).
    pub fn gate(&self) -> Option<f32> {
        self.baseline_threshold
            .filter(|t| t.is_finite() && *t > 0.0)
    }

    /// The spread the fault-family evidence is measured in; None without a usable one.
    pub fn spread(&self) -> Option<BaselineSpread> {
        let inv_spread = self.baseline_inv_spread?;
        (inv_spread > 0.0 && inv_spread.is_finite() && self.windows >= 2).then_some(
            BaselineSpread {
                inv_spread,
                windows: self.windows,
            },
        )
    }

    /// The healthy windows' impulsiveness; None without a usable one.
    pub fn impulse(&self) -> Option<ImpulseBaseline> {
        self.healthy_kurtosis
            .filter(|b| b.sd >= 0.0 && b.mean.is_finite() && b.windows >= 2)
    }

    /// The healthy windows' indicator levels; None without usable ones.
    pub fn indicators(&self) -> Option<IndicatorBaseline> {
        self.healthy_indicators.filter(|b| {
            let levels_ok = b.levels().iter().all(|l| {
                l.center.is_finite()
                    && l.spread > 0.0
                    && l.spread.is_finite()
                    && l.healthy_max.is_finite()
            });
            levels_ok && b.windows >= 2 && b.median_of >= 1
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::indicators::Level;

    fn level() -> Level {
        Level {
            center: 1.0,
            spread: 0.5,
            healthy_max: 2.0,
        }
    }

    #[test]
    fn text_round_trips_and_each_part_reads_only_when_usable() {
        let a = Alignment {
            windows: 60,
            records: vec!["h.wav".into()],
            baseline_threshold: Some(3.5),
            baseline_inv_spread: Some(4.0),
            healthy_kurtosis: Some(ImpulseBaseline {
                mean: 0.1,
                sd: 0.2,
                windows: 60,
            }),
            healthy_indicators: Some(IndicatorBaseline {
                rms: level(),
                crest: level(),
                kurtosis: level(),
                resonance: level(),
                windows: 60,
                median_of: 5,
            }),
            ..Alignment::default()
        };
        let back = Alignment::from_text(&a.to_text(), "m.onnx").unwrap();
        assert_eq!(back, a);
        assert_eq!(back.gate(), Some(3.5));
        assert_eq!(back.spread().map(|s| s.windows), Some(60));
        assert!(back.impulse().is_some() && back.indicators().is_some());
        // an alignment from before the later parts were stored
        let old = Alignment::from_text(r#"{"windows":60}"#, "m.onnx").unwrap();
        assert!(old.gate().is_none() && old.spread().is_none());
        assert!(old.impulse().is_none() && old.indicators().is_none());
        // unusable parts read as None
        let bad = Alignment {
            baseline_inv_spread: Some(f32::NAN),
            healthy_kurtosis: Some(ImpulseBaseline {
                mean: 0.0,
                sd: 0.1,
                windows: 1,
            }),
            ..a
        };
        assert!(bad.spread().is_none() && bad.impulse().is_none());
        let e = Alignment::from_text("[1,2]", "m.onnx").unwrap_err();
        assert!(format!("{e:#}").contains("m.onnx") && format!("{e:#}").contains("align"));
    }
}
