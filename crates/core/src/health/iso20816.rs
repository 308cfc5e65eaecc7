//! ISO 20816-3 evaluation zones for broadband velocity RMS (10-1000 Hz), as an advisory next
//! to the classifier: zone A (new machines), B (unrestricted long-term operation), C (limited
//! operation), D (damage likely). The zone boundaries depend on the machine group and the
//! foundation; the rig in the thesis is smaller than the standard's 15 kW floor, so the zone is
//! published as advice and never changes the health state.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};

/// Machine group of ISO 20816-3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MachineGroup {
    /// Large machines, 300 kW .. 50 MW.
    Group1,
    /// Medium machines, 15 kW .. 300 kW.
    Group2,
}

/// Support stiffness class of ISO 20816-3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Foundation {
    Rigid,
    Flexible,
}

/// Zone limits (`[health.iso20816]`): a group and foundation, or explicit boundaries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZoneConfig {
    #[serde(default = "default_group")]
    pub group: MachineGroup,
    #[serde(default = "default_foundation")]
    pub foundation: Foundation,
    /// Explicit A/B, B/C, C/D boundaries in mm/s (overrides group and foundation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits_mm_s: Option<[f64; 3]>,
}

fn default_group() -> MachineGroup {
    MachineGroup::Group2
}
fn default_foundation() -> Foundation {
    Foundation::Rigid
}

impl Default for ZoneConfig {
    fn default() -> Self {
        ZoneConfig {
            group: default_group(),
            foundation: default_foundation(),
            limits_mm_s: None,
        }
    }
}

/// Evaluation zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Zone {
    A,
    B,
    C,
    D,
}

impl ZoneConfig {
    /// The A/B, B/C and C/D boundaries in mm/s (ISO 20816-3:2022, Table A.1 / A.2).
    pub fn limits(&self) -> [f64; 3] {
        if let Some(l) = self.limits_mm_s {
            return l;
        }
        match (self.group, self.foundation) {
            (MachineGroup::Group1, Foundation::Rigid) => [2.3, 4.5, 7.1],
            (MachineGroup::Group1, Foundation::Flexible) => [3.5, 7.1, 11.0],
            (MachineGroup::Group2, Foundation::Rigid) => [1.4, 2.8, 4.5],
            (MachineGroup::Group2, Foundation::Flexible) => [2.3, 4.5, 7.1],
        }
    }

    pub fn validate(&self) -> Result<()> {
        let l = self.limits();
        if !(l[0] > 0.0 && l[0] < l[1] && l[1] < l[2] && l[2].is_finite()) {
            bail!("health.iso20816.limits_mm_s = {l:?}: need 0 < A/B < B/C < C/D");
        }
        Ok(())
    }

    /// The zone of a velocity RMS value in mm/s (None for a non-finite value).
    pub fn zone(&self, v_rms_mm_s: f64) -> Option<Zone> {
        if !v_rms_mm_s.is_finite() {
            return None;
        }
        let l = self.limits();
        Some(if v_rms_mm_s <= l[0] {
            Zone::A
        } else if v_rms_mm_s <= l[1] {
            Zone::B
        } else if v_rms_mm_s <= l[2] {
            Zone::C
        } else {
            Zone::D
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn group2_rigid_boundaries() {
        let z = ZoneConfig::default();
        assert_eq!(z.zone(1.0), Some(Zone::A));
        assert_eq!(z.zone(1.4), Some(Zone::A));
        assert_eq!(z.zone(2.0), Some(Zone::B));
        assert_eq!(z.zone(3.0), Some(Zone::C));
        assert_eq!(z.zone(4.6), Some(Zone::D));
        assert_eq!(z.zone(f64::NAN), None);
    }

    #[test]
    fn explicit_limits_override_and_are_checked() {
        let z = ZoneConfig {
            limits_mm_s: Some([1.0, 2.0, 3.0]),
            ..Default::default()
        };
        assert_eq!(z.zone(2.5), Some(Zone::C));
        let bad = ZoneConfig {
            limits_mm_s: Some([2.0, 1.0, 3.0]),
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("limits_mm_s"));
        let g1 = ZoneConfig {
            group: MachineGroup::Group1,
            foundation: Foundation::Flexible,
            limits_mm_s: None,
        };
        assert_eq!(g1.limits(), [3.5, 7.1, 11.0]);
    }
}
