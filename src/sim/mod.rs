//! The rig simulator: a flexible rotor on a linear drive-end bushing and a nonlinear
//! Hertzian ball bearing with localized defects, housings on springs, a high-frequency
//! structural path and sensor noise. `simulate(&RigConfig, &Scenario)` returns a
//! [`Recording`] laid out like the rig's channels (3-axis housing acceleration at the DAQ
//! rate, analog tacho), with labels in its metadata.
//!
//! Parts: [`rotor`] (beam FE + Guyan reduction + supports), [`bearing_contact`] (balls, cage,
//! Hertz contact), [`defects`] (slot geometry), [`structure`] (resonances), [`profile`]
//! (speed), [`integrate`] (the stepper), [`decimate`] (anti-aliasing), [`scenario`], [`plan`]
//! (datasets) and [`output`] (MCAP/WAV).

pub mod bearing_contact;
pub mod dataset;
pub mod decimate;
pub mod defects;
pub mod integrate;
pub mod linalg;
pub mod output;
pub mod plan;
pub mod profile;
pub mod rotor;
pub mod scenario;
pub mod signature;
pub mod structure;

pub use profile::SpeedProfile;
pub use scenario::{label_of, Fault, Overrides, Scenario};

use crate::bearing::{BearingGeometry, FaultOrders};
use crate::config::simulation::{SimulationConfig, SIGNALS};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Context, Result};
use bearing_contact::BallBearing;
use integrate::Engine;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rotor::RotorModel;
use std::collections::BTreeMap;
use structure::Structure;

/// Standard gravity, for channels in g.
pub const G0: f64 = 9.80665;

/// The rig's simulation section (or an error saying how to add one).
pub fn rig_simulation(rig: &RigConfig) -> Result<&SimulationConfig> {
    rig.simulation.as_ref().with_context(|| {
        format!("rig {:?} has no [simulation] section; add one (an empty `[simulation]` gives the thesis rig defaults)", rig.machine.id)
    })
}

/// Contact angle the simulator uses for this rig (degrees).
pub fn contact_angle_deg(rig: &RigConfig, sim: &SimulationConfig) -> f64 {
    sim.bearing
        .contact_angle_deg
        .unwrap_or(rig.bearing.contact_angle_deg)
}

/// The theoretical fault orders with the model's own contact angle (no slip).
pub fn model_fault_orders(rig: &RigConfig, sim: &SimulationConfig) -> FaultOrders {
    rig.bearing
        .with_contact_angle(contact_angle_deg(rig, sim))
        .fault_orders()
}

/// Output sample rate for this rig.
pub fn sample_rate(rig: &RigConfig, sim: &SimulationConfig) -> f64 {
    sim.sample_rate_hz
        .or(rig.acquisition.sample_rate_hz)
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

fn unit_scale(unit: &str, channel: &str) -> Result<f64> {
    match unit.trim() {
        "m/s^2" | "m/s2" | "m/s²" => Ok(1.0),
        "g" => Ok(1.0 / G0),
        "mm/s^2" => Ok(1000.0),
        other => {
            bail!("channel {channel:?} has unit {other:?}; the simulator writes m/s^2, mm/s^2 or g")
        }
    }
}

/// Linearised modal check: the first bending-mode frequencies (vertical, horizontal) of the
/// rig with the test bearing linearised at its static equilibrium, Hz.
pub fn bending_modes(
    rig: &RigConfig,
    sim: &SimulationConfig,
) -> Result<([f64; 2], BTreeMap<&'static str, Vec<f64>>)> {
    let rotor = RotorModel::build(sim)?;
    let bearing = BallBearing::new(
        &rig.bearing,
        &sim.bearing,
        contact_angle_deg(rig, sim),
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
    let sim = scenario.overrides.apply(base);
    sim.validate()?;
    if !(scenario.seconds > 0.0 && scenario.seconds <= 3600.0) {
        bail!(
            "scenario length {} s: must be in (0, 3600] s",
            scenario.seconds
        );
    }
    scenario.profile.validate(scenario.seconds)?;
    let fs = sample_rate(rig, &sim);
    let n_out = (scenario.seconds * fs).round() as usize;
    if n_out < 16 {
        bail!(
            "scenario of {} s at {fs} Hz gives fewer than 16 samples",
            scenario.seconds
        );
    }
    let alpha = contact_angle_deg(rig, &sim);
    let geom: BearingGeometry = rig.bearing;

    // Channels: acceleration channels that map to a simulated signal, in rig order.
    let mut chans = Vec::new();
    for c in rig
        .channels
        .iter()
        .filter(|c| c.kind == ChannelKind::Acceleration)
    {
        if let Some(sig) = signal_for(&sim, &c.name, &c.axis) {
            chans.push((
                c,
                sig,
                unit_scale(&c.unit, &c.name)? / c.sensitivity.max(f64::MIN_POSITIVE),
            ));
        }
    }
    if chans.is_empty() {
        bail!(
            "rig {:?}: none of the acceleration channels maps to a simulated signal; set [simulation.channel_map] (signals: {SIGNALS:?})",
            rig.machine.id
        );
    }
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
    let structure = Structure::new(&sim.structure.resonances, dt);
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
    };
    let mut rng = StdRng::seed_from_u64(scenario.seed);
    let out = engine.run(n_out, &want, &mut rng)?;

    // Sensor noise, units.
    let mut channels = Vec::with_capacity(chans.len());
    let adc = sim.structure.adc_resolution_m_s2;
    // electrical line interference: harmonics of the line frequency, random phases
    let lines: Vec<(f64, f64, f64)> = sim
        .structure
        .line_amplitudes_m_s2
        .iter()
        .enumerate()
        .map(|(h, &a)| {
            (
                a,
                std::f64::consts::TAU * sim.structure.line_hz * (h + 1) as f64 / fs,
                rng.random_range(0.0..std::f64::consts::TAU),
            )
        })
        .collect();
    for ((c, _, scale), sig) in chans.iter().zip(out.signals) {
        // quantisation step in the channel's unit, a power of two (exact in f32)
        let lsb = if adc > 0.0 {
            2f64.powf((adc * scale).log2().round())
        } else {
            0.0
        };
        let samples: Vec<f32> = sig
            .iter()
            .enumerate()
            .map(|(i, &a)| {
                let z: f64 = rng.sample(StandardNormal);
                let hum: f64 = lines
                    .iter()
                    .map(|&(amp, w, ph)| amp * (w * i as f64 + ph).sin())
                    .sum();
                let y = (a + hum + sim.structure.noise_rms_m_s2 * z) * scale;
                (if lsb > 0.0 {
                    (y / lsb).round() * lsb
                } else {
                    y
                }) as f32
            })
            .collect();
        channels.push(Channel {
            name: c.name.clone(),
            axis: c.axis.clone(),
            unit: c.unit.clone(),
            samples,
        });
    }

    // Analog tacho if the rig has a tacho channel.
    let tacho = match rig.channels.iter().find(|c| c.kind == ChannelKind::Tacho) {
        Some(tc) => {
            let ppr = rig.pulses_per_rev().max(1) as f64;
            let duty = sim.tacho.duty;
            let samples = (0..n_out)
                .map(|i| {
                    let pa = out.boundary_angles[i] * ppr / std::f64::consts::TAU;
                    let pb = out.boundary_angles[i + 1] * ppr / std::f64::consts::TAU;
                    let frac = high_fraction(pa, pb, duty);
                    let z: f64 = rng.sample(StandardNormal);
                    let y = (sim.tacho.high_v * frac + sim.tacho.noise_v * z)
                        / tc.sensitivity.max(f64::MIN_POSITIVE);
                    // a 16-bit tacho input over +-8 V: 2^-12 V steps
                    ((y * 4096.0).round() / 4096.0) as f32
                })
                .collect();
            Some(Tacho::Analog {
                samples,
                unit: tc.unit.clone(),
            })
        }
        None => None,
    };

    let mean_rpm = scenario.profile.mean_rpm(scenario.seconds);
    let orders = model_fault_orders(rig, &sim);
    let mut md = BTreeMap::new();
    md.insert("label".to_string(), scenario.label().to_string());
    let faults: Vec<&str> = scenario.faults.iter().map(Fault::label).collect();
    md.insert(
        "faults".into(),
        if faults.is_empty() {
            "healthy".into()
        } else {
            faults.join(",")
        },
    );
    md.insert("rpm".into(), format!("{mean_rpm:.3}"));
    md.insert("speed_profile".into(), scenario.profile.describe());
    md.insert("seed".into(), scenario.seed.to_string());
    md.insert("seconds".into(), format!("{}", scenario.seconds));
    md.insert("rig".into(), rig.machine.id.clone());
    md.insert(
        "generator".into(),
        format!("rigmon-sim {}", env!("CARGO_PKG_VERSION")),
    );
    md.insert("contact_angle_deg".into(), format!("{alpha}"));
    md.insert("slip".into(), format!("{}", sim.bearing.slip));
    md.insert("slip_jitter".into(), format!("{}", sim.bearing.slip_jitter));
    md.insert("bpfo_order".into(), format!("{:.5}", orders.bpfo));
    md.insert("bpfi_order".into(), format!("{:.5}", orders.bpfi));
    md.insert("ftf_order".into(), format!("{:.5}", orders.ftf));
    md.insert("bsf_order".into(), format!("{:.5}", orders.bsf));
    if !scenario.faults.is_empty() {
        md.insert("defect_width_mm".into(), format!("{}", sim.defect.width_mm));
        md.insert(
            "defect_length_mm".into(),
            format!("{}", sim.defect.length_mm),
        );
        md.insert("defect_depth_mm".into(), format!("{}", sim.defect.depth_mm));
        md.insert(
            "defect_shape".into(),
            format!("{:?}", sim.defect.shape).to_lowercase(),
        );
    }
    md.insert(
        "noise_rms_m_s2".into(),
        format!("{}", sim.structure.noise_rms_m_s2),
    );
    if let Some(r) = sim.structure.resonances.first() {
        md.insert("resonance_hz".into(), format!("{}", r.hz));
    }
    for (k, v) in scenario.overrides.to_metadata() {
        md.insert(format!("override.{k}"), v);
    }
    for (k, v) in &scenario.metadata {
        md.insert(k.clone(), v.clone());
    }
    md.insert(
        "simulation".into(),
        toml::to_string(&sim).unwrap_or_default(),
    );

    Ok(Recording {
        sample_rate: fs,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: Some(mean_rpm),
        provenance: Provenance {
            source_path: String::new(),
            format: "simulated".into(),
            notes: vec![format!(
                "rigmon simulator: rig {}, {} internal steps per sample, max {} balls loaded, max journal excursion {:.2} um",
                rig.machine.id,
                k,
                out.max_loaded,
                out.max_excursion * 1e6
            )],
        },
        metadata: md,
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
