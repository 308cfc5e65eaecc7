//! When the health indicators leave the machine's healthy baseline for good (issue 35): the
//! alarm that holds.
//!
//! Each window's indicator scores ([`IndicatorBaseline::scores`]) are smoothed by a running
//! **median over the last `median_of` windows** (31: about five minutes of 10 s captures): one
//! loud capture, or any burst of up to 15 windows, cannot move the median, so it cannot alarm.
//! An indicator stands **beyond** the baseline when its smoothed score exceeds the highest
//! smoothed score the healthy windows themselves reached, plus `margin` (3) spreads, and at
//! least `margin`: the healthy stretch, its run-in and its slow drifts included, never reaches
//! its own threshold, and a drift must carry the level three healthy spreads past anything
//! seen while healthy. Damage raises energy and impulsiveness, so only upward departures
//! count (a level that falls, as the resonance band does when a machine warms up, is no
//! alarm). The machine has **departed** once some indicator has stood beyond for `persist`
//! consecutive windows (30); from then on the departure holds: the health state is a fault
//! and stays one ([`crate::health::HealthStateMachine`]), whatever later windows say, until
//! the machine is re-baselined. These numbers were chosen on three of the six FEMTO learning
//! bearings and checked on the other three (docs/early-warning.md).

use super::indicators::{median, Indicator, IndicatorBaseline, Indicators, PerIndicator};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Default windows in the running median.
pub const MEDIAN_OF: usize = 31;
/// Default windows an indicator must stand beyond the baseline before the machine has
/// departed.
pub const PERSIST: usize = 30;
/// Default margin, in healthy spreads, above the highest healthy smoothed score.
pub const MARGIN: f32 = 3.0;

/// How the departure is decided (the `[health.departure]` section).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepartureSettings {
    /// Consecutive windows some indicator must stand beyond its threshold.
    #[serde(default = "default_persist")]
    pub persist: usize,
    /// Spreads above the highest healthy smoothed score (and the least threshold).
    #[serde(default = "default_margin")]
    pub margin: f32,
}

fn default_persist() -> usize {
    PERSIST
}
fn default_margin() -> f32 {
    MARGIN
}

impl Default for DepartureSettings {
    fn default() -> Self {
        DepartureSettings {
            persist: PERSIST,
            margin: MARGIN,
        }
    }
}

impl DepartureSettings {
    /// Check the numbers; errors name the key.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.persist == 0 || self.persist > 100_000 {
            anyhow::bail!(
                "health.departure.persist = {}: must be between 1 and 100000 windows",
                self.persist
            );
        }
        if !(self.margin.is_finite() && self.margin > 0.0) {
            anyhow::bail!(
                "health.departure.margin = {}: must be a finite number of spreads > 0",
                self.margin
            );
        }
        Ok(())
    }
}

/// Running medians of the last `n` windows' scores, per indicator.
#[derive(Debug, Clone)]
struct Smoother {
    n: usize,
    recent: VecDeque<[f32; 4]>,
    scratch: Vec<f32>,
}

impl Smoother {
    fn new(n: usize) -> Self {
        let n = n.max(1);
        Smoother {
            n,
            recent: VecDeque::with_capacity(n + 1),
            scratch: Vec::with_capacity(n),
        }
    }

    /// Add one window's scores; the medians once `n` windows are held.
    fn push(&mut self, z: PerIndicator) -> Option<PerIndicator> {
        if self.recent.len() >= self.n {
            self.recent.pop_front();
        }
        self.recent.push_back(z.to_array());
        if self.recent.len() < self.n {
            return None;
        }
        let mut out = [0.0f32; 4];
        for (j, o) in out.iter_mut().enumerate() {
            self.scratch.clear();
            self.scratch.extend(self.recent.iter().map(|r| r[j]));
            *o = median(&mut self.scratch);
        }
        Some(PerIndicator::from_array(out))
    }
}

/// The highest smoothed score per indicator over the healthy windows (in time order), at the
/// baseline's median length.
pub fn healthy_max<'a>(
    b: &IndicatorBaseline,
    healthy: impl Iterator<Item = &'a Indicators>,
) -> PerIndicator {
    let mut s = Smoother::new(b.median_of);
    let mut top = [f32::NEG_INFINITY; 4];
    for i in healthy {
        if let Some(m) = s.push(b.scores(i)) {
            for (t, v) in top.iter_mut().zip(m.to_array()) {
                *t = t.max(v);
            }
        }
    }
    PerIndicator::from_array(top.map(|t| if t.is_finite() { t } else { 0.0 }))
}

/// The machine's healthy indicator baseline from its healthy windows' indicators, in time
/// order: the levels ([`IndicatorBaseline::fit`]) and the highest smoothed score each
/// indicator reached over them (None: fewer sound windows than `median_of`).
pub fn fit_baseline(healthy: &[Indicators], median_of: usize) -> Option<IndicatorBaseline> {
    let mut b = IndicatorBaseline::fit(healthy, median_of)?;
    let top = healthy_max(&b, healthy.iter().filter(|i| i.is_sound()));
    b.rms.healthy_max = top.rms;
    b.crest.healthy_max = top.crest;
    b.kurtosis.healthy_max = top.kurtosis;
    b.resonance.healthy_max = top.resonance;
    Some(b)
}

/// What one window says about the departure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DepartureReading {
    /// This window's indicator scores ([`IndicatorBaseline::scores`]).
    pub scores: PerIndicator,
    /// The running medians of the scores (None until `median_of` windows were seen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smoothed: Option<PerIndicator>,
    /// Each indicator's threshold on its smoothed score.
    pub threshold: PerIndicator,
    /// The indicator standing furthest beyond (or nearest to) its threshold, and by how much
    /// (smoothed score - threshold; > 0: beyond).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leading: Option<Indicator>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excess: Option<f32>,
    /// Consecutive windows some indicator has stood beyond.
    pub beyond_for: usize,
    /// Window-end time (s) at which the machine departed from its healthy baseline (None:
    /// not departed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub departed_since_s: Option<f64>,
}

/// The departure test of one machine (module doc).
#[derive(Debug, Clone)]
pub struct Departure {
    baseline: IndicatorBaseline,
    settings: DepartureSettings,
    smoother: Smoother,
    beyond_for: usize,
    since: Option<f64>,
}

impl Departure {
    pub fn new(baseline: IndicatorBaseline, settings: DepartureSettings) -> Self {
        Departure {
            smoother: Smoother::new(baseline.median_of),
            baseline,
            settings,
            beyond_for: 0,
            since: None,
        }
    }

    pub fn baseline(&self) -> &IndicatorBaseline {
        &self.baseline
    }

    pub fn settings(&self) -> DepartureSettings {
        self.settings
    }

    /// Each indicator's threshold on its smoothed score.
    pub fn threshold(&self) -> PerIndicator {
        let m = self.settings.margin;
        PerIndicator::from_array(self.baseline.levels().map(|l| l.healthy_max.max(0.0) + m))
    }

    /// Window-end time at which the machine departed (None: it has not).
    pub fn departed_since(&self) -> Option<f64> {
        self.since
    }

    /// Add one window ending at `t_end`.
    pub fn push(&mut self, t_end: f64, values: &Indicators) -> DepartureReading {
        let scores = self.baseline.scores(values);
        let smoothed = self.smoother.push(scores);
        let threshold = self.threshold();
        let lead = smoothed.map(|m| {
            let (m, t) = (m.to_array(), threshold.to_array());
            (0..4)
                .map(|j| (j, m[j] - t[j]))
                .fold((0, f32::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a })
        });
        match lead {
            Some((_, e)) if e > 0.0 => self.beyond_for += 1,
            _ => self.beyond_for = 0,
        }
        if self.since.is_none() && self.beyond_for >= self.settings.persist {
            self.since = Some(t_end);
        }
        DepartureReading {
            scores,
            smoothed,
            threshold,
            leading: lead.map(|(j, _)| Indicator::ALL[j]),
            excess: lead.map(|(_, e)| e),
            beyond_for: self.beyond_for,
            departed_since_s: self.since,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::indicators::LEVEL_FLOOR as FLOOR;

    fn ind(rms: f32, kurtosis: f32) -> Indicators {
        Indicators {
            rms,
            crest: 3.0,
            kurtosis,
            resonance: 0.5 * rms,
            samples: 2560,
        }
    }

    /// A healthy stretch: RMS 1 +- 2 % (a deterministic wobble), kurtosis 0 +- 0.1.
    fn healthy(n: usize) -> Vec<Indicators> {
        (0..n)
            .map(|i| {
                let w = ((i * 37 % 11) as f32 - 5.0) / 5.0;
                ind(1.0 + 0.02 * w, 0.1 * w)
            })
            .collect()
    }

    fn run(b: IndicatorBaseline, seq: &[Indicators]) -> Vec<DepartureReading> {
        let mut d = Departure::new(b, DepartureSettings::default());
        seq.iter()
            .enumerate()
            .map(|(i, x)| d.push(10.0 * (i + 1) as f64, x))
            .collect()
    }

    #[test]
    fn the_healthy_stretch_never_reaches_its_own_threshold() {
        // a run-in: the first 40 windows twice as loud, inside the baseline
        let mut h = healthy(200);
        for x in h.iter_mut().take(40) {
            x.rms *= 2.0;
            x.resonance *= 2.0;
        }
        let b = fit_baseline(&h, MEDIAN_OF).unwrap();
        let out = run(b, &h);
        assert!(out.iter().all(|r| r.departed_since_s.is_none()));
        assert!(out.iter().all(|r| r.excess.is_none_or(|e| e <= 0.0)));
    }

    #[test]
    fn a_burst_shorter_than_half_the_median_never_counts_and_a_lasting_rise_holds() {
        let h = healthy(100);
        let b = fit_baseline(&h, MEDIAN_OF).unwrap();
        let mut seq = h.clone();
        // 15 loud windows (< 31 / 2) in a row, then healthy again
        seq.extend((0..15).map(|_| ind(50.0, 40.0)));
        seq.extend(healthy(100));
        let out = run(b, &seq);
        assert!(
            out.iter().all(|r| r.beyond_for == 0),
            "a burst moved the median"
        );
        // a rise to 3x RMS that lasts: beyond once half the median holds it, departed
        // `persist` windows later, and departed stays departed when it falls back
        let mut seq = h.clone();
        seq.extend((0..80).map(|_| ind(3.0, 0.0)));
        seq.extend(healthy(50));
        let out = run(b, &seq);
        let first_beyond = out.iter().position(|r| r.beyond_for == 1).unwrap();
        assert_eq!(
            first_beyond,
            100 + 15,
            "a median of 31 turns at the 16th loud window"
        );
        let departed = out
            .iter()
            .position(|r| r.departed_since_s.is_some())
            .unwrap();
        assert_eq!(departed, first_beyond + PERSIST - 1);
        assert_eq!(out[departed].leading, Some(Indicator::Rms));
        assert!(out[departed..].iter().all(|r| r.departed_since_s.is_some()));
        assert!(out.last().unwrap().beyond_for == 0);
    }

    #[test]
    fn a_fall_or_a_drift_within_the_margin_is_no_departure() {
        let h = healthy(100);
        let b = fit_baseline(&h, MEDIAN_OF).unwrap();
        // the level falls to a third (warming up), and drifts up by 2 spreads over 500 windows
        let mut seq: Vec<Indicators> = (0..200).map(|_| ind(0.33, 0.0)).collect();
        seq.extend((0..500).map(|i| {
            let f = (FLOOR * 2.0 * i as f32 / 500.0).exp();
            ind(f, 0.0)
        }));
        let out = run(b, &seq);
        assert!(out.iter().all(|r| r.departed_since_s.is_none()));
        let bad = DepartureSettings {
            persist: 0,
            margin: 3.0,
        };
        assert!(bad.validate().unwrap_err().to_string().contains("persist"));
    }
}
