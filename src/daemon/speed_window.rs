//! Shaft speed for one streaming window, as the rig file's `[speed]` asks: tacho edges
//! (detected from an analog tacho or delivered by the source) kept from one window before the
//! start, a fixed rpm, the source's stored rpm (`recording`, falling back to edges, then to
//! estimation), or an estimate from the vibration itself. Also says when the tacho has gone
//! quiet inside a window (so the state goes `unknown` instead of raising a false alarm).

use super::windows::WindowView;
use crate::config::{RigConfig, SpeedConfig};
use crate::dsp::speed::SpeedTrack;
use crate::dsp::speed_estimate;
use anyhow::Result;

/// Missing pulses for longer than this many revolutions at a window edge = tacho lost.
const LOST_REVS: f64 = 2.5;

enum Mode {
    Edges {
        pulses_per_rev: u32,
        name: &'static str,
    },
    Constant(SpeedTrack),
    Estimate {
        min_rpm: f64,
        max_rpm: f64,
    },
    /// `recording` without a stored rpm: edges when there are some, else estimate.
    EdgesOrEstimate {
        pulses_per_rev: u32,
    },
}

/// Builds a [`SpeedTrack`] per window.
pub struct SpeedWindow {
    mode: Mode,
    sample_rate: f64,
    edges: Vec<f64>,
}

impl SpeedWindow {
    pub fn new(rig: &RigConfig, sample_rate: f64, nominal_rpm: Option<f64>) -> Result<Self> {
        let mode = match &rig.speed {
            SpeedConfig::Tacho { pulses_per_rev, .. } => Mode::Edges {
                pulses_per_rev: *pulses_per_rev,
                name: "tacho",
            },
            SpeedConfig::Edges { pulses_per_rev } => Mode::Edges {
                pulses_per_rev: *pulses_per_rev,
                name: "edges",
            },
            SpeedConfig::Fixed { rpm } => Mode::Constant(SpeedTrack::fixed(*rpm)?),
            SpeedConfig::Recording => match nominal_rpm {
                Some(rpm) => Mode::Constant(SpeedTrack::constant(rpm, "recording")?),
                None => Mode::EdgesOrEstimate {
                    pulses_per_rev: rig.pulses_per_rev(),
                },
            },
            SpeedConfig::Estimate { min_rpm, max_rpm } => Mode::Estimate {
                min_rpm: *min_rpm,
                max_rpm: *max_rpm,
            },
        };
        Ok(SpeedWindow {
            mode,
            sample_rate,
            edges: Vec::with_capacity(256),
        })
    }

    /// Short name of the speed source (for messages before a window has been computed).
    pub fn source_name(&self) -> &'static str {
        match &self.mode {
            Mode::Edges { name, .. } => name,
            Mode::Constant(_) => "fixed",
            Mode::Estimate { .. } => "estimate",
            Mode::EdgesOrEstimate { .. } => "recording",
        }
    }

    /// The speed track for this window (`classifier` = the classifier channel's samples, for
    /// estimation).
    pub fn track(&mut self, view: &WindowView, classifier: &[f32]) -> Result<SpeedTrack> {
        match &self.mode {
            Mode::Edges {
                pulses_per_rev,
                name,
            } => {
                self.edges.clear();
                self.edges.extend(view.edges.iter().copied());
                SpeedTrack::from_edges(&self.edges, *pulses_per_rev, name)
            }
            Mode::Constant(t) => Ok(t.clone()),
            Mode::Estimate { min_rpm, max_rpm } => self.estimate(classifier, *min_rpm, *max_rpm),
            Mode::EdgesOrEstimate { pulses_per_rev } => {
                self.edges.clear();
                self.edges.extend(view.edges.iter().copied());
                if self.edges.len() >= 3 {
                    SpeedTrack::from_edges(&self.edges, *pulses_per_rev, "edges")
                } else {
                    self.estimate(classifier, 300.0, 3600.0)
                }
            }
        }
    }

    /// One speed for the whole window from the vibration (a constant track needs no clock).
    fn estimate(&self, x: &[f32], min_rpm: f64, max_rpm: f64) -> Result<SpeedTrack> {
        let t = speed_estimate::estimate_constant(x, self.sample_rate, min_rpm, max_rpm)?;
        SpeedTrack::constant(t.rpm, "estimate")
    }

    /// True when tacho pulses stop (or have not started) more than a couple of revolutions
    /// inside the window: the speed there is a guess, so the window must not be classified.
    pub fn lost_pulses(&self, track: &SpeedTrack, t0: f64, t1: f64) -> bool {
        if !matches!(self.mode, Mode::Edges { .. } | Mode::EdgesOrEstimate { .. })
            || track.source() == "estimate"
        {
            return false;
        }
        let Some((first, last)) = track.span() else {
            return false;
        };
        let rpm = track.mean_rpm(first.max(t0 - 1.0), last);
        if !(rpm.is_finite() && rpm > 0.0) {
            return true;
        }
        let rev_s = 60.0 / rpm;
        first > t0 + LOST_REVS * rev_s || last < t1 - LOST_REVS * rev_s
    }
}
