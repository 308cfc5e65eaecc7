//! The speed from the vibration read jointly from every cue (issue 34 items 1-3, 7), on an
//! independent generator of the seed's rig built here from simple physics, not from any
//! shared record and not from the project's simulator: one accelerometer axis at 10 kHz,
//! no tacho, the tracker as `[speed] source = "estimate"` runs it (300-3600 rpm, the rig's
//! bearing, 1 s windows every 0.5 s).
//!
//! The machine: shaft lines at 1x and 2x (an accelerometer's 1x at 588 rpm stands about 24x
//! its floor in a 20 s spectrum, 2x about 9x: amplitudes 0.11 and 0.041 against unit white
//! noise; at 1188 rpm an acceleration four times larger), and, for a damaged bearing, impacts
//! at the fault rate (the kinematic order, each interval jittered 1 % by slip) through two
//! structural modes: one at 3 kHz (ζ = 0.05, the carrier the envelope sees) and one at 400 Hz
//! (ζ = 0.1) whose response below it puts the impact train's comb into the raw spectrum, as
//! strong as the shaft's own lines or stronger. An inner race's impacts are modulated by the
//! load zone once per revolution. Speed laws: steady, a slow drift, and a fluctuation of
//! +-2 % (4 % peak to peak) at 0.3 Hz.
//!
//! Errors are the window's mean speed (its last second) against the truth's mean over the
//! same second, over every window once the tracker's history (4 s at 300 rpm) is full.

use rigmon::bearing::{BearingGeometry, FaultOrders};
use rigmon::dsp::fault_family::FamilySettings;
use rigmon::dsp::speed_tracker::{
    JointParts, SpeedHint, SpeedTracker, TrackedSpeed, TrackerSettings,
};
use std::f64::consts::TAU;

const FS: f64 = 10_000.0;
const HOP: usize = 5_000;
const RANGE: (f64, f64) = (300.0, 3600.0);

/// The seed rig's bearing (SKF 6007: BPFO 4.59 orders).
fn orders() -> FaultOrders {
    BearingGeometry {
        balls: 11,
        ball_diameter_mm: 7.94,
        pitch_diameter_mm: 48.0,
        contact_angle_deg: 0.0,
    }
    .fault_orders()
}

#[derive(Clone, Copy)]
enum Fault {
    Outer,
    Inner,
}

/// What the machine shows.
#[derive(Clone, Copy)]
struct Machine {
    /// Shaft 1x and 2x amplitudes.
    shaft: (f64, f64),
    /// A damaged bearing and its impacts' peak response (in units of the noise).
    fault: Option<(Fault, f64)>,
}

/// A second-order resonator driven by impulses: a structural mode at `hz`, damping `zeta`,
/// whose response to a unit impact peaks near 1.
struct Mode {
    a1: f64,
    a2: f64,
    b: f64,
    y: [f64; 2],
}

impl Mode {
    fn new(hz: f64, zeta: f64) -> Mode {
        let r = (-zeta * TAU * hz / FS).exp();
        let th = TAU * hz * (1.0 - zeta * zeta).sqrt() / FS;
        Mode {
            a1: 2.0 * r * th.cos(),
            a2: -r * r,
            b: th.sin(),
            y: [0.0; 2],
        }
    }

    fn step(&mut self, x: f64) -> f64 {
        let y = self.a1 * self.y[0] + self.a2 * self.y[1] + self.b * x;
        self.y = [y, self.y[0]];
        y
    }
}

/// Xorshift uniform (0, 1) and Gaussian samples.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn gauss(&mut self) -> f64 {
        (-2.0 * self.uniform().ln()).sqrt() * (TAU * self.uniform()).cos()
    }
}

/// `seconds` of the machine turning along `hz(t)`.
fn signal(m: Machine, seconds: f64, hz: impl Fn(f64) -> f64, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let o = orders();
    let (mut high, mut low) = (Mode::new(3_000.0, 0.05), Mode::new(400.0, 0.1));
    let (mut theta, mut fault_phase) = (0.0, 0.0);
    let mut next_impact = 1.0;
    (0..(FS * seconds) as usize)
        .map(|i| {
            let t = i as f64 / FS;
            let f = hz(t);
            theta += f / FS;
            let mut v = rng.gauss();
            v += m.shaft.0 * (TAU * theta).sin() + m.shaft.1 * (TAU * 2.0 * theta + 1.0).sin();
            let mut kick = 0.0;
            if let Some((fault, amp)) = m.fault {
                let order = match fault {
                    Fault::Outer => o.bpfo,
                    Fault::Inner => o.bpfi,
                };
                fault_phase += order * f / FS;
                if fault_phase >= next_impact {
                    next_impact += 1.0 + 0.01 * rng.gauss();
                    kick = match fault {
                        Fault::Outer => amp,
                        Fault::Inner => amp * (0.3 + 0.7 * (0.5 + 0.5 * (TAU * theta).cos())),
                    };
                }
            }
            v += high.step(kick) + 0.5 * low.step(kick);
            v as f32
        })
        .collect()
}

fn settings(hint: Option<SpeedHint>) -> TrackerSettings {
    TrackerSettings {
        min_rpm: RANGE.0,
        max_rpm: RANGE.1,
        hint,
        families: Some(FamilySettings {
            orders: orders(),
            band_top_hz: 4_000.0,
        }),
    }
}

/// Every window's speed once the history is full, with the truth's mean over its last
/// second; `joint` false reads as before issue 34.
fn windows(
    x: &[f32],
    s: TrackerSettings,
    hz: &dyn Fn(f64) -> f64,
    parts: JointParts,
) -> Vec<(f64, TrackedSpeed, f64)> {
    let mut tr = SpeedTracker::new(s, FS).unwrap();
    tr.set_joint_parts(parts);
    let full = tr.history_s();
    let mut out = Vec::new();
    for (k, c) in x.chunks(HOP).enumerate() {
        tr.push((k * HOP) as u64, c);
        let t = ((k + 1) * HOP) as f64 / FS;
        if let Ok(e) = tr.estimate() {
            if t >= full {
                let truth = (0..100)
                    .map(|j| hz(t - 1.0 + j as f64 / 100.0))
                    .sum::<f64>()
                    * 0.6;
                out.push((t, e, truth));
            }
        }
    }
    out
}

/// Relative errors of the windows' mean speeds over their last second, sorted.
fn errors(w: &[(f64, TrackedSpeed, f64)]) -> Vec<f64> {
    let mut e: Vec<f64> = w
        .iter()
        .map(|(t, s, truth)| (s.track.mean_rpm(t - 1.0, *t) / truth - 1.0).abs())
        .collect();
    e.sort_by(f64::total_cmp);
    e
}

fn quantile(e: &[f64], q: f64) -> f64 {
    e[((e.len() as f64 * q).ceil() as usize).clamp(1, e.len()) - 1]
}

fn healthy(rpm: f64) -> Machine {
    let a = 0.11 * (rpm / 588.0).powi(2);
    Machine {
        shaft: (a, 0.37 * a),
        fault: None,
    }
}

/// The healthy machine at 588 rpm with a damaged bearing whose impacts peak at 6x the noise.
fn damaged_588(fault: Fault) -> Machine {
    Machine {
        fault: Some((fault, 6.0)),
        ..healthy(588.0)
    }
}

/// One case read three ways on the same samples: the errors (sorted) of the tracker's
/// default reading (the joint reading), of the joint reading with the phase fit
/// (`speed_phase`, measured but not on by default) and of the reading before issue 34; all
/// printed.
struct Readings {
    now: Vec<f64>,
    phase: Vec<f64>,
    before: Vec<f64>,
}

impl Readings {
    fn of(name: &str, x: &[f32], hz: &dyn Fn(f64) -> f64) -> Readings {
        let run = |p: JointParts| errors(&windows(x, settings(None), hz, p));
        let r = Readings {
            now: run(JointParts::default_on()),
            phase: run(JointParts::all(true)),
            before: run(JointParts::all(false)),
        };
        let pm = |e: &[f64]| {
            format!(
                "p95 {:.3} % median {:.3} %",
                100.0 * quantile(e, 0.95),
                100.0 * quantile(e, 0.5)
            )
        };
        eprintln!(
            "{name} ({} windows): joint {} | with the phase fit {} | before issue 34 {}",
            r.now.len(),
            pm(&r.now),
            pm(&r.phase),
            pm(&r.before)
        );
        r
    }

    fn p95(&self) -> f64 {
        quantile(&self.now, 0.95)
    }
}

fn case(name: &str, m: Machine, hz: &dyn Fn(f64) -> f64, seed: u64) -> Readings {
    Readings::of(name, &signal(m, 30.0, hz, seed), hz)
}

/// A healthy machine at 588 rpm (weak 1x), steady: issue 34's target, p95 within 0.5 %
/// (the newest second shown in phase keeps the weak line followed: `newest_in_phase`), and
/// most windows confident (before that part: p95 4.4 %, 43 of 53 uncertain; docs/speed.md).
/// 1188 rpm is printed beside it.
#[test]
fn a_weak_1x_at_588_rpm_is_read() {
    let hz = |_: f64| 588.0 / 60.0;
    let x = signal(healthy(588.0), 30.0, hz, 3);
    let r = Readings::of("healthy 588 steady", &x, &hz);
    let unsure = |p: JointParts| {
        windows(&x, settings(None), &hz, p)
            .iter()
            .filter(|(_, e, _)| e.uncertain())
            .count()
    };
    eprintln!(
        "healthy 588 steady: uncertain windows {} joint, {} with the phase fit, {} without the newest second in phase",
        unsure(JointParts::default_on()),
        unsure(JointParts::all(true)),
        unsure(JointParts {
            newest_in_phase: false,
            ..JointParts::default_on()
        })
    );
    assert!(r.p95() <= 0.005, "p95 {}", r.p95());
    let uncertain = unsure(JointParts::default_on());
    assert!(2 * uncertain < r.now.len(), "{uncertain} windows uncertain");
    let hz = |_: f64| 1188.0 / 60.0;
    Readings::of(
        "healthy 1188 steady",
        &signal(healthy(1188.0), 30.0, hz, 4),
        &hz,
    );
}

/// The speed fluctuating +-2 % at 0.3 Hz: better than before, and by the phase's wandering
/// law (`JointParts::phase_wander`) better than the spectrum's reading alone (the history's
/// mean along its trend) in the median and no worse in p95 (within a tenth of a percent),
/// both pooled over four draws: a draw's p95 is two or three windows (draw 5 alone reads
/// 5.4 % with the law and 2.9 % without it since the line is held, `held_line`; 20 draws of
/// this generator pool to 2.68 % with it and 2.82 % without; four to 2.84 % both ways).
/// Target p95 <= 1.5 % not met yet (docs/speed.md). 1188 rpm is printed beside it.
#[test]
fn a_fluctuating_speed_is_read_better_than_before() {
    let hz = |t: f64| 588.0 / 60.0 * (1.0 + 0.02 * (TAU * 0.3 * t).sin());
    let (mut now, mut spectrum) = (Vec::new(), Vec::new());
    for seed in [5, 7_919, 15_838, 23_757] {
        let x = signal(healthy(588.0), 30.0, hz, seed);
        let r = Readings::of(&format!("healthy 588 fluctuating, draw {seed}"), &x, &hz);
        assert!(r.p95() < quantile(&r.before, 0.95), "p95 {}", r.p95());
        now.extend(r.now);
        spectrum.extend(errors(&windows(
            &x,
            settings(None),
            &hz,
            JointParts {
                phase_wander: false,
                ..JointParts::default_on()
            },
        )));
    }
    now.sort_by(f64::total_cmp);
    spectrum.sort_by(f64::total_cmp);
    eprintln!(
        "healthy 588 fluctuating, 4 draws ({} windows): p95 {:.3} % median {:.3} % with the wandering law, {:.3} % / {:.3} % without",
        now.len(),
        100.0 * quantile(&now, 0.95),
        100.0 * quantile(&now, 0.5),
        100.0 * quantile(&spectrum, 0.95),
        100.0 * quantile(&spectrum, 0.5)
    );
    assert!(quantile(&now, 0.95) <= quantile(&spectrum, 0.95) + 0.001);
    assert!(quantile(&now, 0.5) < quantile(&spectrum, 0.5));
    let hz = |t: f64| 1188.0 / 60.0 * (1.0 + 0.02 * (TAU * 0.3 * t).sin());
    case("healthy 1188 fluctuating", healthy(1188.0), &hz, 6);
}

/// A clean 1x line alone at 1188 rpm is read without bias: the median within 0.1 %.
#[test]
fn a_clean_line_is_read_without_bias() {
    let hz = |_: f64| 1188.0 / 60.0;
    let m = Machine {
        shaft: (0.44, 0.0),
        fault: None,
    };
    let r = case("clean 1188", m, &hz, 7);
    assert!(
        quantile(&r.now, 0.5) <= 0.001,
        "median {}",
        quantile(&r.now, 0.5)
    );
}

/// An outer race at 588 rpm whose BPFO comb (45, 90, 135 Hz) stands above the shaft lines:
/// the shaft is 9.8 Hz with the comb its train, not a shaft at 22.5, 30 or 45 Hz, and read
/// within issue 34's 0.5 % for a steady speed (p95).
#[test]
fn a_bearing_comb_does_not_become_the_shaft() {
    let hz = |_: f64| 588.0 / 60.0;
    let m = damaged_588(Fault::Outer);
    // a shaft read from the comb is 30 % or more off (1350, 1800 or 2700 rpm)
    let r = case("outer race 588", m, &hz, 9);
    assert!(r.p95() <= 0.005, "p95 {}", r.p95());
}

/// While the tracker acquires (the line not yet trusted), the last window's line, still the
/// whole history's best above noise, is held without searching parts of the history along
/// trends (`JointParts::held_line`): two draws where the best of those searches was found by
/// chance, one a steady healthy 588 rpm whose line it read 5 % off along a trend, one an outer
/// race at 588 rpm whose 45 Hz BPFO line it read as a shaft at 2,600 rpm along a trend of
/// 3 % per second (draws found among 20 of this generator; the case's own seed above reads
/// well either way). Each within issue 34's 0.5 % (p95), and each worse without the part.
#[test]
fn the_last_windows_line_is_held_against_chance_trends() {
    let hz = |_: f64| 588.0 / 60.0;
    let outer = damaged_588(Fault::Outer);
    for (name, m, seed) in [
        ("steady 588, draw 5", healthy(588.0), 5),
        ("outer race 588, draw 95028", outer, 95_028),
    ] {
        let x = signal(m, 30.0, hz, seed);
        let read = |held_line| {
            errors(&windows(
                &x,
                settings(None),
                &hz,
                JointParts {
                    held_line,
                    ..JointParts::default_on()
                },
            ))
        };
        let (with, without) = (read(true), read(false));
        let (p, q) = (quantile(&with, 0.95), quantile(&without, 0.95));
        eprintln!(
            "{name}: p95 {:.3} % with the line held, {:.3} % without",
            100.0 * p,
            100.0 * q
        );
        assert!(p <= 0.005, "{name}: p95 {p}");
        assert!(q > 2.0 * p, "{name}: {q} without the part, {p} with");
    }
}

/// An impulsive inner race with a weak shaft line at 588 rpm: within 0.5 % (p95).
#[test]
fn an_impulsive_inner_race_keeps_the_shaft() {
    let hz = |_: f64| 588.0 / 60.0;
    let m = damaged_588(Fault::Inner);
    let r = case("inner race 588", m, &hz, 13);
    assert!(r.p95() <= 0.005, "p95 {}", r.p95());
}

/// A slow drift 588 -> 700 rpm over 30 s is followed better than before.
#[test]
fn a_slow_drift_is_followed() {
    let hz = |t: f64| (588.0 + 112.0 * t / 30.0) / 60.0;
    let r = case("drift 588-700", healthy(600.0), &hz, 17);
    assert!(r.p95() < quantile(&r.before, 0.95), "p95 {}", r.p95());
}

/// A healthy record without any line is never a confident speed.
#[test]
fn no_lines_no_speed() {
    let hz = |_: f64| 10.0;
    let m = Machine {
        shaft: (0.0, 0.0),
        fault: None,
    };
    let x = signal(m, 20.0, hz, 19);
    for (t, e, _) in windows(&x, settings(None), &hz, JointParts::all(true)) {
        assert!(e.uncertain(), "at {t} s: {e:?}");
    }
}

/// A clear line fluctuating +-2 % at 0.3 Hz at 1188 rpm (issue 34: p95 <= 1.5 % with a 4 %
/// fluctuation): the phase of its harmonics over the whole history curves by very strong
/// evidence, so the window's speed is the phase smoother's wandering law, weighed against the
/// spectrum's steady one by their posterior probabilities (`JointParts::phase_wander`, on by
/// default): p95 within 1.5 % over three draws, below the spectrum's own reading (which
/// reads the history's mean and trend); on a steady line the curve is never taken, so the
/// speeds are the same to the bit with and without it.
#[test]
fn a_fluctuating_clear_line_is_read_from_its_phase() {
    let hz = |t: f64| 1188.0 / 60.0 * (1.0 + 0.02 * (TAU * 0.3 * t).sin());
    let without = JointParts {
        phase_wander: false,
        ..JointParts::default_on()
    };
    let (mut on, mut off) = (Vec::new(), Vec::new());
    for seed in [11, 12, 13] {
        let x = signal(healthy(1188.0), 30.0, hz, seed);
        on.extend(errors(&windows(
            &x,
            settings(None),
            &hz,
            JointParts::default_on(),
        )));
        off.extend(errors(&windows(&x, settings(None), &hz, without)));
    }
    on.sort_by(f64::total_cmp);
    off.sort_by(f64::total_cmp);
    let (p_on, p_off) = (quantile(&on, 0.95), quantile(&off, 0.95));
    eprintln!(
        "1188 rpm +-2 % at 0.3 Hz, {} windows: p95 {:.3} % with the curve, {:.3} % without",
        on.len(),
        100.0 * p_on,
        100.0 * p_off
    );
    assert!(
        p_on <= 0.015 && p_on < p_off,
        "p95 {p_on} (without {p_off})"
    );
    let steady = |_: f64| 1188.0 / 60.0;
    let x = signal(healthy(1188.0), 30.0, steady, 14);
    let rpm = |p: JointParts| -> Vec<f64> {
        windows(&x, settings(None), &steady, p)
            .iter()
            .map(|(_, e, _)| e.rpm)
            .collect()
    };
    assert_eq!(rpm(JointParts::default_on()), rpm(without));
}
