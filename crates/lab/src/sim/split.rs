//! The mechanics and the structural path run apart. The structural modes
//! ([`super::structure`]) are driven by the bearing's force on the housing and feed nothing
//! back into the rotor or the bearing, and the anti-aliasing decimation is linear, so a
//! run's signals are its mechanical signals plus the decimated response of the modes to the
//! housing forces. [`run_mechanics`] runs the mechanics once and keeps the forces;
//! [`EngineRun::with_resonances`] adds the modes of any `[[simulation.structure.resonances]]`
//! list in one cheap pass. Calibration uses it, so trying a resonance (its frequency and
//! damping) does not re-run the mechanics ([`mechanics_part`] is the cache key).

use super::decimate::{design, Decimator};
use super::structure::Structure;
use super::{engine_with, integrate, EngineRun, Scenario};
use crate::config::simulation::{ResonanceConfig, SimulationConfig};
use crate::config::RigConfig;
use anyhow::{bail, Result};

/// The part of a simulation section the mechanics depend on: [`SimulationConfig::engine_part`]
/// without the structural modes.
pub fn mechanics_part(sim: &SimulationConfig) -> SimulationConfig {
    let mut s = sim.engine_part();
    s.structure.resonances.clear();
    s
}

/// The mechanics of one scenario with the structural path left out and the housing forces
/// kept: finish it with [`EngineRun::with_resonances`].
pub fn run_mechanics(
    rig: &RigConfig,
    base: &SimulationConfig,
    scenario: &Scenario,
) -> Result<EngineRun> {
    engine_with(rig, base, scenario, true)
}

impl EngineRun {
    /// Bytes this run holds (its signals, shaft angles and any housing forces kept).
    pub fn bytes(&self) -> usize {
        let signals: usize = self.out.signals.iter().map(Vec::len).sum();
        let forces = self.out.housing_forces.as_ref().map_or(0, |(f, _)| f.len());
        8 * (signals + self.out.boundary_angles.len()) + 24 * forces
    }

    /// This run of the mechanics ([`run_mechanics`]) with the structural modes `res`
    /// added: the run [`super::run_engine`] gives for a section with these resonances, up
    /// to rounding (the modes' response is decimated on its own and added). The result
    /// keeps no forces.
    pub fn with_resonances(&self, res: &[ResonanceConfig]) -> Result<EngineRun> {
        let Some((forces, w_steps)) = &self.out.housing_forces else {
            bail!("internal: this engine run kept no housing forces (use run_mechanics)");
        };
        let k = self.oversampling;
        let dt = 1.0 / (self.fs * k as f64);
        let mut out = integrate::EngineOutput {
            signals: self.out.signals.clone(),
            boundary_angles: self.out.boundary_angles.clone(),
            max_loaded: self.out.max_loaded,
            max_excursion: self.out.max_excursion,
            want: self.out.want.clone(),
            housing_forces: None,
        };
        if !res.is_empty() {
            let added =
                structure_signals(forces, *w_steps, res, &self.out.want, (k, dt, self.n_out));
            for (s, a) in out.signals.iter_mut().zip(added) {
                for (x, y) in s.iter_mut().zip(a.into_iter().flatten()) {
                    *x += y;
                }
            }
        }
        Ok(EngineRun {
            out,
            rng: self.rng.clone(),
            fs: self.fs,
            n_out: self.n_out,
            alpha: self.alpha,
            oversampling: k,
        })
    }
}

/// The modes' acceleration on each wanted signal (None for signals they do not reach: the
/// drive-end housing), decimated on the engine's output instants: internal step `i` (from
/// `-w_steps`) is pushed from `i = -d` on and output sample `o` is read at `i = o k + d`
/// (`d` the filter's half length), as in [`super::integrate::Engine::run`].
fn structure_signals(
    forces: &[[f64; 3]],
    w_steps: i64,
    res: &[ResonanceConfig],
    want: &[usize],
    (k, dt, n_out): (usize, f64, usize),
) -> Vec<Option<Vec<f64>>> {
    let taps = design(k, 14);
    let d = (taps.len() / 2) as i64;
    let ki = k as i64;
    let mut structure = Structure::new(res, dt);
    let mut decs: Vec<Option<Decimator>> = want
        .iter()
        .map(|&w| (w < 3).then(|| Decimator::new(taps.clone())))
        .collect();
    let mut out: Vec<Option<Vec<f64>>> = decs
        .iter()
        .map(|d| d.as_ref().map(|_| vec![0.0; n_out]))
        .collect();
    for (n, f) in forces.iter().enumerate() {
        let i = n as i64 - w_steps;
        let a = structure.step(*f, dt);
        if i < -d {
            continue;
        }
        let j = i - d;
        let at = (j >= 0 && j % ki == 0).then_some((j / ki) as usize);
        for ((dec, &w), o) in decs.iter_mut().zip(want).zip(out.iter_mut()) {
            if let (Some(dec), Some(o)) = (dec.as_mut(), o.as_mut()) {
                dec.push(a[w]);
                if let Some(m) = at.filter(|&m| m < n_out) {
                    o[m] = dec.output();
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mechanics run apart plus the modes give the signals of one run with the modes
    /// inside, within rounding, for the rig's own modes and for a moved first mode.
    #[test]
    fn the_structure_apart_adds_up_to_the_whole_run() {
        let rig = RigConfig::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/hit-sm-self.toml"
        )))
        .unwrap();
        let sim = super::super::rig_simulation(&rig).unwrap().clone();
        let sc = Scenario::constant(&[], 900.0, 0.3, 7);
        let mech = run_mechanics(&rig, &sim, &sc).unwrap();
        let mut moved = sim.clone();
        moved.structure.resonances[0].hz *= 1.7;
        moved.structure.resonances[0].damping = 0.05;
        for s in [&sim, &moved] {
            let whole = super::super::run_engine(&rig, s, &sc).unwrap();
            let apart = mech.with_resonances(&s.structure.resonances).unwrap();
            for (a, b) in whole.out.signals.iter().zip(&apart.out.signals) {
                let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(scale > 0.0);
                let worst = a
                    .iter()
                    .zip(b)
                    .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
                assert!(worst <= 1e-9 * scale, "{worst} of {scale}");
            }
        }
        // the modes matter: without them the signals differ
        let bare = mech.with_resonances(&[]).unwrap();
        let whole = super::super::run_engine(&rig, &sim, &sc).unwrap();
        let diff = whole.out.signals[0]
            .iter()
            .zip(&bare.out.signals[0])
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(diff > 0.0);
    }
}
