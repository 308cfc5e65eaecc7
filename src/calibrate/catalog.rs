//! The effect catalog: each effect is a switchable change of the rig's `[simulation]`
//! section with bounded parameters. `apply` maps parameter values onto simulation keys.
//!
//! | effect | parameters (bounds) | `[simulation]` keys |
//! |---|---|---|
//! | `slip` | `slip` 0-0.06 | `bearing.slip` |
//! | `contact_angle` | `contact_angle_deg` 0-40 | `bearing.contact_angle_deg` |
//! | `resonance` | `hz` 800-0.4 fs | `structure.resonances[0].hz` |
//! | `unbalance` | `scale` 0.1-300 (log) | `rotor.discs[*].unbalance_g_mm` x scale |
//! | `line_interference` | `line_hz` {50, 60}, `amplitude_m_s2` 0.01-3 (log) | `structure.line_hz`, `line_amplitudes_m_s2` |
//! | `speed_fluctuation` | `fraction` 0.002-0.1 (log), `period_s` 0.2-5 (log) | `speed_fluctuation.fraction`, `.period_s` |

use crate::config::simulation::{SimulationConfig, SpeedFluctuationConfig};
use serde::Serialize;

/// Effects the calibrator can add.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    Slip,
    ContactAngle,
    Resonance,
    Unbalance,
    LineInterference,
    SpeedFluctuation,
}

pub const ALL: [Effect; 6] = [
    Effect::Slip,
    Effect::ContactAngle,
    Effect::Resonance,
    Effect::Unbalance,
    Effect::LineInterference,
    Effect::SpeedFluctuation,
];

/// How a parameter is searched.
#[derive(Debug, Clone, PartialEq)]
pub enum Range {
    Linear(f64, f64),
    Log(f64, f64),
    Choice(Vec<f64>),
}

/// One bounded parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: &'static str,
    pub range: Range,
}

impl Effect {
    pub fn name(&self) -> &'static str {
        match self {
            Effect::Slip => "slip",
            Effect::ContactAngle => "contact_angle",
            Effect::Resonance => "resonance",
            Effect::Unbalance => "unbalance",
            Effect::LineInterference => "line_interference",
            Effect::SpeedFluctuation => "speed_fluctuation",
        }
    }

    /// The error components this effect acts on: its parameters are searched, and it is
    /// accepted, on these alone, so an effect cannot win by absorbing a mismatch it does not
    /// model physically (e.g. a contact angle reshaping the resonance bands).
    pub fn components(&self) -> &'static [&'static str] {
        match self {
            Effect::Slip | Effect::ContactAngle => &["env"],
            Effect::Resonance => &["bands"],
            Effect::Unbalance | Effect::LineInterference => &["lines"],
            Effect::SpeedFluctuation => &["speed", "lines"],
        }
    }

    /// Parameters and bounds; `fs` is the lowest measured sample rate.
    pub fn params(&self, fs: f64) -> Vec<Param> {
        let p = |name, range| Param { name, range };
        match self {
            Effect::Slip => vec![p("slip", Range::Linear(0.0, 0.06))],
            Effect::ContactAngle => vec![p("contact_angle_deg", Range::Linear(0.0, 40.0))],
            Effect::Resonance => vec![p("hz", Range::Log(800.0, 0.4 * fs))],
            Effect::Unbalance => vec![p("scale", Range::Log(0.1, 300.0))],
            Effect::LineInterference => vec![
                p("line_hz", Range::Choice(vec![50.0, 60.0])),
                p("amplitude_m_s2", Range::Log(0.01, 3.0)),
            ],
            Effect::SpeedFluctuation => vec![
                p("period_s", Range::Log(0.2, 5.0)),
                p("fraction", Range::Log(0.002, 0.1)),
            ],
        }
    }

    /// Starting values for a search (the rig's current value where there is one).
    pub fn start(&self, sim: &SimulationConfig, fs: f64) -> Vec<f64> {
        match self {
            Effect::Slip => vec![sim.bearing.slip],
            Effect::ContactAngle => vec![sim.bearing.contact_angle_deg.unwrap_or(0.0)],
            Effect::Resonance => vec![sim.structure.resonances.first().map_or(0.2 * fs, |r| r.hz)],
            Effect::Unbalance => vec![1.0],
            Effect::LineInterference => vec![50.0, 0.1],
            Effect::SpeedFluctuation => vec![1.0, 0.01],
        }
    }

    /// The simulation section with this effect switched on at `values`.
    pub fn apply(&self, base: &SimulationConfig, values: &[f64]) -> SimulationConfig {
        let mut s = base.clone();
        match self {
            Effect::Slip => s.bearing.slip = values[0],
            Effect::ContactAngle => s.bearing.contact_angle_deg = Some(values[0]),
            Effect::Resonance => {
                if let Some(r) = s.structure.resonances.first_mut() {
                    r.hz = values[0];
                }
            }
            Effect::Unbalance => {
                for d in &mut s.rotor.discs {
                    d.unbalance_g_mm *= values[0];
                }
            }
            Effect::LineInterference => {
                s.structure.line_hz = values[0];
                s.structure.line_amplitudes_m_s2 = vec![values[1]];
            }
            Effect::SpeedFluctuation => {
                s.speed_fluctuation = Some(SpeedFluctuationConfig {
                    period_s: values[0],
                    fraction: values[1],
                })
            }
        }
        s
    }
}
