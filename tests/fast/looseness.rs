//! Issue 39: a loose housing's landings (`[simulation.loose_impacts]`, the calibrate effect
//! `looseness_impacts`) are in what the simulator writes and stay in every dataset recording
//! a calibrated rig file gives (`rigmon dataset`, `adapt`'s plan), whatever the plan draws.

use crate::common::rig;
use rigmon::calibrate::{impacts, views::BAND_MIN_HZ};
use rigmon::config::simulation::LooseImpactsConfig;
use rigmon::config::RigConfig;
use rigmon::recording::Recording;
use rigmon::sim::{self, Scenario};

/// The `impacts` view (envelope of the broadband energy) of the vertical channel at `hz`, dB
/// above its local median less the view's threshold.
fn impacts_at(rec: &Recording, hz: f64) -> f64 {
    let v = impacts::measure(
        &rec.channel("vertical").unwrap().samples,
        rec.sample_rate,
        BAND_MIN_HZ,
    );
    let f = impacts::frequencies();
    let i = f.iter().position(|x| (x - hz).abs() < 0.5).unwrap();
    v[i]
}

/// At 1200 rpm a landing every other revolution is a 10 Hz comb in the `impacts` view (and
/// none at 15 Hz, between its lines); without the section there is no comb. A calibrated
/// rig file naming `looseness_impacts` keeps the landings in the dataset in both
/// `--calibrated` modes, with a plan that draws unbalance, noise and the resonance.
#[test]
fn landings_ring_every_other_revolution_and_reach_the_dataset() {
    let plain = rig("lut-rig.toml");
    let mut loose = plain.clone();
    loose.simulation.as_mut().unwrap().loose_impacts = Some(LooseImpactsConfig {
        ref_rpm: 1200.0,
        exponent: 1.0,
        impact_m_s2: 5.0,
        mode_hz: 900.0,
        damping: 0.04,
        horizontal_ratio: 0.5,
        phase_deg: 30.0,
        timing_jitter: 0.01,
    });
    let scenario = Scenario::constant(&[], 1200.0, 2.0, 5);
    let without = impacts_at(&sim::simulate(&plain, &scenario).unwrap(), 10.0);
    let check = |rig: &RigConfig, rec: &Recording, what: &str| {
        let (on, off) = (impacts_at(rec, 10.0), impacts_at(rec, 15.0));
        assert!(
            on > 10.0 && on > off + 10.0 && on > without + 10.0,
            "{what}: impacts at 10 Hz {on} dB, 15 Hz {off} dB, without landings {without} dB ({})",
            rig.machine.id
        );
    };
    check(
        &loose,
        &sim::simulate(&loose, &scenario).unwrap(),
        "simulate",
    );
    loose.calibration = Some(rigmon::config::CalibrationStamp {
        id: "cal-test".into(),
        effects: vec![toml::from_str("name = \"looseness_impacts\"\nimpact_m_s2 = 5.0").unwrap()],
    });
    let plan = sim::plan::Plan::parse(
        "name = \"loop\"\nseed = 2\nseconds = 2.0\n[random]\nunbalance_scale = [0.5, 2.0]\n\
         noise_rms_m_s2 = [0.1, 0.3]\nresonance_hz = [2000, 3000]\n[[case]]\n\
         faults = \"healthy\"\nrpm = 1200\nrecordings = 1\n",
    )
    .unwrap();
    for (mode, rec) in crate::sim::planned_recordings(&loose, &plan) {
        check(&loose, &rec, &format!("dataset {mode:?}"));
    }
}
