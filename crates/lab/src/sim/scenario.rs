//! A scenario: which faults, which speed profile, how long, which seed, and optional
//! overrides of the rig's `[simulation]` parameters (defect size, slip, load, contact angle,
//! noise, resonance...). Plans expand into scenarios; `simulate` runs one.

use super::defects::DefectSet;
use super::profile::SpeedProfile;
use crate::config::simulation::{DefectShape, SimulationConfig};
use crate::vocabulary::Condition;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The label of a fault list: `healthy`, or the dominant (first listed) fault. Compound
/// faults keep the full list in the `faults` metadata key.
pub fn label_of(faults: &[Condition]) -> &'static str {
    faults
        .first()
        .map_or(Condition::Healthy.as_str(), |f| f.as_str())
}

/// Optional per-scenario changes to the rig's `[simulation]` section.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Overrides {
    pub defect_width_mm: Option<f64>,
    pub defect_depth_mm: Option<f64>,
    pub defect_length_mm: Option<f64>,
    pub defect_shape: Option<DefectShape>,
    pub outer_race_position_deg: Option<f64>,
    pub inner_race_position_deg: Option<f64>,
    pub slip: Option<f64>,
    pub slip_jitter: Option<f64>,
    pub contact_angle_deg: Option<f64>,
    pub radial_load_n: Option<f64>,
    pub radial_clearance_mm: Option<f64>,
    /// Axial preload, N (loads every ball when the contact angle is > 0).
    pub preload_n: Option<f64>,
    /// Scales every disc's unbalance.
    pub unbalance_scale: Option<f64>,
    pub noise_rms_m_s2: Option<f64>,
    /// Moves the first structural resonance to this frequency (others keep their ratio).
    pub resonance_hz: Option<f64>,
    /// Sets the damping ratio of every structural resonance.
    pub resonance_damping: Option<f64>,
}

impl Overrides {
    /// The rig's simulation section with these overrides applied.
    pub fn apply(&self, base: &SimulationConfig) -> SimulationConfig {
        let mut s = base.clone();
        let d = &mut s.defect;
        if let Some(v) = self.defect_width_mm {
            d.width_mm = v;
        }
        if let Some(v) = self.defect_depth_mm {
            d.depth_mm = v;
        }
        if let Some(v) = self.defect_length_mm {
            d.length_mm = v;
        }
        if let Some(v) = self.defect_shape {
            d.shape = v;
        }
        if let Some(v) = self.outer_race_position_deg {
            d.outer_race_position_deg = v;
        }
        if let Some(v) = self.inner_race_position_deg {
            d.inner_race_position_deg = v;
        }
        let b = &mut s.bearing;
        if let Some(v) = self.slip {
            b.slip = v;
        }
        if let Some(v) = self.slip_jitter {
            b.slip_jitter = v;
        }
        if let Some(v) = self.contact_angle_deg {
            b.contact_angle_deg = Some(v);
        }
        if let Some(v) = self.radial_load_n {
            b.radial_load_n = v;
        }
        if let Some(v) = self.radial_clearance_mm {
            b.radial_clearance_mm = v;
        }
        if let Some(v) = self.preload_n {
            b.preload_n = v;
        }
        if let Some(k) = self.unbalance_scale {
            for disc in &mut s.rotor.discs {
                disc.unbalance_g_mm *= k;
            }
        }
        if let Some(v) = self.noise_rms_m_s2 {
            s.structure.noise_rms_m_s2 = v;
        }
        if let Some(f) = self.resonance_hz {
            if let Some(f0) = s.structure.resonances.first().map(|r| r.hz) {
                for r in &mut s.structure.resonances {
                    r.hz *= f / f0;
                }
            }
        }
        if let Some(z) = self.resonance_damping {
            for r in &mut s.structure.resonances {
                r.damping = z;
            }
        }
        s
    }

    /// `key=value` pairs of the overrides that are set (for metadata).
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let v = serde_json::to_value(self).unwrap_or_default();
        let mut out = BTreeMap::new();
        if let Some(map) = v.as_object() {
            for (k, val) in map {
                if !val.is_null() {
                    out.insert(k.clone(), val.to_string().trim_matches('"').to_string());
                }
            }
        }
        out
    }
}

/// One simulation run.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Empty = healthy.
    pub faults: Vec<Condition>,
    pub profile: SpeedProfile,
    /// Length of the recording, s.
    pub seconds: f64,
    pub seed: u64,
    pub overrides: Overrides,
    /// Extra metadata stored with the recording (plan name, case...).
    pub metadata: BTreeMap<String, String>,
}

impl Scenario {
    /// A constant-speed scenario without overrides.
    pub fn constant(faults: &[Condition], rpm: f64, seconds: f64, seed: u64) -> Scenario {
        Scenario {
            faults: faults.to_vec(),
            profile: SpeedProfile::Constant { rpm },
            seconds,
            seed,
            overrides: Overrides::default(),
            metadata: BTreeMap::new(),
        }
    }

    pub fn label(&self) -> &'static str {
        label_of(&self.faults)
    }

    pub fn defect_set(&self) -> DefectSet {
        DefectSet {
            outer_race: self.faults.contains(&Condition::OuterRace),
            inner_race: self.faults.contains(&Condition::InnerRace),
            ball: self.faults.contains(&Condition::Ball),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_lists() {
        assert!(Condition::parse_faults("healthy").unwrap().is_empty());
        assert_eq!(
            Condition::parse_faults("inner_race,outer_race").unwrap(),
            vec![Condition::InnerRace, Condition::OuterRace]
        );
        assert_eq!(
            label_of(&Condition::parse_faults("ir+or").unwrap()),
            "inner_race"
        );
        let err = Condition::parse_faults("cage").unwrap_err().to_string();
        assert!(err.contains("cage"), "{err}");
    }

    #[test]
    fn overrides_apply() {
        let base = SimulationConfig::default();
        let o = Overrides {
            defect_width_mm: Some(0.3),
            resonance_hz: Some(2000.0),
            ..Default::default()
        };
        let s = o.apply(&base);
        assert_eq!(s.defect.width_mm, 0.3);
        assert!((s.structure.resonances[0].hz - 2000.0).abs() < 1e-9);
        assert!(s.structure.resonances[1].hz > 2000.0);
        assert_eq!(o.to_metadata()["defect_width_mm"], "0.3");
    }
}
