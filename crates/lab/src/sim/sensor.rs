//! The sensor stage of a simulation: from the engine's housing signals and shaft angles
//! ([`super::EngineRun`]) to a [`Recording`]: white sensor noise, electrical line
//! interference, shaft-order and half-order lines, a loose housing's landings, units and
//! quantisation per channel, the
//! analog tacho and the metadata (labels, the simulation section used).

use super::{channel_signals, high_fraction, model_fault_orders, EngineRun, Scenario};
use crate::config::simulation::{SimulationConfig, SIGNALS};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use crate::vocabulary::Condition;
use anyhow::Result;
use rand::Rng;
use rand_distr::StandardNormal;
use std::collections::BTreeMap;

/// Electrical line interference: harmonics of the line frequency with random phases, as
/// (amplitude, radians per sample, phase).
fn line_interference(sim: &SimulationConfig, fs: f64, rng: &mut impl Rng) -> Vec<(f64, f64, f64)> {
    sim.structure
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
        .collect()
}

/// Finish an engine run with the full simulation section `sim` (the scenario's overrides
/// applied); its engine part must be the one the run was made with.
pub fn finish(
    rig: &RigConfig,
    sim: &SimulationConfig,
    scenario: &Scenario,
    run: &EngineRun,
) -> Result<Recording> {
    let (out, fs, n_out, alpha, k) = (&run.out, run.fs, run.n_out, run.alpha, run.oversampling);
    let mut rng = run.rng.clone();
    let chans = channel_signals(&rig.channels, &rig.machine.id, sim)?;
    // Sensor noise, units.
    let mut channels = Vec::with_capacity(chans.len());
    let adc = sim.structure.adc_resolution_m_s2;
    let lines = line_interference(sim, fs, &mut rng);
    // shaft-order lines: per sample, the shaft angle and speed from the sample's boundaries;
    // the speed law (rpm / ref)^exponent is one gain per sample for every order, and orders
    // without amplitude or above Nyquist at that sample's speed are skipped (no aliases)
    let shaft_lines = sim.shaft_lines.as_ref().map(|l| {
        let b = &out.boundary_angles;
        let shaft_hz: Vec<f64> = (0..n_out)
            .map(|i| (b[i + 1] - b[i]) * fs / std::f64::consts::TAU)
            .collect();
        let gain: Vec<f64> = shaft_hz.iter().map(|&f| l.speed_gain(60.0 * f)).collect();
        let orders: Vec<(f64, f64)> = l
            .amplitudes_m_s2
            .iter()
            .enumerate()
            .filter(|(_, &a)| a != 0.0)
            .map(|(k, &a)| ((k + 1) as f64, a))
            .collect();
        (l.phase_deg.to_radians(), shaft_hz, gain, orders)
    });
    // half-order lines (0.5x, 1.5x, ...) the same way; their angle is half orders of the shaft
    // angle, so they repeat every two revolutions
    let half_lines = sim.subharmonics.as_ref().map(|h| {
        let b = &out.boundary_angles;
        let gain: Vec<f64> = (0..n_out)
            .map(|i| h.speed_gain(60.0 * (b[i + 1] - b[i]) * fs / std::f64::consts::TAU))
            .collect();
        let orders: Vec<(f64, f64)> = h.lines().into_iter().filter(|(_, a)| *a != 0.0).collect();
        (h.phase_deg.to_radians(), gain, orders)
    });
    let half_line = |vertical: bool, i: usize| -> f64 {
        let Some((phase, gain, orders)) = &half_lines else {
            return 0.0;
        };
        let b = &out.boundary_angles;
        let shaft_hz = (b[i + 1] - b[i]) * fs / std::f64::consts::TAU;
        let th = 0.5 * (b[i] + b[i + 1]);
        let nyquist = 0.5 * fs;
        orders
            .iter()
            .take_while(|(o, _)| o * shaft_hz < nyquist)
            .map(|(o, a)| {
                let x = o * (th + 2.0 * phase);
                a * gain[i] * if vertical { x.cos() } else { x.sin() }
            })
            .sum()
    };
    let shaft_line = |vertical: bool, i: usize| -> f64 {
        let Some((phase, shaft_hz, gain, orders)) = &shaft_lines else {
            return 0.0;
        };
        let th = 0.5 * (out.boundary_angles[i] + out.boundary_angles[i + 1]) + phase;
        let nyquist = 0.5 * fs;
        orders
            .iter()
            .take_while(|(k, _)| k * shaft_hz[i] < nyquist)
            .map(|(k, a)| {
                let x = k * th;
                a * gain[i] * if vertical { x.cos() } else { x.sin() }
            })
            .sum()
    };
    let landings = super::landings::Radial::new(sim, &out.boundary_angles, fs);
    for ((c, signal, scale), sig) in chans.iter().zip(&out.signals) {
        // shaft and half-order lines act on the radial housing signals: cos on vertical, sin
        // on horizontal
        let radial = match SIGNALS[*signal] {
            "vertical" | "support_vertical" => Some(true),
            "horizontal" | "support_horizontal" => Some(false),
            _ => None,
        };
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
                let y = (a
                    + hum
                    + radial.map_or(0.0, |v| shaft_line(v, i))
                    + radial.map_or(0.0, |v| half_line(v, i))
                    + radial.map_or(0.0, |v| landings.at(v, i))
                    + sim.structure.noise_rms_m_s2 * z)
                    * scale;
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
            unit: c.unit.to_string(),
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
                unit: tc.unit.to_string(),
            })
        }
        // No tacho on the rig: the recording still carries the simulator's own speed, as the
        // exact time of every revolution, for analyses that must not guess it (training
        // data in estimate mode, see analysis::recording).
        None => Some(Tacho::Edges {
            times_s: revolution_times(&out.boundary_angles, fs),
        }),
    };

    let mean_rpm = scenario.profile.mean_rpm(scenario.seconds);
    let orders = model_fault_orders(rig, sim);
    let mut md = BTreeMap::new();
    md.insert("label".to_string(), scenario.label().to_string());
    let faults: Vec<&str> = scenario.faults.iter().map(|f| f.as_str()).collect();
    md.insert(
        "faults".into(),
        if faults.is_empty() {
            Condition::Healthy.as_str().into()
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
        nominal_rpm: None,
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

/// The times (s, from the first sample) at which the shaft angle passes a whole revolution,
/// linearly interpolated between output-sample boundaries (boundary n is at (n - 1/2) / fs).
fn revolution_times(boundary_angles: &[f64], fs: f64) -> Vec<f64> {
    let tau = std::f64::consts::TAU;
    let mut times = Vec::new();
    for (n, w) in boundary_angles.windows(2).enumerate() {
        let (a, b) = (w[0] / tau, w[1] / tau);
        let mut k = a.floor() + 1.0;
        while k <= b && b > a {
            let t = (n as f64 - 0.5 + (k - a) / (b - a)) / fs;
            if t >= 0.0 {
                times.push(t);
            }
            k += 1.0;
        }
    }
    times
}
