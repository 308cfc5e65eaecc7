//! `rigmon bench simulate`, its last part: adapt's two datasets (a plan on the rig and on a
//! calibrated copy whose calibration changed only a mode and the noise) simulated the way
//! before issue 37's third pass (each dataset on its own) and as a pair sharing each run's
//! mechanics (`sim::dataset_pair`), in the same run: wall seconds and the ratio.

use crate::config::RigConfig;
use crate::sim::dataset::{generate, CalibratedDraws};
use crate::sim::dataset_pair::{generate_pair, Ahead, DatasetJob};
use crate::sim::plan::Plan;
use anyhow::{Context, Result};
use std::path::Path;
use std::time::Instant;

/// Wall seconds of both ways and how many runs the pair shared.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PairTiming {
    pub recordings: usize,
    pub apart_s: f64,
    pub pair_s: f64,
    pub shared_runs: usize,
    /// apart / pair.
    pub ratio: f64,
}

impl PairTiming {
    /// The benchmark's line: both ways and their ratio.
    pub fn line(&self) -> String {
        format!(
            "adapt's two datasets of that plan (the rig and a copy whose calibration moved a mode and the noise), {} recordings: apart {:.2} s, as a pair {:.2} s ({} runs shared their mechanics): {:.2}x",
            self.recordings,
            self.apart_s,
            self.pair_s,
            self.shared_runs,
            self.ratio
        )
    }
}

/// The rig as a calibration that found a mode 20 % higher, twice as damped, and twice the
/// noise would leave it (the mechanics unchanged).
fn calibrated_copy(rig: &RigConfig) -> Result<RigConfig> {
    let mut cal = rig.clone();
    let mut sim = crate::sim::rig_simulation(&cal)?.clone();
    if let Some(r) = sim.structure.resonances.first_mut() {
        r.hz *= 1.2;
        r.damping *= 2.0;
    }
    sim.structure.noise_rms_m_s2 *= 2.0;
    cal.simulation = Some(sim);
    Ok(cal)
}

/// Time both ways on `plan` into folders under `dir` (removed afterwards).
pub fn time_both(rig: &RigConfig, plan: &Plan, dir: &Path) -> Result<PairTiming> {
    let cal = calibrated_copy(rig)?;
    let d = |s: &str| dir.join(s);
    let t0 = Instant::now();
    for (r, sub) in [(rig, "apart-zero"), (&cal, "apart-cal")] {
        generate(
            r,
            plan,
            &d(sub),
            "mcap",
            None,
            false,
            CalibratedDraws::Spread,
        )
        .with_context(|| format!("dataset into {}", d(sub).display()))?;
    }
    let apart_s = t0.elapsed().as_secs_f64();
    let (z, c) = (d("pair-zero"), d("pair-cal"));
    let t0 = Instant::now();
    let pair = generate_pair(
        [
            DatasetJob { rig, plan, dir: &z },
            DatasetJob {
                rig: &cal,
                plan,
                dir: &c,
            },
        ],
        Ahead::default(),
        "mcap",
        None,
        false,
        CalibratedDraws::Spread,
    )?;
    let pair_s = t0.elapsed().as_secs_f64();
    let _ = std::fs::remove_dir_all(dir);
    Ok(PairTiming {
        recordings: pair.first.recordings + pair.second.recordings,
        apart_s,
        pair_s,
        shared_runs: pair.shared_runs,
        ratio: apart_s / pair_s,
    })
}
