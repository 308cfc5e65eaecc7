//! The rig simulator: a flexible rotor on a linear drive-end bushing and a nonlinear
//! Hertzian ball bearing with localized defects, housings on springs, a high-frequency
//! structural path and sensor noise. `simulate(&RigConfig, &Scenario)` returns a
//! [`Recording`] laid out like the rig's channels (3-axis housing acceleration at the DAQ
//! rate, analog tacho), with labels in its metadata.
//!
//! Parts: [`rotor`] (beam FE + Guyan reduction + supports), [`bearing_contact`] (balls, cage,
//! Hertz contact), [`defects`] (slot geometry), [`structure`] (resonances; [`split`] runs it
//! apart from the mechanics, so calibration re-runs only it), [`profile`]
//! (speed), [`integrate`] (the stepper), [`decimate`] (anti-aliasing), [`sensor`] (noise,
//! electrical and shaft-order lines, a loose housing's [`landings`], units, tacho: the stage
//! after the mechanics, see [`run_engine`]), [`scenario`], [`plan`] and [`dataset`] (datasets;
//! [`dataset_pair`] simulates adapt's two datasets sharing their mechanics) and [`output`]
//! (MCAP/WAV); its
//! `[simulation]` rig-file section is [`crate::config::simulation`].

pub(crate) mod bearing_contact;
pub mod dataset;
pub mod dataset_pair;
pub(crate) mod decimate;
pub mod defects;
pub(crate) mod integrate;
pub(crate) mod landings;
pub(crate) mod linalg;
pub mod output;
pub mod plan;
pub mod profile;
pub mod rotor;
pub mod scenario;
pub mod sensor;
pub mod signature;
pub mod split;
pub mod structure;

pub use landings::peak as landing_peak;
pub use profile::SpeedProfile;
pub use scenario::{label_of, Overrides, Scenario};

use crate::bearing::{BearingGeometry, FaultOrders};
use crate::config::simulation::{SimulationConfig, SIGNALS};
use crate::config::{Acquisition, ChannelConfig, ChannelKind, RigConfig};
use crate::recording::Recording;
use crate::vocabulary::{AccelUnit, ChannelUnit};
use anyhow::{bail, Context, Result};
use bearing_contact::BallBearing;
use integrate::Engine;
use rand::rngs::StdRng;
use rand::SeedableRng;
use rotor::RotorModel;
use std::collections::BTreeMap;
use structure::Structure;

/// The rig's simulation section (or an error saying how to add one).
pub fn rig_simulation(rig: &RigConfig) -> Result<&SimulationConfig> {
    rig.simulation.as_ref().with_context(|| {
        format!("rig {:?} has no [simulation] section; add one (an empty `[simulation]` gives the thesis rig defaults)", rig.machine.id)
    })
}

/// Contact angle the simulator uses for this rig (degrees).
pub fn contact_angle_deg(bearing: &BearingGeometry, sim: &SimulationConfig) -> f64 {
    sim.bearing
        .contact_angle_deg
        .unwrap_or(bearing.contact_angle_deg)
}

/// The theoretical fault orders with the model's own contact angle (no slip).
pub fn model_fault_orders(rig: &RigConfig, sim: &SimulationConfig) -> FaultOrders {
    rig.bearing
        .with_contact_angle(contact_angle_deg(&rig.bearing, sim))
        .fault_orders()
}

/// Output sample rate for this rig.
pub fn sample_rate(acquisition: &Acquisition, sim: &SimulationConfig) -> f64 {
    sim.sample_rate_hz
        .or(acquisition.sample_rate_hz)
        .unwrap_or(10_000.0)
}

/// Which simulated signal feeds a rig channel (explicit map first, then the axis).
fn signal_for(sim: &SimulationConfig, name: &str, axis: &str) -> Option<usize> {
    let key = sim
        .channel_map
        .get(name)
        .map(String::as_str)
        .unwrap_or(axis);
    SIGNALS.iter().position(|s| *s == key)
}

/// The structural mode the rig's classifier channel sees most of (see
/// [`structure::dominant_mode`]), Hz: where the model puts the resonance that impacts
/// ring through, whether or not a simulation excites it.
pub fn dominant_resonance_hz(rig: &RigConfig, sim: &SimulationConfig) -> Option<f64> {
    dominant_resonance(rig, sim).map(|i| sim.structure.resonances[i].hz)
}

/// The index in `[[simulation.structure.resonances]]` of [`dominant_resonance_hz`]'s mode.
pub fn dominant_resonance(rig: &RigConfig, sim: &SimulationConfig) -> Option<usize> {
    let ch = rig.classifier_channel()?;
    let signal = SIGNALS[signal_for(sim, &ch.name, &ch.axis)?];
    structure::dominant_mode(&sim.structure.resonances, signal)
}

/// Factor from m/s^2 to a channel's unit (any spelling [`AccelUnit`] accepts).
pub fn unit_scale(unit: &ChannelUnit, channel: &str) -> Result<f64> {
    match unit.accel() {
        Some(u) => Ok(1.0 / u.factor_to_m_s2()),
        None => bail!(
            "channel {channel:?} has unit {:?}; the simulator writes acceleration in one of {}",
            unit.as_str(),
            AccelUnit::accepted()
        ),
    }
}

/// The first bending-mode frequencies (vertical, horizontal), Hz, and the mode tables by name.
pub type BendingModes = ([f64; 2], BTreeMap<&'static str, Vec<f64>>);

/// Linearised modal check: the first bending-mode frequencies (vertical, horizontal) of the
/// rig with the test bearing linearised at its static equilibrium, Hz.
pub fn bending_modes(rig: &RigConfig, sim: &SimulationConfig) -> Result<BendingModes> {
    let rotor = RotorModel::build(sim)?;
    let bearing = BallBearing::new(
        &rig.bearing,
        &sim.bearing,
        contact_angle_deg(&rig.bearing, sim),
        &sim.defect,
        Default::default(),
    );
    let (_, kb) = integrate::static_equilibrium(&rotor, &bearing, sim.bearing.radial_load_n)?;
    let fv = rotor.natural_frequencies(0, kb[0])?;
    let fh = rotor.natural_frequencies(1, kb[1])?;
    let mut all = BTreeMap::new();
    all.insert("vertical", fv.clone());
    all.insert("horizontal", fh.clone());
    Ok(([fv[0], fh[0]], all))
}

/// Simulate one scenario on a rig with its own `[simulation]` section.
pub fn simulate(rig: &RigConfig, scenario: &Scenario) -> Result<Recording> {
    let base = rig_simulation(rig)?;
    simulate_with(rig, base, scenario)
}

/// Simulate with an explicit simulation section (the scenario's overrides still apply).
pub fn simulate_with(
    rig: &RigConfig,
    base: &SimulationConfig,
    scenario: &Scenario,
) -> Result<Recording> {
    let run = run_engine(rig, base, scenario)?;
    sensor::finish(rig, &scenario.overrides.apply(base), scenario, &run)
}

/// The mechanical part of one simulation: the housing signals the rig's channels need and
/// the shaft angles, before the sensor stage ([`sensor::finish`]: noise, electrical and
/// shaft-order lines, units, quantisation, tacho). It depends only on
/// [`SimulationConfig::engine_part`], so a caller that varies sensor-stage keys alone (as
/// calibration does) can run it once and finish it many times.
#[derive(Debug, Clone)]
pub struct EngineRun {
    out: integrate::EngineOutput,
    /// Random state after the engine; the sensor stage continues from a copy of it.
    rng: StdRng,
    fs: f64,
    n_out: usize,
    alpha: f64,
    oversampling: usize,
}

/// Acceleration channels that map to a simulated signal, in rig order: (channel, signal
/// index, scale from m/s^2 to the channel's unit). `rig_id` names the rig in the error.
fn channel_signals<'a>(
    channels: &'a [ChannelConfig],
    rig_id: &str,
    sim: &SimulationConfig,
) -> Result<Vec<(&'a ChannelConfig, usize, f64)>> {
    let mut chans = Vec::new();
    for c in channels
        .iter()
        .filter(|c| c.kind == ChannelKind::Acceleration)
    {
        if let Some(sig) = signal_for(sim, &c.name, &c.axis) {
            chans.push((
                c,
                sig,
                unit_scale(&c.unit, &c.name)? / c.sensitivity.max(f64::MIN_POSITIVE),
            ));
        }
    }
    if chans.is_empty() {
        bail!(
            "rig {rig_id:?}: none of the acceleration channels maps to a simulated signal; set [simulation.channel_map] (signals: {SIGNALS:?})"
        );
    }
    Ok(chans)
}

/// Run the mechanical part of a scenario (validates the section and the scenario).
pub fn run_engine(
    rig: &RigConfig,
    base: &SimulationConfig,
    scenario: &Scenario,
) -> Result<EngineRun> {
    engine_with(rig, base, scenario, false)
}

/// [`run_engine`]; with `apart`, the structural path is left out and the housing forces
/// kept for it ([`split`]).
fn engine_with(
    rig: &RigConfig,
    base: &SimulationConfig,
    scenario: &Scenario,
    apart: bool,
) -> Result<EngineRun> {
    let sim = scenario.overrides.apply(base);
    sim.validate()?;
    if !(scenario.seconds > 0.0 && scenario.seconds <= 3600.0) {
        bail!(
            "scenario length {} s: must be in (0, 3600] s",
            scenario.seconds
        );
    }
    scenario.profile.validate(scenario.seconds)?;
    let fs = sample_rate(&rig.acquisition, &sim);
    let n_out = (scenario.seconds * fs).round() as usize;
    if n_out < 16 {
        bail!(
            "scenario of {} s at {fs} Hz gives fewer than 16 samples",
            scenario.seconds
        );
    }
    let alpha = contact_angle_deg(&rig.bearing, &sim);
    let geom: BearingGeometry = rig.bearing;

    let chans = channel_signals(&rig.channels, &rig.machine.id, &sim)?;
    let want: Vec<usize> = chans.iter().map(|c| c.1).collect();

    let rotor = RotorModel::build(&sim)?;
    let bearing = BallBearing::new(
        &geom,
        &sim.bearing,
        alpha,
        &sim.defect,
        scenario.defect_set(),
    );
    let k = sim.oversampling as usize;
    let dt = 1.0 / (fs * k as f64);
    let modes = if apart {
        &[][..]
    } else {
        &sim.structure.resonances[..]
    };
    let structure = Structure::new(modes, dt);
    let mut engine = Engine {
        rotor,
        bearing,
        structure,
        profile: match (&scenario.profile, &sim.speed_fluctuation) {
            (SpeedProfile::Constant { rpm }, Some(f)) => SpeedProfile::Sine {
                rpm: *rpm,
                amplitude_rpm: f.fraction * rpm,
                period_s: f.period_s,
            },
            (p, _) => p.clone(),
        },
        fs,
        oversampling: k,
        warmup_s: sim.warmup_s,
        radial_load_n: sim.bearing.radial_load_n,
        record_forces: apart,
    };
    let mut rng = StdRng::seed_from_u64(scenario.seed);
    let out = engine.run(n_out, &want, &mut rng)?;
    Ok(EngineRun {
        out,
        rng,
        fs,
        n_out,
        alpha,
        oversampling: k,
    })
}

/// Fraction of the phase interval [pa, pb] (in pulse periods, increasing) spent in the high
/// part [m, m + duty) of each period.
fn high_fraction(pa: f64, pb: f64, duty: f64) -> f64 {
    let span = pb - pa;
    if span <= 0.0 {
        let f = pa - pa.floor();
        return if f < duty { 1.0 } else { 0.0 };
    }
    let mut high = 0.0;
    let mut m = pa.floor();
    while m <= pb {
        let lo = pa.max(m);
        let hi = pb.min(m + duty);
        if hi > lo {
            high += hi - lo;
        }
        m += 1.0;
    }
    high / span
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tacho_fraction() {
        assert_eq!(high_fraction(0.0, 0.05, 0.1), 1.0);
        assert!((high_fraction(0.05, 0.15, 0.1) - 0.5).abs() < 1e-12);
        assert_eq!(high_fraction(0.3, 0.4, 0.1), 0.0);
        assert!((high_fraction(0.95, 1.05, 0.1) - 0.5).abs() < 1e-12);
    }
}
