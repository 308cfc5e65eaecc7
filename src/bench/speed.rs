//! `rigmon bench speed`: what reading the shaft speed from the vibration costs the daemon.
//! Two machines: the LUT rig's three accelerometers at 10 kHz (250-2000 rpm) and one
//! accelerometer at 51.2 kHz (the HIT-SM rig, 500-1500 rpm). Each runs a synthetic recording
//! (a slow speed ramp with shaft harmonics, bearing impacts and noise) through the one
//! analysis stage twice in the same process: with `[speed] estimate` (the streaming tracker)
//! and, as the baseline, with the true speed given (everything else the same). The ratio is
//! the cost of the tracker on top of the features, and the tracker's own CPU time per hop is
//! set against the hop, the daemon's budget per window. The speeds read are checked against
//! the truth (median and largest error), so a fast tracker that reads wrong does not pass.
//!
//! Then the joint reading of issue 34 ([`joint_cases`]): the streaming tracker alone on the
//! seed rig's cases built here from simple physics (a weak 1x at 588 rpm, a clean 1x at
//! 1188 rpm, a fluctuating speed, an outer race whose BPFO comb outshines the shaft), read
//! jointly and as before issue 34 in the same run: the p95 speed error of each and the CPU
//! ratio of the two; beside them the shipped reading with the harmonic sum's grid scanned
//! point by point (the search before issue 37 item 4: the same speeds, the CPU ratio), and
//! with the phase reading ([`crate::dsp::speed_tracker::JointParts::phase`]) switched.

use super::{abs, machine_line, thread_cpu_s, BenchOptions};
use crate::analysis::{extract_recording, extract_with_speed};
use crate::bearing::BearingGeometry;
use crate::config::RigConfig;
use crate::dsp::fault_family::FamilySettings;
use crate::dsp::speed_config::SpeedConfig;
use crate::dsp::speed_tracker::{JointParts, SpeedTracker, TrackerSettings};
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
    Ok((
        rec,
        SpeedTrack::from_edges(&edges, 1, crate::vocabulary::SpeedSourceKind::Simulator)?,
    ))
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
    let joint = joint_cases(seconds)?;
    if opts.json {
        println!(
            "{}",
            serde_json::json!({ "machine": machine_line(), "cases": rows, "joint": joint })
        );
        return Ok(());
    }
    print_joint(&joint);
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

/// One case of the joint reading: a name, the speed law (Hz at t), 1x and 2x amplitudes and
/// the peak response of outer-race impacts (0: healthy), against unit noise.
type JointCase = (&'static str, fn(f64) -> f64, (f64, f64), f64);

const JOINT: [JointCase; 5] = [
    ("weak 1x, 588 rpm", |_| 9.8, (0.11, 0.041), 0.0),
    ("clean 1x, 1188 rpm", |_| 19.8, (0.44, 0.0), 0.0),
    (
        "588 rpm +-2 % at 0.3 Hz",
        |t| 9.8 * (1.0 + 0.02 * (std::f64::consts::TAU * 0.3 * t).sin()),
        (0.11, 0.041),
        0.0,
    ),
    (
        "outer race, BPFO comb, 588 rpm",
        |_| 9.8,
        (0.11, 0.041),
        6.0,
    ),
    (
        "1188 rpm +-2 % at 0.3 Hz",
        |t| 19.8 * (1.0 + 0.02 * (std::f64::consts::TAU * 0.3 * t).sin()),
        (0.44, 0.0),
        0.0,
    ),
];

/// Independent draws of every joint case (noise, impact timing): one draw hid a reading
/// of the outer race at 4.6 times its speed that two draws in five showed.
const DRAWS: u64 = 5;
/// Seconds of signal per draw at least (the history alone is 4 s).
const JOINT_MIN_S: f64 = 20.0;

/// `seconds` of one accelerometer axis at 10 kHz: the case's shaft lines, unit white noise,
/// and impacts at the LUT bearing's BPFO (1 % jitter) through a 3 kHz and a 400 Hz mode.
fn joint_signal(c: &JointCase, fs: f64, seconds: f64, bpfo: f64, draw: u64) -> Vec<f32> {
    use std::f64::consts::TAU;
    let mut seed = 0x9e37_79b9_7f4a_7c15u64 ^ draw.wrapping_mul(0xd1b5_4a32_d192_ed03);
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mode = |hz: f64, z: f64| {
        let r = (-z * TAU * hz / fs).exp();
        let th = TAU * hz / fs;
        (2.0 * r * th.cos(), -r * r, th.sin())
    };
    let modes = [mode(3_000.0, 0.05), mode(400.0, 0.1)];
    let mut y = [[0.0f64; 2]; 2];
    let (mut theta, mut phase, mut next) = (0.0, 0.0, 1.0);
    (0..(fs * seconds) as usize)
        .map(|i| {
            let f = (c.1)(i as f64 / fs);
            theta += f / fs;
            phase += bpfo * f / fs;
            let g = (-2.0 * uniform().ln()).sqrt() * (TAU * uniform()).cos();
            let mut kick = 0.0;
            if c.3 > 0.0 && phase >= next {
                next += 1.0 + 0.01 * (uniform() - 0.5) * 3.46;
                kick = c.3;
            }
            let mut v = g + c.2 .0 * (TAU * theta).sin() + c.2 .1 * (TAU * 2.0 * theta + 1.0).sin();
            for (k, &(a1, a2, b)) in modes.iter().enumerate() {
                let out = a1 * y[k][0] + a2 * y[k][1] + b * kick;
                y[k] = [out, y[k][0]];
                v += if k == 0 { out } else { 0.5 * out };
            }
            v as f32
        })
        .collect()
}

/// How a joint case is read: the parts of the reading, and whether the harmonic sum's grid
/// is searched point by point (the search before issue 37 item 4) or bounded (the default).
#[derive(Clone, Copy)]
struct Reading {
    parts: JointParts,
    exhaustive: bool,
}

/// Every window's relative error (windows after the history, each window's mean over its
/// last second against the truth's) and tracker CPU seconds, read as `how` says.
fn joint_run(c: &JointCase, x: &[f32], fs: f64, how: Reading) -> Result<(Vec<f64>, f64)> {
    let orders = BearingGeometry {
        balls: 11,
        ball_diameter_mm: 7.94,
        pitch_diameter_mm: 48.0,
        contact_angle_deg: 0.0,
    }
    .fault_orders();
    let settings = TrackerSettings {
        min_rpm: 300.0,
        max_rpm: 3600.0,
        hint: None,
        families: Some(FamilySettings {
            orders,
            band_top_hz: 4_000.0,
        }),
    };
    let mut tr = SpeedTracker::new(settings, fs)?;
    tr.set_joint_parts(how.parts);
    tr.set_exhaustive(how.exhaustive);
    let hop = (fs / 2.0) as usize;
    let mut errs = Vec::new();
    let cpu = thread_cpu_s();
    for (k, chunk) in x.chunks(hop).enumerate() {
        tr.push((k * hop) as u64, chunk);
        let t = ((k + 1) * hop) as f64 / fs;
        if let (Ok(e), true) = (tr.estimate(), t >= tr.history_s()) {
            let truth = (0..100)
                .map(|j| (c.1)(t - 1.0 + j as f64 / 100.0))
                .sum::<f64>()
                * 0.6;
            errs.push((e.track.mean_rpm(t - 1.0, t) / truth - 1.0).abs());
        }
    }
    let cpu = thread_cpu_s() - cpu;
    if errs.is_empty() {
        bail!("{}: no window after the tracker's history", c.0);
    }
    Ok((errs, cpu))
}

/// The 95th percentile of `errs` (not empty).
fn p95(mut errs: Vec<f64>) -> f64 {
    errs.sort_by(f64::total_cmp);
    let i = ((errs.len() as f64 * 0.95).ceil() as usize).clamp(1, errs.len()) - 1;
    errs[i]
}

/// One reading of a case over every draw: the p95 of all windows together, the worst
/// draw's own p95, the windows and the tracker CPU seconds.
struct Pooled {
    p95: f64,
    worst_draw_p95: f64,
    windows: usize,
    cpu: f64,
}

fn pooled(c: &JointCase, draws: &[Vec<f32>], fs: f64, how: Reading) -> Result<Pooled> {
    let (mut all, mut worst, mut cpu) = (Vec::new(), 0.0f64, 0.0);
    for x in draws {
        let (errs, t) = joint_run(c, x, fs, how)?;
        worst = worst.max(p95(errs.clone()));
        all.extend(errs);
        cpu += t;
    }
    Ok(Pooled {
        windows: all.len(),
        p95: p95(all),
        worst_draw_p95: worst,
        cpu,
    })
}

/// Every joint case read every way in this run, each over [`DRAWS`] independent draws.
fn joint_cases(seconds: f64) -> Result<Vec<serde_json::Value>> {
    let fs = 10_000.0;
    let bpfo = 5.5 * (1.0 - 7.94 / 48.0);
    let seconds = seconds.max(JOINT_MIN_S);
    JOINT
        .iter()
        .map(|c| {
            let draws: Vec<Vec<f32>> = (0..DRAWS)
                .map(|d| joint_signal(c, fs, seconds, bpfo, d))
                .collect();
            let read = |parts, exhaustive| pooled(c, &draws, fs, Reading { parts, exhaustive });
            let shipped = read(JointParts::default_on(), false)?;
            let (p95, cpu) = (shipped.p95, shipped.cpu);
            let scan = read(JointParts::default_on(), true)?;
            let (p95_scan, cpu_scan) = (scan.p95, scan.cpu);
            let before = read(JointParts::all(false), false)?;
            let (p95_before, cpu_before) = (before.p95, before.cpu);
            let phase = JointParts {
                phase: !JointParts::default_on().phase,
                ..JointParts::default_on()
            };
            let switched = read(phase, false)?;
            let (p95_phase, cpu_phase) = (switched.p95, switched.cpu);
            Ok(serde_json::json!({
                "case": c.0,
                "draws": DRAWS,
                "seconds_per_draw": seconds,
                "windows": shipped.windows,
                "p95_error_pct": 100.0 * p95,
                "p95_error_worst_draw_pct": 100.0 * shipped.worst_draw_p95,
                "p95_error_before_worst_draw_pct": 100.0 * before.worst_draw_p95,
                "p95_error_scan_pct": 100.0 * p95_scan,
                "p95_error_before_pct": 100.0 * p95_before,
                "p95_error_phase_switched_pct": 100.0 * p95_phase,
                "phase_on_by_default": JointParts::default_on().phase,
                "tracker_cpu_s": cpu,
                "tracker_cpu_scan_s": cpu_scan,
                "tracker_cpu_before_s": cpu_before,
                "tracker_cpu_phase_switched_s": cpu_phase,
                "cpu_ratio_scan": cpu / cpu_scan,
                "cpu_ratio": cpu / cpu_before,
            }))
        })
        .collect()
}

fn print_joint(rows: &[serde_json::Value]) {
    println!("joint reading (issue 34), the tracker alone, 1 ch x 10 kHz, 300-3600 rpm, each case read in this run over independent draws (p95 of all their windows; the worst draw's own p95 in brackets): as shipped, with the harmonic sum scanned point by point (before issue 37), as before issue 34, and with the phase reading switched:");
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap_or(0.0);
    for r in rows {
        let phase = if r["phase_on_by_default"].as_bool().unwrap_or(false) {
            "off"
        } else {
            "on"
        };
        println!(
            "  {} ({} draws x {:.0} s, {} windows): p95 error {:.3} % [{:.3} %] (scanned {:.3} %, before {:.3} % [{:.3} %], phase {phase} {:.3} %); tracker CPU {:.2} s (scanned {:.2} s: x{:.2}; before {:.2} s: x{:.2}; phase {phase} {:.2} s)",
            r["case"].as_str().unwrap_or(""),
            r["draws"],
            f(r, "seconds_per_draw"),
            r["windows"],
            f(r, "p95_error_pct"),
            f(r, "p95_error_worst_draw_pct"),
            f(r, "p95_error_scan_pct"),
            f(r, "p95_error_before_pct"),
            f(r, "p95_error_before_worst_draw_pct"),
            f(r, "p95_error_phase_switched_pct"),
            f(r, "tracker_cpu_s"),
            f(r, "tracker_cpu_scan_s"),
            f(r, "cpu_ratio_scan"),
            f(r, "tracker_cpu_before_s"),
            f(r, "cpu_ratio"),
            f(r, "tracker_cpu_phase_switched_s"),
        );
    }
}
