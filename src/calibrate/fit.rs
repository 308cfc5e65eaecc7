//! Greedy forward selection: simulate every measured operating point, then repeatedly try
//! each catalog effect not yet added (bounded search on the fit part), and add the one that
//! cuts the fit-part error most, if the held-out part confirms it ([`accepts`]). Stops when
//! nothing passes. Simulations are cached by (simulation section, operating point).

use super::catalog::{Effect, ALL};
use super::error::{self, ErrorParts};
use super::locate::{locate, Unexplained};
use super::measured::Measured;
use super::search;
use super::views::{self, Views};
use crate::config::simulation::SimulationConfig;
use crate::config::RigConfig;
use crate::sim::{rig_simulation, simulate_with, Scenario};
use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};

/// Relative and absolute cuts an effect must make, in its own components, on the fit part...
pub const FIT_CUT: (f64, f64) = (0.25, 0.05);
/// ... and on the held-out part.
pub const HELD_CUT: (f64, f64) = (0.10, 0.03);

/// Acceptance rule, on the effect's own error components: the fit part drops by >= 25 %
/// and >= 0.05 AND the held-out part by >= 10 % and >= 0.03.
pub fn accepts(fit: (f64, f64), held: (f64, f64)) -> bool {
    let cut = |(b, a): (f64, f64), (rel, abs): (f64, f64)| b - a >= rel * b && b - a >= abs;
    cut(fit, FIT_CUT) && cut(held, HELD_CUT)
}

/// One candidate effect as tried in one round.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    pub name: String,
    pub params: BTreeMap<String, f64>,
    pub fit_before: f64,
    pub fit_after: f64,
    pub held_before: f64,
    pub held_after: f64,
    /// The effect's own components (search and acceptance), fit and held-out part.
    pub own: Vec<String>,
    pub own_fit_before: f64,
    pub own_fit_after: f64,
    pub own_held_before: f64,
    pub own_held_after: f64,
    /// Error over all recordings before / after.
    pub error_before: f64,
    pub error_after: f64,
    pub accepted: bool,
    pub evaluations: usize,
    #[serde(skip)]
    pub effect: Option<Effect>,
    #[serde(skip)]
    pub values: Vec<f64>,
}

/// The outcome of a calibration.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub fit_part: Vec<bool>,
    pub before: ErrorParts,
    pub after: ErrorParts,
    pub accepted: Vec<Trial>,
    pub rounds: Vec<Vec<Trial>>,
    pub unexplained: Vec<Unexplained>,
    pub calibrated: SimulationConfig,
    pub measured_views: Vec<Views>,
    pub views_before: Vec<Views>,
    pub views_after: Vec<Views>,
}

/// Measured recordings and their simulated twins.
pub struct Twin<'a> {
    pub rig: &'a RigConfig,
    pub ops: &'a [Measured],
    pub measured: Vec<Views>,
    cache: Mutex<HashMap<(String, usize), Arc<Views>>>,
}

impl<'a> Twin<'a> {
    pub fn new(rig: &'a RigConfig, ops: &'a [Measured]) -> Result<Self> {
        let measured = ops
            .par_iter()
            .map(|m| {
                let mut v = views::compute(&m.recording, rig)
                    .with_context(|| format!("views of {}", m.name))?;
                v.healthy = m.faults.is_empty();
                Ok(v)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Twin {
            rig,
            ops,
            measured,
            cache: Mutex::new(HashMap::new()),
        })
    }

    /// Views of the simulated twin of operating point `i`.
    pub fn simulated(&self, sim: &SimulationConfig, i: usize) -> Result<Arc<Views>> {
        let key = (serde_json::to_string(sim)?, i);
        if let Some(v) = self.cache.lock().expect("cache").get(&key) {
            return Ok(v.clone());
        }
        let m = &self.ops[i];
        let mut s = sim.clone();
        s.sample_rate_hz = Some(m.recording.sample_rate);
        let sc = Scenario::constant(&m.faults, m.rpm, m.recording.duration_s(), 1000 + i as u64);
        let rec = simulate_with(self.rig, &s, &sc)
            .with_context(|| format!("simulating the twin of {}", m.name))?;
        let v = Arc::new(views::compute(&rec, self.rig)?);
        self.cache.lock().expect("cache").insert(key, v.clone());
        Ok(v)
    }

    /// Mean error over the operating points `idx`.
    pub fn error(&self, sim: &SimulationConfig, idx: &[usize]) -> Result<ErrorParts> {
        let parts = idx
            .par_iter()
            .map(|&i| Ok(error::pair(&self.measured[i], &*self.simulated(sim, i)?)))
            .collect::<Result<Vec<_>>>()?;
        Ok(error::mean(&parts))
    }
}

/// Extra, reportable parameters derived from the simulation (e.g. the 1x amplitude the
/// unbalance scale produces at the highest measured speed).
fn derived(twin: &Twin, effect: Effect, sim: &SimulationConfig) -> Result<BTreeMap<String, f64>> {
    let mut out = BTreeMap::new();
    if effect == Effect::Unbalance {
        let (i, m) = twin
            .ops
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.rpm.total_cmp(&b.1.rpm))
            .context("no operating points")?;
        let v = twin.simulated(sim, i)?;
        let k = (m.rpm / 60.0).round() as usize;
        let a = v.amplitude_hz.get(k).copied().unwrap_or(0.0);
        out.insert("order1_m_s2".into(), (a * 1e4).round() / 1e4);
        out.insert("at_rpm".into(), m.rpm.round());
    }
    Ok(out)
}

/// Run the greedy calibration.
pub fn calibrate(rig: &RigConfig, ops: &[Measured], fit_part: Vec<bool>) -> Result<Outcome> {
    let base = rig_simulation(rig)?.clone();
    let twin = Twin::new(rig, ops)?;
    let all: Vec<usize> = (0..ops.len()).collect();
    let fit: Vec<usize> = all.iter().copied().filter(|&i| fit_part[i]).collect();
    let held: Vec<usize> = all.iter().copied().filter(|&i| !fit_part[i]).collect();
    let fs = ops
        .iter()
        .map(|m| m.recording.sample_rate)
        .fold(f64::INFINITY, f64::min);
    let before = twin.error(&base, &all)?;
    let mut current = base.clone();
    let mut accepted: Vec<Trial> = Vec::new();
    let mut rounds = Vec::new();
    loop {
        let cur_fit_parts = twin.error(&current, &fit)?;
        let cur_held_parts = twin.error(&current, &held)?;
        let (cur_fit, cur_held) = (cur_fit_parts.total, cur_held_parts.total);
        let cur_all = twin.error(&current, &all)?.total;
        let mut trials = Vec::new();
        for effect in ALL {
            if accepted.iter().any(|t| t.effect == Some(effect)) {
                continue;
            }
            let params = effect.params(fs);
            let start = effect.start(&current, fs);
            let mut failure = None;
            let own = effect.components();
            let (values, own_fit_after, evals) =
                search::minimize(&params, &start, &mut |x| match twin
                    .error(&effect.apply(&current, x), &fit)
                {
                    Ok(e) => e.of(own),
                    Err(e) => {
                        failure.get_or_insert(e);
                        f64::INFINITY
                    }
                });
            if let Some(e) = failure {
                return Err(e.context(format!("trying effect {}", effect.name())));
            }
            let cand = effect.apply(&current, &values);
            let fit_after = twin.error(&cand, &fit)?.total;
            let held_parts = twin.error(&cand, &held)?;
            let held_after = held_parts.total;
            let (own_fit_before, own_held_before) = (cur_fit_parts.of(own), cur_held_parts.of(own));
            let own_held_after = held_parts.of(own);
            let all_after = twin.error(&cand, &all)?.total;
            let mut p: BTreeMap<String, f64> = params
                .iter()
                .zip(&values)
                .map(|(p, v)| (p.name.to_string(), round_sig(*v)))
                .collect();
            p.extend(derived(&twin, effect, &cand)?);
            trials.push(Trial {
                name: effect.name().into(),
                params: p,
                fit_before: cur_fit,
                fit_after,
                held_before: cur_held,
                held_after,
                error_before: cur_all,
                error_after: all_after,
                own: own.iter().map(|s| s.to_string()).collect(),
                own_fit_before,
                own_fit_after,
                own_held_before,
                own_held_after,
                accepted: accepts(
                    (own_fit_before, own_fit_after),
                    (own_held_before, own_held_after),
                ),
                evaluations: evals,
                effect: Some(effect),
                values,
            });
        }
        let best = trials
            .iter()
            .enumerate()
            .filter(|(_, t)| t.accepted)
            .max_by(|a, b| {
                let cut = |t: &Trial| t.own_fit_before - t.own_fit_after;
                cut(a.1).total_cmp(&cut(b.1))
            })
            .map(|(i, _)| i);
        for (i, t) in trials.iter_mut().enumerate() {
            t.accepted = Some(i) == best;
        }
        rounds.push(trials.clone());
        match best {
            Some(i) => {
                let t = trials[i].clone();
                current = t.effect.expect("effect").apply(&current, &t.values);
                accepted.push(t);
            }
            None => break,
        }
        if accepted.len() == ALL.len() {
            break;
        }
    }
    let after = twin.error(&current, &all)?;
    let views_before: Vec<Views> = all
        .iter()
        .map(|&i| twin.simulated(&base, i).map(|v| (*v).clone()))
        .collect::<Result<_>>()?;
    let views_after: Vec<Views> = all
        .iter()
        .map(|&i| twin.simulated(&current, i).map(|v| (*v).clone()))
        .collect::<Result<_>>()?;
    let pairs: Vec<(&Views, &Views)> = twin.measured.iter().zip(views_after.iter()).collect();
    let unexplained = locate(&pairs);
    Ok(Outcome {
        fit_part,
        before,
        after,
        accepted,
        rounds,
        unexplained,
        calibrated: current,
        measured_views: twin.measured.clone(),
        views_before,
        views_after,
    })
}

/// Round to 4 significant digits (reports).
pub fn round_sig(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let d = 3 - v.abs().log10().floor() as i32;
    let p = 10f64.powi(d);
    (v * p).round() / p
}
