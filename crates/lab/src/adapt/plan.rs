//! The dataset plan `rigmon adapt` derives from a rig file and the measured recordings of
//! that machine. Its speeds come from the machine: the rig file's declared operating range
//! when `[speed] source = "estimate"` (`min_rpm..max_rpm`), the fixed speed when the rig file
//! fixes one, otherwise the speeds the measured recordings turn at (as the one analysis stage
//! reads them, [`crate::analysis::speed_source::whole_recording`]) from 6 % below (a motor
//! slows under load) to 3 % above ([`speed_basis`]); [`check_speeds`] refuses a plan that
//! would simulate a standing shaft or a speed the rig file does not allow before anything is
//! simulated. Defect sizes are scaled to the bearing's balls, outer-race defects all around
//! the race, inner-race defects at any angle, an axial preload with a small contact angle
//! (so every ball carries load and an outer-race defect away from the radial load zone still
//! makes impacts, as on the CWRU motor whose 3 and 12 o'clock faults show BPFO lines;
//! `config/plans/cwru-preload.toml`), a radial load, slip, unbalance, noise, resonance and
//! speed-fluctuation ranges wide enough to cover an unknown machine. Where calibration fitted
//! a parameter, `rigmon dataset --calibrated spread` semantics move these ranges onto the
//! fitted value (see [`crate::sim::dataset::CalibratedDraws::Spread`]). Classes: healthy,
//! outer race, inner race, plus ball when the measured labels hold a ball record. Labelled
//! faults add cases of their own ([`super::shape`]).

use crate::config::RigConfig;
use crate::dsp::speed_config::SpeedConfig;
use crate::sim::plan::{Plan, PlanCase, RandomRanges};
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use serde::Serialize;

/// How far below the slowest measured speed the derived plan draws (fraction).
pub const RPM_BELOW: f64 = 0.06;
/// How far above the fastest measured speed the derived plan draws (fraction).
pub const RPM_ABOVE: f64 = 0.03;
/// Relative speed-fluctuation amplitude range of the derived plan.
pub const SPEED_FLUCTUATION: [f64; 2] = [0.0, 0.005];
/// Contact angle range of the derived plan, degrees (> 0, so a preload loads every ball).
pub const CONTACT_ANGLE_DEG: [f64; 2] = [3.0, 10.0];
/// Axial preload range of the derived plan, N (`cwru-preload.toml`'s).
pub const PRELOAD_N: [f64; 2] = [50.0, 400.0];
/// Static radial load range of the derived plan, N; its top is raised to
/// [`RADIAL_LOAD_ABOVE_RIG`] x the rig file's own `radial_load_n` where that is higher (a rig
/// file that states a heavy load, such as the MFPT rig's 1,200 N, is simulated around it).
pub const RADIAL_LOAD_N: [f64; 2] = [0.0, 400.0];
/// How far above the rig file's radial load the derived plan draws.
pub const RADIAL_LOAD_ABOVE_RIG: f64 = 1.5;

/// What the measured recordings say about the operating range.
#[derive(Debug, Clone, Serialize)]
pub struct MeasuredRange {
    pub rpm_min: f64,
    pub rpm_max: f64,
    /// Sample rates seen, Hz (reported; the simulation keeps the rig file's rate).
    pub sample_rates_hz: Vec<f64>,
    pub labels: Vec<String>,
}

impl MeasuredRange {
    /// From (name, rpm, sample rate, label) per recording; a recording without a usable
    /// speed is named in the error.
    pub fn of(items: &[(String, f64, f64, String)]) -> Result<MeasuredRange> {
        if items.is_empty() {
            bail!("no measured recording to derive a dataset plan from");
        }
        if let Some((name, rpm, ..)) = items.iter().find(|i| !(i.1.is_finite() && i.1 > 0.0)) {
            bail!(
                "{name}: its speed reads {rpm} rpm; a plan cannot be derived from a standing shaft. \
                 Check the recording's speed source ([speed] in the rig file, the tacho channel or the stored rpm)"
            );
        }
        let rpm_min = items.iter().map(|i| i.1).fold(f64::INFINITY, f64::min);
        let rpm_max = items.iter().map(|i| i.1).fold(0.0, f64::max);
        let mut sample_rates_hz: Vec<f64> = items.iter().map(|i| i.2).collect();
        sample_rates_hz.sort_by(f64::total_cmp);
        sample_rates_hz.dedup();
        let mut labels: Vec<String> = items.iter().map(|i| i.3.clone()).collect();
        labels.sort();
        labels.dedup();
        Ok(MeasuredRange {
            rpm_min,
            rpm_max,
            sample_rates_hz,
            labels,
        })
    }
}

/// The speeds a plan may simulate on this rig, rpm, and why: `[speed] estimate` declares
/// its operating range; a `fixed` speed checked against the 1x line is followed within
/// `check_within_percent`, an unchecked one is read for every window, so a simulated
/// recording must turn at it (within one feature bin at the highest order: `bin_width_order
/// / max_order`). `None`: the rig file does not bound the speed (tacho, edges, stored rpm).
pub fn allowed_speeds(rig: &RigConfig) -> Option<([f64; 2], String)> {
    match rig.speed {
        SpeedConfig::Estimate {
            min_rpm, max_rpm, ..
        } => Some((
            [min_rpm, max_rpm],
            format!("the rig file's [speed] estimate range {min_rpm}-{max_rpm} rpm"),
        )),
        SpeedConfig::Fixed {
            rpm,
            check_within_percent,
        } => {
            // a fixed speed checked against the 1x line is followed within the check's
            // range; an unchecked one is read for every window, so a recording must turn
            // at it within one feature bin at the highest order
            let (tol, why) = if check_within_percent > 0.0 {
                (
                    0.01 * check_within_percent,
                    "the 1x check follows the shaft within it",
                )
            } else {
                (
                    rig.features.bin_width_order / rig.features.max_order,
                    "every window is read at it; this keeps the highest order within one bin",
                )
            };
            Some((
                [rpm * (1.0 - tol), rpm * (1.0 + tol)],
                format!(
                    "the rig file's fixed speed {rpm} rpm +-{:.1} % ({why})",
                    100.0 * tol
                ),
            ))
        }
        _ => None,
    }
}

/// The speeds a derived plan may draw its mean speed from: [`allowed_speeds`], pulled in
/// by the largest [`SPEED_FLUCTUATION`] so a fluctuating recording stays inside (a fixed
/// speed is simulated without fluctuation).
pub fn plannable_speeds(rig: &RigConfig) -> Option<[f64; 2]> {
    let ([a, b], _) = allowed_speeds(rig)?;
    let f = SPEED_FLUCTUATION[1];
    Some(match rig.speed {
        SpeedConfig::Fixed { rpm, .. } => [rpm, rpm],
        _ => [a / (1.0 - f), b / (1.0 + f)],
    })
}

/// The derived plan's speed range, rpm, and where it comes from ([`plannable_speeds`],
/// else the measured speeds -[`RPM_BELOW`] / +[`RPM_ABOVE`]).
pub fn speed_basis(rig: &RigConfig, range: &MeasuredRange) -> ([f64; 2], String) {
    match (&rig.speed, allowed_speeds(rig), plannable_speeds(rig)) {
        (SpeedConfig::Fixed { rpm, .. }, Some(_), _) => (
            [*rpm, *rpm],
            format!("the rig file's fixed speed {rpm} rpm"),
        ),
        (_, Some((_, why)), Some(inside)) => (
            inside,
            format!(
                "{why}, {:.1} % inside each end for the speed fluctuation",
                100.0 * SPEED_FLUCTUATION[1]
            ),
        ),
        _ => (
            [
                (1.0 - RPM_BELOW) * range.rpm_min,
                (1.0 + RPM_ABOVE) * range.rpm_max,
            ],
            format!(
                "the measured recordings' speeds {:.0}-{:.0} rpm, -{:.0} % / +{:.0} %",
                range.rpm_min,
                range.rpm_max,
                100.0 * RPM_BELOW,
                100.0 * RPM_ABOVE
            ),
        ),
    }
}

/// Refuse a plan that would simulate a standing (or reversed) shaft, or a speed the rig
/// file does not allow ([`allowed_speeds`]): every planned recording is expanded and its
/// speed over its whole length checked, before anything is simulated.
pub fn check_speeds(plan: &Plan, rig: &RigConfig) -> Result<()> {
    let allowed = allowed_speeds(rig);
    for run in plan.expand()? {
        let (lo, hi) = run.scenario.profile.range_rpm(run.scenario.seconds);
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0) {
            bail!(
                "plan {:?}, recording {}: it would simulate {lo:.1} rpm; a plan must simulate a turning shaft. \
                 Give its case an rpm, profile or random.rpm above 0",
                plan.name,
                run.stem
            );
        }
        if let Some(([a, b], why)) = &allowed {
            // a relative margin for ranges written with rounded numbers
            if lo < a * (1.0 - 1e-9) || hi > b * (1.0 + 1e-9) {
                bail!(
                    "plan {:?}, recording {}: it would simulate {lo:.1}-{hi:.1} rpm, outside {why}. \
                     Keep the plan's speeds inside it, or widen the range in the rig file",
                    plan.name,
                    run.stem
                );
            }
        }
    }
    Ok(())
}

/// Derive the plan: `recordings` per class of `seconds` each.
pub fn derive(
    rig: &RigConfig,
    range: &MeasuredRange,
    recordings: usize,
    seconds: f64,
) -> Result<Plan> {
    let sim = crate::sim::rig_simulation(rig)?;
    let fs = sim
        .sample_rate_hz
        .or(rig.acquisition.sample_rate_hz)
        .unwrap_or(10_000.0);
    let d = rig.bearing.ball_diameter_mm;
    let (rpm, speeds) = speed_basis(rig, range);
    let top_hz = (0.4 * fs).min(5000.0);
    let random = RandomRanges {
        // an induction motor slows under load (CWRU 0 -> 3 hp: 1797 -> 1730 rpm, -3.7 %):
        // faults may be recorded under more load than the healthy recordings
        rpm: Some(rpm),
        // EDM-like pits from 2 % to 10 % of the ball diameter (0.16-0.79 mm for 7.94 mm balls)
        defect_width_mm: Some([0.02 * d, 0.10 * d]),
        defect_depth_mm: Some([0.05, 0.3]),
        inner_race_position_deg: Some([0.0, 360.0]),
        slip: Some([0.0, 0.01]),
        slip_jitter: Some([0.005, 0.02]),
        // a small contact angle with an axial preload loads every ball: without it the
        // simulator leaves an outer-race defect away from the load zone silent
        contact_angle_deg: Some(CONTACT_ANGLE_DEG),
        preload_n: Some(PRELOAD_N),
        radial_load_n: Some([
            RADIAL_LOAD_N[0],
            RADIAL_LOAD_N[1].max(RADIAL_LOAD_ABOVE_RIG * sim.bearing.radial_load_n),
        ]),
        unbalance_scale: Some([0.3, 3.0]),
        noise_rms_m_s2: Some([0.1, 1.0]),
        resonance_hz: Some([(0.5 * top_hz).min(2000.0), top_hz]),
        resonance_damping: Some([0.02, 0.08]),
        // a fixed speed is read for every window: simulate it steady
        speed_fluctuation: (!matches!(rig.speed, SpeedConfig::Fixed { .. }))
            .then_some(SPEED_FLUCTUATION),
        speed_fluctuation_period_s: Some([0.5, 3.0]),
        ..RandomRanges::default()
    };
    let ball = range.labels.iter().any(|l| *l == Condition::Ball);
    let classes = &Condition::NAMES[..if ball { 4 } else { 3 }];
    let cases = classes
        .iter()
        .map(|c| PlanCase {
            name: None,
            faults: c.to_string(),
            rpm: None,
            profile: None,
            recordings,
            seconds: None,
            overrides: Default::default(),
            random: if *c == Condition::OuterRace {
                // all around the race: load zone (0) to opposite (+-180)
                RandomRanges {
                    outer_race_position_deg: Some([-180.0, 180.0]),
                    ..RandomRanges::default()
                }
            } else {
                RandomRanges::default()
            },
        })
        .collect();
    let plan = Plan {
        name: format!("adapt-{}", rig.machine.id),
        description: format!(
            "derived by rigmon adapt from rig {:?}; speeds {:.0}-{:.0} rpm from {speeds}",
            rig.machine.id, rpm[0], rpm[1]
        ),
        seed: 18,
        seconds,
        random,
        cases,
    };
    plan.validate()?;
    check_speeds(&plan, rig)?;
    Ok(plan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_covers_the_measured_speeds_and_every_class() {
        let rig = RigConfig::load(
            &std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("config/cwru-de.toml"),
        )
        .unwrap();
        let r = MeasuredRange::of(&[
            ("a".into(), 1796.0, 48_000.0, "healthy".into()),
            ("b".into(), 1772.0, 12_000.0, "inner_race".into()),
        ])
        .unwrap();
        let p = derive(&rig, &r, 10, 2.0).unwrap();
        let [lo, hi] = p.random.rpm.unwrap();
        // down to 6 % below the slowest recording (a motor slows under load), 3 % above the fastest
        assert!(lo < 0.95 * 1772.0 && hi > 1796.0 && lo > 1650.0 && hi < 1900.0);
        assert_eq!(p.cases.len(), 3);
        assert_eq!(p.totals(), (30, 60.0));
        // text form parses back as a plan
        let text = toml::to_string(&p).unwrap();
        assert_eq!(Plan::parse(&text).unwrap(), p);
        // every draw carries an axial preload and a contact angle > 0, so outer-race defects
        // all around the race make impacts
        let [a_lo, _] = p.random.contact_angle_deg.unwrap();
        let [f_lo, _] = p.random.preload_n.unwrap();
        assert!(a_lo > 0.0 && f_lo > 0.0, "{:?}", p.random);
        let runs = p.expand().unwrap();
        assert!(runs.iter().all(|r| {
            let o = &r.scenario.overrides;
            o.preload_n.is_some_and(|f| f >= f_lo) && o.contact_angle_deg.is_some_and(|a| a >= a_lo)
        }));
        let r = MeasuredRange::of(&[("a".into(), 1796.0, 48_000.0, "ball".into())]).unwrap();
        assert_eq!(derive(&rig, &r, 10, 2.0).unwrap().cases.len(), 4);
    }

    #[test]
    fn the_radial_load_range_covers_the_rig_files_own_load() {
        let dir =
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config");
        let r = MeasuredRange::of(&[("a".into(), 1500.0, 97_656.0, "healthy".into())]).unwrap();
        // the CWRU rig keeps the simulator's default 60 N: the default range
        let de = RigConfig::load(&dir.join("cwru-de.toml")).unwrap();
        assert_eq!(
            derive(&de, &r, 10, 2.0).unwrap().random.radial_load_n,
            Some(RADIAL_LOAD_N)
        );
        // the MFPT rig states 1,200 N (270 lbs): drawn up to 1.5x that
        let mfpt = RigConfig::load(&dir.join("mfpt.toml")).unwrap();
        let [lo, hi] = derive(&mfpt, &r, 10, 2.0)
            .unwrap()
            .random
            .radial_load_n
            .unwrap();
        assert_eq!((lo, hi), (0.0, 1800.0));
    }

    fn cwru_de() -> RigConfig {
        RigConfig::load(
            &std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("config/cwru-de.toml"),
        )
        .unwrap()
    }

    #[test]
    fn in_estimate_mode_the_plan_spans_the_rigs_declared_range() {
        let mut rig = cwru_de();
        rig.speed = SpeedConfig::Estimate {
            min_rpm: 500.0,
            max_rpm: 1500.0,
            check_within_percent: 0.0,
        };
        // recordings at 900 rpm only: the plan still covers what the rig file declares
        let r = MeasuredRange::of(&[("h".into(), 900.0, 51_200.0, "healthy".into())]).unwrap();
        let p = derive(&rig, &r, 10, 2.0).unwrap();
        let [lo, hi] = p.random.rpm.unwrap();
        let f = SPEED_FLUCTUATION[1];
        assert!(
            (lo - 500.0 / (1.0 - f)).abs() < 1e-9 && (hi - 1500.0 / (1.0 + f)).abs() < 1e-9,
            "{lo}-{hi}"
        );
        assert!(
            p.description.contains("estimate range"),
            "{}",
            p.description
        );
        // a fixed speed is simulated at that speed
        rig.speed = SpeedConfig::Fixed {
            rpm: 900.0,
            check_within_percent: 0.0,
        };
        assert_eq!(
            derive(&rig, &r, 10, 2.0).unwrap().random.rpm,
            Some([900.0, 900.0])
        );
    }

    #[test]
    fn a_standing_shaft_or_a_speed_the_rig_forbids_is_refused_before_simulation() {
        let mut rig = cwru_de();
        let e = MeasuredRange::of(&[
            ("ok.mat".into(), 1796.0, 12_000.0, "healthy".into()),
            ("stopped.mat".into(), 0.0, 12_000.0, "healthy".into()),
        ])
        .unwrap_err()
        .to_string();
        assert!(e.contains("stopped.mat") && e.contains("0 rpm"), "{e}");
        let r = MeasuredRange::of(&[("h".into(), 1796.0, 12_000.0, "healthy".into())]).unwrap();
        let mut p = derive(&rig, &r, 4, 2.0).unwrap();
        // a case at 0 rpm (what a plan built from an unknown speed used to simulate)
        p.random.rpm = None;
        for c in &mut p.cases {
            c.rpm = Some(1796.0);
        }
        p.cases[0].rpm = Some(0.0);
        let e = format!("{:#}", check_speeds(&p, &rig).unwrap_err());
        assert!(
            e.contains("c00_healthy_0rpm_0000") && e.contains("turning shaft"),
            "{e}"
        );
        // estimate mode: a plan outside min_rpm..max_rpm
        rig.speed = SpeedConfig::Estimate {
            min_rpm: 500.0,
            max_rpm: 1500.0,
            check_within_percent: 0.0,
        };
        for c in &mut p.cases {
            c.rpm = None;
        }
        p.random.rpm = Some([400.0, 900.0]);
        let e = format!("{:#}", check_speeds(&p, &rig).unwrap_err());
        assert!(
            e.contains("outside the rig file's [speed] estimate range 500-1500 rpm"),
            "{e}"
        );
        // inside, with room for the plan's speed fluctuation
        p.random.rpm = plannable_speeds(&rig);
        check_speeds(&p, &rig).unwrap();
    }
}
