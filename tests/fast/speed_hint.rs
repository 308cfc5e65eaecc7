//! A nominal speed is a prior, not the truth (issue 34 item 3), on independent cases built
//! from physics, not from any shared record: shaft lines (1x-5x) in unit Gaussian noise,
//! through the streaming tracker as the daemon runs it (10 kHz, 1 s windows every 0.5 s),
//! with the nominal speed as the hint (+-10 %, the default) inside a 300-3600 rpm rig. Only
//! windows 1.5 s after the tracker's history (20 revolutions at the band's lowest speed)
//! are judged.
//! - a shaft at 600 rpm labelled 1200 (and 750 labelled 1500): the vibration's speed, marked
//!   [`SpeedStatus::OffHint`] (1200 labelled 600, the octave above, is not searched);
//! - a shaft 3-8 % off its nominal: read where it turns, no contradiction;
//! - a weak 1x at low speed (an accelerometer sees 1x at 10 Hz 4x weaker than 2x): the hint's
//!   speed, no contradiction;
//! - an outer-race comb (BPFO 4.59 orders) stronger than the shaft lines: the comb never
//!   becomes the shaft;
//! - no lines at all: the hint's own speed, no contradiction.

use crate::speed_cues::{gaussian, lut_bearing};
use rigmon::dsp::fault_family::FamilySettings;
use rigmon::dsp::speed_tracker::{
    SpeedHint, SpeedStatus, SpeedTracker, TrackedSpeed, TrackerSettings,
};
use std::f64::consts::TAU;

const FS: f64 = 10_000.0;
const HOP: usize = 5_000;
const SECONDS: f64 = 12.0;

/// What the machine shows: shaft lines (order, amplitude) at `rpm`, and optionally an outer
/// race: a comb at BPFO's harmonics (amplitude) and a 3 kHz resonance struck at BPFO.
#[derive(Clone, Copy)]
struct Machine<'a> {
    rpm: f64,
    lines: &'a [(f64, f64)],
    outer_race: Option<f64>,
}

/// Unit-variance Gaussian noise plus the machine.
fn signal(m: Machine, seed: u64) -> Vec<f32> {
    let mut noise = gaussian(seed);
    let f = m.rpm / 60.0;
    let bpfo = lut_bearing().fault_orders().bpfo;
    (0..(FS * SECONDS) as usize)
        .map(|i| {
            let t = i as f64 / FS;
            let mut v = noise();
            for &(order, a) in m.lines {
                v += a * (TAU * order * f * t + order).sin();
            }
            if let Some(a) = m.outer_race {
                for h in 1..=3 {
                    v += a * (TAU * h as f64 * bpfo * f * t).sin();
                }
                // a decaying 3 kHz ring after every impact
                let since = (t * bpfo * f).fract() / (bpfo * f);
                v += 4.0 * a * (-since * 600.0).exp() * (TAU * 3_000.0 * since).sin();
            }
            v as f32
        })
        .collect()
}

fn settings(hint_rpm: f64, families: bool) -> TrackerSettings {
    TrackerSettings {
        min_rpm: 300.0,
        max_rpm: 3600.0,
        hint: Some(SpeedHint {
            rpm: hint_rpm,
            within: 0.1,
        }),
        families: families.then(|| FamilySettings {
            orders: lut_bearing().fault_orders(),
            band_top_hz: 4_000.0,
        }),
    }
}

/// The speed of every window after the tracker's history is full.
fn windows(x: &[f32], s: TrackerSettings) -> Vec<(f64, TrackedSpeed)> {
    let mut tr = SpeedTracker::new(s, FS).unwrap();
    let full = tr.history_s();
    let mut out = Vec::new();
    for (k, c) in x.chunks(HOP).enumerate() {
        tr.push((k * HOP) as u64, c);
        let t = ((k + 1) * HOP) as f64 / FS;
        match tr.estimate() {
            // the first second after the history may still be the hint's (the band's line
            // not yet clear: as before issue 34 item 3), and an octave is taken once seen in
            // two windows in a row
            Ok(e) if t >= full + 1.5 => out.push((t, e)),
            _ => {}
        }
    }
    assert!(out.len() >= 10, "{} windows", out.len());
    out
}

/// Shaft lines of a machine with unbalance and misalignment: 1x-5x falling off.
const SHAFT: [(f64, f64); 5] = [(1.0, 0.6), (2.0, 0.8), (3.0, 0.4), (4.0, 0.3), (5.0, 0.2)];

/// Every window reads `rpm` within 1 % with status `status`.
fn assert_all(est: &[(f64, TrackedSpeed)], rpm: f64, status: SpeedStatus, what: &str) {
    for (t, e) in est {
        assert!(
            e.status == status && (e.rpm / rpm - 1.0).abs() < 0.01 && !e.uncertain(),
            "{what} at {t} s: {:.1} rpm, {:?} at {:.2} (want {rpm} rpm, {status:?})",
            e.rpm,
            e.status,
            e.confidence
        );
    }
}

#[test]
fn a_shaft_at_the_octave_below_its_label_is_read_and_marked() {
    // the octave above (1200 rpm labelled 600) is not searched: docs/speed.md
    for (rpm, label, seed) in [(600.0, 1200.0, 5), (750.0, 1500.0, 7)] {
        let m = Machine {
            rpm,
            lines: &SHAFT,
            outer_race: None,
        };
        let est = windows(&signal(m, seed), settings(label, false));
        assert_all(
            &est,
            rpm,
            SpeedStatus::OffHint,
            &format!("{rpm} rpm labelled {label}"),
        );
    }
}

#[test]
fn a_speed_off_its_nominal_is_read_without_a_contradiction() {
    for (rpm, nominal) in [
        (1036.0, 1000.0),
        (1080.0, 1000.0),
        (776.0, 800.0),
        (1300.0, 1400.0),
    ] {
        let m = Machine {
            rpm,
            lines: &SHAFT,
            outer_race: None,
        };
        let est = windows(&signal(m, 11), settings(nominal, false));
        assert_all(
            &est,
            rpm,
            SpeedStatus::Tracking,
            &format!("{rpm} rpm, nominal {nominal}"),
        );
    }
}

/// An accelerometer at 480 rpm: 1x barely above the noise, 2x and 3x clear. The odd line
/// (3x) says the band's speed is right: no contradiction, the speed within 1 %.
#[test]
fn a_weak_1x_at_low_speed_keeps_the_hint() {
    let m = Machine {
        rpm: 480.0,
        lines: &[(1.0, 0.08), (2.0, 0.5), (3.0, 0.35), (4.0, 0.25)],
        outer_race: None,
    };
    let est = windows(&signal(m, 13), settings(480.0, true));
    for (t, e) in &est {
        assert!(
            e.status != SpeedStatus::OffHint && (e.rpm / 480.0 - 1.0).abs() < 0.01,
            "at {t} s: {e:?}"
        );
    }
}

/// An outer race at 588 rpm whose BPFO comb (45, 90, 135 Hz) stands well above the shaft's
/// weak 1x and 2x: with the nominal speed as hint and the bearing's families, the comb never
/// becomes the shaft.
#[test]
fn an_outer_race_comb_stronger_than_the_shaft_does_not_win_over_the_hint() {
    let m = Machine {
        rpm: 588.0,
        lines: &[(1.0, 0.25), (2.0, 0.2)],
        outer_race: Some(1.0),
    };
    let est = windows(&signal(m, 17), settings(588.0, true));
    for (t, e) in &est {
        assert!(
            e.status != SpeedStatus::OffHint && (e.rpm / 588.0 - 1.0).abs() < 0.01,
            "at {t} s: {e:?}"
        );
    }
}

/// Noise alone with a hint: the hint's own speed in every window, never a contradiction.
#[test]
fn no_lines_with_a_hint_is_the_hint_and_no_contradiction() {
    let m = Machine {
        rpm: 900.0,
        lines: &[],
        outer_race: None,
    };
    let est = windows(&signal(m, 19), settings(900.0, true));
    assert_all(&est, 900.0, SpeedStatus::Hint, "noise, hint 900 rpm");
}

/// Checked on the shared HIT-SM records only after the rule was chosen on the cases above
/// (their speeds are in their names): each record with its name's speed as the manifest
/// `rpm` hint, through the shipped rig file (`[speed] estimate`, 500-1500 rpm, hint +-10 %).
/// The 18 fault records turn at their names' speeds (`tests/fast/dsp.rs`): none may claim a
/// contradiction. The three Normal records all turn at ~1201 rpm: Normal_600 (the octave
/// above its name) and Normal_900 (4/3 of it) are not searched, so no record may claim one
/// (the rule with the octave above claimed IR8_600 at 1201-1218 rpm in 1-2 of 9 windows).
#[test]
fn hit_sm_names_are_checked_against_the_vibration() {
    let rig = rigmon::config::RigConfig::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/config/hit-sm-self.toml"
    )))
    .unwrap();
    let data = crate::common::shared_data().join("hit-sm-self");
    let mut wrong = Vec::new();
    for cond in ["Normal", "IR2", "IR5", "IR8", "OR2", "OR5", "OR8"] {
        for nominal in [600.0, 900.0, 1200.0] {
            let name = format!("{cond}_{nominal}.mat");
            let mut rec = rigmon::importers::load(
                &data.join(&name),
                &rig,
                &rigmon::importers::ImportOptions::default(),
            )
            .unwrap();
            rec.nominal_rpm = Some(rigmon::recording::NominalSpeed {
                rpm: nominal,
                declared_at: format!("{name} (its name)"),
            });
            let (track, against) = rigmon::analysis::whole_recording_checked(&rec, &rig).unwrap();
            let rpm = track.mean_rpm(0.0, rec.duration_s());
            let want_off = false;
            let said = against.as_ref().map(|c| c.message());
            eprintln!("{name}: {rpm:.1} rpm; {said:?}");
            match (&against, want_off) {
                (None, false) => {}
                (Some(c), true) if (c.vibration_rpm / 1200.0 - 1.0).abs() < 0.01 => {}
                _ => wrong.push(format!("{name}: {rpm:.1} rpm, {said:?}")),
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}
