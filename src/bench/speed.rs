//! `rigmon bench speed`: what reading the shaft speed from the vibration costs the daemon.
//! Two machines: the LUT rig's three accelerometers at 10 kHz (250-2000 rpm) and one
//! accelerometer at 51.2 kHz (the HIT-SM rig, 500-1500 rpm). Each runs a synthetic recording
//! (a slow speed ramp with shaft harmonics, bearing impacts and noise) through the one
//! analysis stage twice in the same process: with `[speed] estimate` (the streaming tracker)
//! and, as the baseline, with the true speed given (everything else the same). The ratio is
//! the cost of the tracker on top of the features, and the tracker's own CPU time per hop is
//! set against the hop, the daemon's budget per window. The speeds read are checked against
//! the truth (median and largest error), so a fast tracker that reads wrong does not pass.

use super::{abs, machine_line, thread_cpu_s, BenchOptions};
use crate::analysis::{extract_recording, extract_with_speed};
use crate::config::RigConfig;
use crate::dsp::speed_config::SpeedConfig;
use crate::dsp::SpeedTrack;
use crate::recording::{Channel, Provenance, Recording};
use anyhow::{bail, Result};
use std::path::Path;
use std::time::Instant;

/// One machine to measure.
struct Machine {
    name: &'static str,
    rig: &'static str,
    sample_rate: f64,
    min_rpm: f64,
    max_rpm: f64,
    /// The synthetic ramp, rpm.
    from_rpm: f64,
    to_rpm: f64,
}

const MACHINES: [Machine; 2] = [
    Machine {
        name: "3 ch x 10 kHz (LUT rig)",
        rig: "config/lut-rig.toml",
        sample_rate: 10_000.0,
        min_rpm: 250.0,
        max_rpm: 2000.0,
        from_rpm: 550.0,
        to_rpm: 650.0,
    },
    Machine {
        name: "1 ch x 51.2 kHz (HIT-SM rig)",
        rig: "config/hit-sm-self.toml",
        sample_rate: 51_200.0,
        min_rpm: 500.0,
        max_rpm: 1500.0,
        from_rpm: 850.0,
        to_rpm: 950.0,
    },
];

/// The synthetic recording: per channel, shaft harmonics 1x-5x (falling as 1/k), impacts at
/// 3.6 orders ringing at 2.5 kHz, and white noise; the true speed track beside it.
fn synthetic(m: &Machine, rig: &RigConfig, seconds: f64) -> Result<(Recording, SpeedTrack)> {
    let fs = m.sample_rate;
    let n = (seconds * fs).round() as usize;
    let (f0, f1) = (m.from_rpm / 60.0, m.to_rpm / 60.0);
    let angle = |t: f64| f0 * t + 0.5 * (f1 - f0) / seconds * t * t;
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut noise = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let (w, zeta) = (std::f64::consts::TAU * 2500.0, 0.05);
    let channels = rig
        .acceleration_channels()
        .enumerate()
        .map(|(k, c)| {
            let gain = 1.0 + 0.2 * k as f64;
            let mut last_impact = f64::NEG_INFINITY;
            let samples = (0..n)
                .map(|i| {
                    let t = i as f64 / fs;
                    let th = std::f64::consts::TAU * angle(t);
                    let lines: f64 = (1..=5).map(|h| (h as f64 * th).sin() / h as f64).sum();
                    if (angle(t) * 3.6).floor() > (angle(t - 1.0 / fs) * 3.6).floor() {
                        last_impact = t;
                    }
                    let dt = t - last_impact;
                    let ring = (-zeta * w * dt).exp() * (w * dt).sin();
                    (gain * (0.2 * lines + ring) + 0.3 * noise()) as f32
                })
                .collect();
            Channel {
                name: c.name.clone(),
                axis: c.axis.clone(),
                unit: c.unit.to_string(),
                samples,
            }
        })
        .collect();
    let edges: Vec<f64> = (1..)
        .map(|r| {
            // time of revolution r on the ramp
            let a = (f1 - f0) / seconds;
            (-f0 + (f0 * f0 + 2.0 * a * r as f64).sqrt()) / a
        })
        .take_while(|&t| t < seconds)
        .collect();
    let rec = Recording {
        sample_rate: fs,
        start_time_ns: 0,
        channels,
        tacho: None,
        rpm: None,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: format!("(bench speed: {})", m.name),
            format: "synthetic".into(),
            notes: Vec::new(),
        },
        metadata: Default::default(),
    };
    Ok((rec, SpeedTrack::from_edges(&edges, 1, "truth")?))
}

/// What one machine measured.
struct Measured {
    signal_s: f64,
    hops: usize,
    estimate_cpu_s: f64,
    given_cpu_s: f64,
    median_err: f64,
    max_err: f64,
}

fn measure(m: &Machine, seconds: f64) -> Result<Measured> {
    let mut rig = RigConfig::load(&abs(Path::new(m.rig))?)?;
    rig.acquisition.sample_rate_hz = Some(m.sample_rate);
    let (rec, truth) = synthetic(m, &rig, seconds)?;
    rig.speed = SpeedConfig::Estimate {
        min_rpm: m.min_rpm,
        max_rpm: m.max_rpm,
        check_within_percent: 10.0,
    };
    let cpu = thread_cpu_s();
    let t0 = Instant::now();
    let tracked = extract_recording(&rec, &rig)?;
    let estimate_cpu_s = thread_cpu_s() - cpu;
    let wall_estimate = t0.elapsed().as_secs_f64();
    let cpu = thread_cpu_s();
    let given = extract_with_speed(&rec, &rig, &truth)?;
    let given_cpu_s = thread_cpu_s() - cpu;
    if tracked.len() != given.len() || tracked.is_empty() {
        bail!(
            "{}: {} windows with the tracker, {} with the true speed",
            m.name,
            tracked.len(),
            given.len()
        );
    }
    // once the tracker's history (20 revolutions at the lowest speed) is full
    let full = 20.0 * 60.0 / m.min_rpm;
    let mut errs: Vec<f64> = tracked
        .iter()
        .zip(&given)
        .filter(|(a, _)| a.t_end >= full)
        .map(|(a, b)| (a.rpm / b.rpm - 1.0).abs())
        .collect();
    if errs.is_empty() {
        bail!(
            "{}: no window after the tracker's history ({full:.1} s); use more --seconds",
            m.name
        );
    }
    errs.sort_by(f64::total_cmp);
    tracing::debug!("{}: {wall_estimate:.2} s wall with the tracker", m.name);
    Ok(Measured {
        signal_s: rec.duration_s(),
        hops: tracked.len(),
        estimate_cpu_s,
        given_cpu_s,
        median_err: errs[errs.len() / 2],
        max_err: errs[errs.len() - 1],
    })
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let seconds = opts.seconds.max(10.0);
    // one thread: the analysis runs on the calling thread, timed by its own CPU clock
    let mut rows = Vec::new();
    for m in &MACHINES {
        let r = measure(m, seconds)?;
        let tracker_ms_per_hop = 1e3 * (r.estimate_cpu_s - r.given_cpu_s) / r.hops as f64;
        let hop_ms = 1e3 * (r.signal_s - 1.0) / (r.hops.max(2) - 1) as f64;
        rows.push(serde_json::json!({
            "machine": m.name,
            "signal_s": r.signal_s,
            "windows": r.hops,
            "cpu_s_with_tracker": r.estimate_cpu_s,
            "cpu_s_true_speed": r.given_cpu_s,
            "ratio": r.estimate_cpu_s / r.given_cpu_s,
            "tracker_ms_per_hop": tracker_ms_per_hop,
            "hop_ms": hop_ms,
            "tracker_share_of_hop": tracker_ms_per_hop / hop_ms,
            "real_time_factor": r.signal_s / r.estimate_cpu_s,
            "speed_error_median_pct": 100.0 * r.median_err,
            "speed_error_max_pct": 100.0 * r.max_err,
        }));
    }
    if opts.json {
        println!(
            "{}",
            serde_json::json!({ "machine": machine_line(), "cases": rows })
        );
        return Ok(());
    }
    println!("bench speed: reading the shaft speed from the vibration (one thread per machine)");
    println!("{}", machine_line());
    for r in &rows {
        println!(
            "{}: {:.0} s of signal, {} windows; CPU {:.2} s with the tracker vs {:.2} s with the true speed (x{:.2}); tracker {:.2} ms per {:.0} ms hop ({:.1} % of the budget); {:.0}x real time; speed error (windows after the history) median {:.3} %, max {:.3} %",
            r["machine"].as_str().unwrap_or(""),
            r["signal_s"].as_f64().unwrap_or(0.0),
            r["windows"],
            r["cpu_s_with_tracker"].as_f64().unwrap_or(0.0),
            r["cpu_s_true_speed"].as_f64().unwrap_or(0.0),
            r["ratio"].as_f64().unwrap_or(0.0),
            r["tracker_ms_per_hop"].as_f64().unwrap_or(0.0),
            r["hop_ms"].as_f64().unwrap_or(0.0),
            100.0 * r["tracker_share_of_hop"].as_f64().unwrap_or(0.0),
            r["real_time_factor"].as_f64().unwrap_or(0.0),
            r["speed_error_median_pct"].as_f64().unwrap_or(0.0),
            r["speed_error_max_pct"].as_f64().unwrap_or(0.0),
        );
    }
    Ok(())
}
