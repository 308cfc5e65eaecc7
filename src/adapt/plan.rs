//! The dataset plan `rigmon adapt` derives from a rig file and the measured recordings of
//! that machine: the speed range the recordings span (-6 % to +3 %: a motor slows under load), defect sizes scaled to the
//! bearing's balls, outer-race defects all around the race, inner-race defects at any angle,
//! an axial preload with a small contact angle (so every ball carries load and an outer-race
//! defect away from the radial load zone still makes impacts, as on the CWRU motor whose
//! 3 and 12 o'clock faults show BPFO lines; `config/plans/cwru-preload.toml`), a radial load,
//! slip, unbalance, noise, resonance and speed-fluctuation ranges wide enough to cover an
//! unknown machine. Where calibration fitted a parameter, `rigmon dataset
//! --calibrated spread` semantics move these ranges onto the fitted value (see
//! [`crate::sim::dataset::CalibratedDraws::Spread`]). Classes: healthy, outer race, inner race,
//! plus ball when the measured labels hold a ball record.

use crate::config::RigConfig;
use crate::sim::plan::{Plan, PlanCase, RandomRanges};
use anyhow::{bail, Result};
use serde::Serialize;

/// How far below the slowest measured speed the derived plan draws (fraction).
pub const RPM_BELOW: f64 = 0.06;
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
    /// From (rpm, sample rate, label) per recording.
    pub fn of(items: &[(f64, f64, String)]) -> Result<MeasuredRange> {
        if items.is_empty() {
            bail!("no measured recording to derive a dataset plan from");
        }
        let rpm_min = items.iter().map(|i| i.0).fold(f64::INFINITY, f64::min);
        let rpm_max = items.iter().map(|i| i.0).fold(0.0, f64::max);
        if !(rpm_min.is_finite() && rpm_min > 0.0) {
            bail!("a measured recording has no usable speed ({rpm_min} rpm)");
        }
        let mut sample_rates_hz: Vec<f64> = items.iter().map(|i| i.1).collect();
        sample_rates_hz.sort_by(f64::total_cmp);
        sample_rates_hz.dedup();
        let mut labels: Vec<String> = items.iter().map(|i| i.2.clone()).collect();
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
    let top_hz = (0.4 * fs).min(5000.0);
    let random = RandomRanges {
        // an induction motor slows under load (CWRU 0 -> 3 hp: 1797 -> 1730 rpm, -3.7 %):
        // faults may be recorded under more load than the healthy recordings
        rpm: Some([(1.0 - RPM_BELOW) * range.rpm_min, 1.03 * range.rpm_max]),
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
        speed_fluctuation: Some([0.0, 0.005]),
        speed_fluctuation_period_s: Some([0.5, 3.0]),
        ..RandomRanges::default()
    };
    let mut classes = vec!["healthy", "outer_race", "inner_race"];
    if range.labels.iter().any(|l| l == "ball") {
        classes.push("ball");
    }
    let cases = classes
        .into_iter()
        .map(|c| PlanCase {
            name: None,
            faults: c.to_string(),
            rpm: None,
            profile: None,
            recordings,
            seconds: None,
            overrides: Default::default(),
            random: if c == "outer_race" {
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
            "derived by rigmon adapt from rig {:?} and measured recordings at {:.0}-{:.0} rpm",
            rig.machine.id, range.rpm_min, range.rpm_max
        ),
        seed: 18,
        seconds,
        random,
        cases,
    };
    plan.validate()?;
    Ok(plan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_covers_the_measured_speeds_and_every_class() {
        let rig = RigConfig::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cwru-de.toml"),
        )
        .unwrap();
        let r = MeasuredRange::of(&[
            (1796.0, 48_000.0, "healthy".into()),
            (1772.0, 12_000.0, "inner_race".into()),
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
        let r = MeasuredRange::of(&[(1796.0, 48_000.0, "ball".into())]).unwrap();
        assert_eq!(derive(&rig, &r, 10, 2.0).unwrap().cases.len(), 4);
    }

    #[test]
    fn the_radial_load_range_covers_the_rig_files_own_load() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
        let r = MeasuredRange::of(&[(1500.0, 97_656.0, "healthy".into())]).unwrap();
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
}
