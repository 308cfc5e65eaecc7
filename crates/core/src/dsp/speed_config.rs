//! The rig file's `[speed]` section: where shaft speed and angle come from (analog tacho,
//! delivered edges, a fixed rpm, the recording's stored rpm, or an estimate from the
//! vibration). Owned by the DSP layer; `config` embeds it in the rig file.

use crate::vocabulary::SpeedSourceKind;
use serde::{Deserialize, Serialize};

/// Where shaft speed and angle come from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "snake_case", deny_unknown_fields)]
pub enum SpeedConfig {
    /// Analog tacho channel: threshold with hysteresis, sub-sample edge interpolation.
    Tacho {
        /// Name of the tacho channel in `channels`.
        channel: String,
        #[serde(default = "one_u32")]
        pulses_per_rev: u32,
        /// Switching threshold in the channel's unit (V).
        #[serde(default = "default_threshold")]
        threshold: f64,
        /// Hysteresis half-width around the threshold.
        #[serde(default = "default_hysteresis")]
        hysteresis: f64,
    },
    /// Edge timestamps delivered by the source (DAQ adapters, MCAP tacho edges).
    Edges {
        #[serde(default = "one_u32")]
        pulses_per_rev: u32,
    },
    /// A fixed, known speed, checked window by window against the vibration's 1x line within
    /// +-`check_within_percent` (0: not checked): replaced where the line is clear and more
    /// than 1 % off (a nominal motor speed is often a few per cent from the shaft's).
    Fixed {
        rpm: f64,
        #[serde(default = "default_hint_within_percent")]
        check_within_percent: f64,
    },
    /// The speed stored in the recording (e.g. CWRU's `X<nnn>RPM`); falls back to estimation.
    /// A stored speed is checked against the recording's own 1x line, searched within
    /// +-`check_within_percent` of it, and replaced where clearly off ([`super::stored_speed`]);
    /// 0 keeps it unchecked.
    Recording {
        #[serde(default = "default_check_within_percent")]
        check_within_percent: f64,
    },
    /// Estimate from the vibration itself by tracking the 1x line over `min_rpm..max_rpm`
    /// (the rig's operating range). A recording's nominal speed (a manifest's `rpm` column)
    /// narrows the search to +-`check_within_percent` around it.
    Estimate {
        #[serde(default = "default_min_rpm")]
        min_rpm: f64,
        #[serde(default = "default_max_rpm")]
        max_rpm: f64,
        #[serde(default = "default_hint_within_percent")]
        check_within_percent: f64,
    },
}

fn one_u32() -> u32 {
    1
}
fn default_threshold() -> f64 {
    2.5
}
fn default_hysteresis() -> f64 {
    0.5
}
fn default_min_rpm() -> f64 {
    300.0
}
fn default_max_rpm() -> f64 {
    3600.0
}
fn default_check_within_percent() -> f64 {
    5.0
}
/// A nominal or fixed speed may be off by several per cent (motor slip, a drive's setting):
/// searched within +-10 %.
fn default_hint_within_percent() -> f64 {
    10.0
}

impl SpeedConfig {
    /// Which source this section asks for (its `source` key).
    pub fn kind(&self) -> SpeedSourceKind {
        match self {
            SpeedConfig::Tacho { .. } => SpeedSourceKind::Tacho,
            SpeedConfig::Edges { .. } => SpeedSourceKind::Edges,
            SpeedConfig::Fixed { .. } => SpeedSourceKind::Fixed,
            SpeedConfig::Recording { .. } => SpeedSourceKind::Recording,
            SpeedConfig::Estimate { .. } => SpeedSourceKind::Estimate,
        }
    }

    /// Pulses per revolution of the tacho, whatever form it comes in (1 without a tacho).
    pub fn pulses_per_rev(&self) -> u32 {
        match self {
            SpeedConfig::Tacho { pulses_per_rev, .. } | SpeedConfig::Edges { pulses_per_rev } => {
                *pulses_per_rev
            }
            _ => 1,
        }
    }

    /// `recording` with the stored speed checked: the search half-width as a fraction.
    pub fn stored_speed_check(&self) -> Option<f64> {
        match self {
            SpeedConfig::Recording {
                check_within_percent,
            } if *check_within_percent > 0.0 => Some(check_within_percent / 100.0),
            _ => None,
        }
    }

    /// (threshold, hysteresis) of the analog tacho, when speed comes from one.
    pub fn tacho_levels(&self) -> Option<(f64, f64)> {
        match self {
            SpeedConfig::Tacho {
                threshold,
                hysteresis,
                ..
            } => Some((*threshold, *hysteresis)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_source_key_is_the_kind_s_name() {
        for kind in SpeedSourceKind::ALL {
            let text = match kind {
                SpeedSourceKind::Tacho => "source = \"tacho\"\nchannel = \"tacho\"".to_string(),
                SpeedSourceKind::Fixed => "source = \"fixed\"\nrpm = 600.0".to_string(),
                SpeedSourceKind::Simulator => continue, // the simulator's, never a rig file's
                k => format!("source = {:?}", k.as_str()),
            };
            let cfg: SpeedConfig = toml::from_str(&text).unwrap();
            assert_eq!(cfg.kind(), kind);
            assert!(text.starts_with(&format!("source = \"{kind}\"")));
        }
    }
}
