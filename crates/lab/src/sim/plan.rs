//! Dataset plans (`config/plans/*.toml`): cases (faults, speed, how many recordings of how
//! long) and optional random ranges drawn per recording (defect size, slip, load, contact
//! angle, noise, resonance, speed, speed fluctuation). A plan expands deterministically into
//! named scenarios: the same plan and seed always give the same dataset.

use super::profile::SpeedProfile;
use super::scenario::{label_of, Overrides, Scenario};
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Uniform ranges `[lo, hi]`; a missing key keeps the rig's value.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomRanges {
    pub rpm: Option<[f64; 2]>,
    pub defect_width_mm: Option<[f64; 2]>,
    pub defect_depth_mm: Option<[f64; 2]>,
    pub outer_race_position_deg: Option<[f64; 2]>,
    pub inner_race_position_deg: Option<[f64; 2]>,
    pub slip: Option<[f64; 2]>,
    pub slip_jitter: Option<[f64; 2]>,
    pub contact_angle_deg: Option<[f64; 2]>,
    pub radial_load_n: Option<[f64; 2]>,
    pub radial_clearance_mm: Option<[f64; 2]>,
    /// Axial preload, N: with a contact angle > 0 it loads every ball, so an outer-race
    /// defect away from the radial load zone still makes impacts (as on real rigs whose
    /// bearings carry a wave spring or an axial load).
    pub preload_n: Option<[f64; 2]>,
    pub unbalance_scale: Option<[f64; 2]>,
    pub noise_rms_m_s2: Option<[f64; 2]>,
    pub resonance_hz: Option<[f64; 2]>,
    pub resonance_damping: Option<[f64; 2]>,
    /// Sinusoidal speed fluctuation, fraction of the speed (0.01 = 1 %).
    pub speed_fluctuation: Option<[f64; 2]>,
    /// Period of the speed fluctuation, s.
    pub speed_fluctuation_period_s: Option<[f64; 2]>,
}

impl RandomRanges {
    /// Case ranges over plan ranges.
    fn merged(&self, over: &RandomRanges) -> RandomRanges {
        macro_rules! pick {
            ($($f:ident),*) => { RandomRanges { $($f: over.$f.or(self.$f)),* } };
        }
        pick!(
            rpm,
            defect_width_mm,
            defect_depth_mm,
            outer_race_position_deg,
            inner_race_position_deg,
            slip,
            slip_jitter,
            contact_angle_deg,
            radial_load_n,
            radial_clearance_mm,
            preload_n,
            unbalance_scale,
            noise_rms_m_s2,
            resonance_hz,
            resonance_damping,
            speed_fluctuation,
            speed_fluctuation_period_s
        )
    }

    fn check(&self, whence: &str) -> Result<()> {
        let v = serde_json::to_value(self)?;
        for (k, r) in v.as_object().into_iter().flatten() {
            if let Some(a) = r.as_array() {
                let (lo, hi) = (
                    a[0].as_f64().unwrap_or(f64::NAN),
                    a[1].as_f64().unwrap_or(f64::NAN),
                );
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    bail!("{whence}.{k} = [{lo}, {hi}]: need two numbers with lo <= hi");
                }
            }
        }
        Ok(())
    }
}

impl RandomRanges {
    /// The range of a plan key (`noise_rms_m_s2`, `resonance_hz`, ...), if the key exists.
    fn range_mut(&mut self, key: &str) -> Option<&mut Option<[f64; 2]>> {
        Some(match key {
            "slip" => &mut self.slip,
            "contact_angle_deg" => &mut self.contact_angle_deg,
            "unbalance_scale" => &mut self.unbalance_scale,
            "noise_rms_m_s2" => &mut self.noise_rms_m_s2,
            "resonance_hz" => &mut self.resonance_hz,
            "resonance_damping" => &mut self.resonance_damping,
            _ => return None,
        })
    }
}

/// How a plan range is moved onto a calibrated value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Recentre {
    /// Keep the width, centre on the value (clamped at 0): slip, contact angle, frequency.
    Shift,
    /// Keep the ratio hi/lo, put the geometric centre on the value: noise, damping, scales.
    Scale,
}

/// The plan keys a calibrated effect sets, with the value the fitted effect gives each
/// (from its `[calibration] effects` entry) and how a range moves onto it. Effects that no
/// plan key draws (line interference, looseness, subharmonics, looseness_impacts, speed
/// fluctuation) have none: they stay in the calibrated `[simulation]` section, which every
/// planned recording is simulated with.
pub fn calibrated_keys(effect: &toml::Table) -> Vec<(&'static str, f64, Recentre)> {
    let num = |k: &str| effect.get(k).and_then(|v| v.as_float());
    let name = effect.get("name").and_then(|n| n.as_str()).unwrap_or("");
    let keys: Vec<(&'static str, Option<f64>, Recentre)> = match name {
        "slip" => vec![("slip", num("slip"), Recentre::Shift)],
        "contact_angle" => vec![(
            "contact_angle_deg",
            num("contact_angle_deg"),
            Recentre::Shift,
        )],
        "resonance" => vec![
            ("resonance_hz", num("hz"), Recentre::Shift),
            ("resonance_damping", num("damping"), Recentre::Scale),
        ],
        "noise" => vec![("noise_rms_m_s2", num("noise_rms_m_s2"), Recentre::Scale)],
        // the fitted shaft lines sit on top of the rotor's own unbalance at scale 1
        "unbalance" => vec![("unbalance_scale", Some(1.0), Recentre::Scale)],
        _ => vec![],
    };
    keys.into_iter()
        .filter_map(|(k, v, how)| v.filter(|v| v.is_finite()).map(|v| (k, v, how)))
        .collect()
}

fn recentre([lo, hi]: [f64; 2], value: f64, how: Recentre) -> [f64; 2] {
    match how {
        Recentre::Shift => {
            let half = 0.5 * (hi - lo);
            let lo = (value - half).max(0.0);
            [lo, lo.max(value + half)]
        }
        Recentre::Scale if lo > 0.0 && value > 0.0 => {
            let half = (hi / lo).sqrt();
            [value / half, value * half]
        }
        Recentre::Scale => [value, value],
    }
}

fn draw(rng: &mut StdRng, r: Option<[f64; 2]>) -> Option<f64> {
    r.map(|[lo, hi]| {
        if hi > lo {
            rng.random_range(lo..=hi)
        } else {
            lo
        }
    })
}

/// One group of recordings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanCase {
    /// Name used in file names (default: label and speed).
    #[serde(default)]
    pub name: Option<String>,
    /// `healthy`, `outer_race`, `inner_race`, `ball`, or a comma-separated compound.
    pub faults: String,
    /// Constant speed (rpm) unless `profile` is given or `random.rpm` is set.
    #[serde(default)]
    pub rpm: Option<f64>,
    #[serde(default)]
    pub profile: Option<SpeedProfile>,
    pub recordings: usize,
    /// Length of each recording, s (default: the plan's `seconds`).
    #[serde(default)]
    pub seconds: Option<f64>,
    #[serde(default)]
    pub overrides: Overrides,
    #[serde(default)]
    pub random: RandomRanges,
}

/// A dataset plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub seed: u64,
    /// Default recording length, s.
    #[serde(default = "default_seconds")]
    pub seconds: f64,
    /// Ranges drawn for every recording of every case (cases may override).
    #[serde(default)]
    pub random: RandomRanges,
    #[serde(rename = "case")]
    pub cases: Vec<PlanCase>,
}

fn default_seconds() -> f64 {
    1.0
}

/// A scenario with its output file stem.
#[derive(Debug, Clone)]
pub struct PlannedRun {
    pub stem: String,
    pub scenario: Scenario,
}

impl PlannedRun {
    /// Keep a calibrated rig's effects (names of its `[calibration] effects`): drop the
    /// plan's draws of the parameters those effects set, so a plan cannot undo a calibration.
    /// A calibrated `speed_fluctuation` turns a plan's sine profile back into its constant
    /// speed (the simulator then applies `[simulation.speed_fluctuation]`). Returns the plan
    /// keys dropped.
    pub fn keep_calibrated(&mut self, effects: &[&str]) -> Vec<&'static str> {
        let o = &mut self.scenario.overrides;
        let mut dropped = Vec::new();
        for e in effects {
            match *e {
                "slip" => dropped.extend(o.slip.take().map(|_| "slip")),
                "contact_angle" => {
                    dropped.extend(o.contact_angle_deg.take().map(|_| "contact_angle_deg"))
                }
                "resonance" => {
                    dropped.extend(o.resonance_hz.take().map(|_| "resonance_hz"));
                    dropped.extend(o.resonance_damping.take().map(|_| "resonance_damping"));
                }
                "unbalance" => dropped.extend(o.unbalance_scale.take().map(|_| "unbalance_scale")),
                "noise" => dropped.extend(o.noise_rms_m_s2.take().map(|_| "noise_rms_m_s2")),
                "speed_fluctuation" => {
                    if let SpeedProfile::Sine { rpm, .. } = self.scenario.profile {
                        self.scenario.profile = SpeedProfile::Constant { rpm };
                        dropped.push("speed_fluctuation");
                    }
                }
                _ => {}
            }
        }
        dropped
    }
}

/// SplitMix64 step: independent, reproducible seeds per (case, recording).
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Plan {
    pub fn load(path: &Path) -> Result<Plan> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read plan {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("in plan {}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Plan> {
        let plan: Plan = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        plan.validate()?;
        Ok(plan)
    }

    pub fn validate(&self) -> Result<()> {
        if self.cases.is_empty() {
            bail!("the plan has no [[case]]; add at least one");
        }
        if !(self.seconds > 0.0) {
            bail!("seconds = {}: must be positive", self.seconds);
        }
        self.random.check("random")?;
        for (i, c) in self.cases.iter().enumerate() {
            Condition::parse_faults(&c.faults).with_context(|| format!("case[{i}].faults"))?;
            if c.rpm.is_none()
                && c.profile.is_none()
                && self.random.rpm.is_none()
                && c.random.rpm.is_none()
            {
                bail!(
                    "case[{i}] ({}) has no speed: give rpm, profile or random.rpm",
                    c.faults
                );
            }
            if c.recordings == 0 {
                bail!("case[{i}].recordings = 0: give at least 1");
            }
            c.random.check(&format!("case[{i}].random"))?;
        }
        Ok(())
    }

    /// Move the plan's (and every case's) range of `key` onto `value`, keeping its spread
    /// ([`Recentre`]); the dataset then varies a calibrated parameter around its fitted value
    /// instead of either ignoring the calibration or fixing the value. Returns the plan-level
    /// range after the move (or the first case's), `None` when no range draws `key`.
    pub fn recentre(&mut self, key: &str, value: f64, how: Recentre) -> Option<[f64; 2]> {
        let mut moved = None;
        let ranges =
            std::iter::once(&mut self.random).chain(self.cases.iter_mut().map(|c| &mut c.random));
        for r in ranges {
            if let Some(Some(range)) = r.range_mut(key) {
                *range = recentre(*range, value, how);
                moved = moved.or(Some(*range));
            }
        }
        moved
    }

    /// Total recordings and seconds of signal.
    pub fn totals(&self) -> (usize, f64) {
        let n = self.cases.iter().map(|c| c.recordings).sum();
        let s = self
            .cases
            .iter()
            .map(|c| c.recordings as f64 * c.seconds.unwrap_or(self.seconds))
            .sum();
        (n, s)
    }

    /// Expand into scenarios (deterministic for the plan's seed).
    pub fn expand(&self) -> Result<Vec<PlannedRun>> {
        let mut out = Vec::new();
        for (ci, c) in self.cases.iter().enumerate() {
            let faults = Condition::parse_faults(&c.faults)?;
            let label = label_of(&faults);
            let ranges = self.random.merged(&c.random);
            let seconds = c.seconds.unwrap_or(self.seconds);
            for r in 0..c.recordings {
                let seed = mix(mix(self.seed ^ 0xA5A5_0000)
                    ^ mix(ci as u64 + 1)
                    ^ (r as u64).wrapping_mul(0x1000_0001));
                let mut rng = StdRng::seed_from_u64(seed);
                let mut o = c.overrides.clone();
                macro_rules! set {
                    ($($f:ident),*) => { $( if let Some(v) = draw(&mut rng, ranges.$f) { o.$f = Some(v); } )* };
                }
                set!(
                    defect_width_mm,
                    defect_depth_mm,
                    outer_race_position_deg,
                    inner_race_position_deg,
                    slip,
                    slip_jitter,
                    contact_angle_deg,
                    radial_load_n,
                    radial_clearance_mm,
                    unbalance_scale,
                    noise_rms_m_s2,
                    resonance_hz,
                    resonance_damping,
                    preload_n
                );
                let rpm = draw(&mut rng, ranges.rpm).or(c.rpm);
                let fluct = draw(&mut rng, ranges.speed_fluctuation);
                let period = draw(&mut rng, ranges.speed_fluctuation_period_s).unwrap_or(2.0);
                let profile = match (&c.profile, rpm) {
                    (Some(p), None) => p.clone(),
                    (_, Some(rpm)) => match fluct {
                        Some(f) if f > 0.0 => SpeedProfile::Sine {
                            rpm,
                            amplitude_rpm: f * rpm,
                            period_s: period,
                        },
                        _ => SpeedProfile::Constant { rpm },
                    },
                    (None, None) => bail!("case[{ci}] has no speed"),
                };
                let case_name = c.name.clone().unwrap_or_else(|| match &c.profile {
                    Some(_) => label.to_string(),
                    None => format!("{label}_{:.0}rpm", c.rpm.unwrap_or(0.0)),
                });
                let stem = format!("c{ci:02}_{case_name}_{r:04}");
                let mut md = std::collections::BTreeMap::new();
                md.insert("plan".to_string(), self.name.clone());
                md.insert("plan_case".to_string(), case_name.clone());
                md.insert("plan_index".to_string(), r.to_string());
                let scenario = Scenario {
                    faults: faults.clone(),
                    profile,
                    seconds,
                    seed: seed ^ 0x5EED,
                    overrides: o,
                    metadata: md,
                };
                out.push(PlannedRun { stem, scenario });
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PLAN: &str = r#"
name = "t"
seed = 3
[random]
defect_width_mm = [0.2, 0.5]
[[case]]
faults = "inner_race"
rpm = 600
recordings = 3
[[case]]
faults = "healthy"
recordings = 2
random = { rpm = [500, 700] }
"#;

    #[test]
    fn expands_deterministically() {
        let p = Plan::parse(PLAN).unwrap();
        let a = p.expand().unwrap();
        let b = p.expand().unwrap();
        assert_eq!(a.len(), 5);
        assert_eq!(a[0].stem, "c00_inner_race_600rpm_0000");
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.scenario, y.scenario);
        }
        let w: Vec<f64> = a[..3]
            .iter()
            .map(|r| r.scenario.overrides.defect_width_mm.unwrap())
            .collect();
        assert!(w.iter().all(|&v| (0.2..=0.5).contains(&v)));
        assert!(w[0] != w[1]);
        let SpeedProfile::Constant { rpm } = a[3].scenario.profile else {
            panic!()
        };
        assert!((500.0..=700.0).contains(&rpm));
        assert_ne!(a[0].scenario.seed, a[1].scenario.seed);
    }

    #[test]
    fn calibrated_effects_survive_the_plan() {
        let p = Plan::parse(&PLAN.replace(
            "defect_width_mm = [0.2, 0.5]",
            "slip = [0.0, 0.01]\nspeed_fluctuation = [0.01, 0.02]",
        ))
        .unwrap();
        let mut runs = p.expand().unwrap();
        assert!(runs[0].scenario.overrides.slip.is_some());
        assert!(matches!(
            runs[0].scenario.profile,
            SpeedProfile::Sine { .. }
        ));
        let dropped = runs[0].keep_calibrated(&["slip", "speed_fluctuation"]);
        assert_eq!(dropped, vec!["slip", "speed_fluctuation"]);
        assert_eq!(runs[0].scenario.overrides.slip, None);
        assert_eq!(
            runs[0].scenario.profile,
            SpeedProfile::Constant { rpm: 600.0 }
        );
        assert!(runs[1].keep_calibrated(&["resonance"]).is_empty());
    }

    #[test]
    fn recentring_keeps_the_spread_around_the_calibrated_value() {
        let mut plan = Plan::parse(&PLAN.replace(
            "[random]\n",
            "[random]\nnoise_rms_m_s2 = [0.1, 1.0]\nresonance_hz = [2000.0, 5000.0]\n",
        ))
        .unwrap();
        let n = plan
            .recentre("noise_rms_m_s2", 0.04, Recentre::Scale)
            .unwrap();
        assert!((n[1] / n[0] - 10.0).abs() < 1e-9 && ((n[0] * n[1]).sqrt() - 0.04).abs() < 1e-12);
        assert_eq!(
            plan.recentre("resonance_hz", 4200.0, Recentre::Shift),
            Some([2700.0, 5700.0])
        );
        assert_eq!(
            plan.recentre("resonance_hz", 1000.0, Recentre::Shift),
            Some([0.0, 2500.0])
        );
        assert_eq!(plan.recentre("slip", 0.02, Recentre::Shift), None);
        let runs = plan.expand().unwrap();
        for r in &runs {
            let v = r.scenario.overrides.noise_rms_m_s2.unwrap();
            assert!((n[0]..=n[1]).contains(&v), "{v} outside {n:?}");
        }
        let e: toml::Table =
            toml::from_str("name = \"resonance\"\nhz = 4187.0\ndamping = 0.01").unwrap();
        assert_eq!(
            calibrated_keys(&e),
            vec![
                ("resonance_hz", 4187.0, Recentre::Shift),
                ("resonance_damping", 0.01, Recentre::Scale)
            ]
        );
    }

    #[test]
    fn errors_name_the_case() {
        let bad = PLAN.replace("faults = \"healthy\"", "faults = \"cage\"");
        let e = format!("{:#}", Plan::parse(&bad).unwrap_err());
        assert!(e.contains("case[1]") && e.contains("cage"), "{e}");
        let bad = PLAN.replace("recordings = 3", "recordings = 3\nrecs = 1");
        assert!(format!("{:#}", Plan::parse(&bad).unwrap_err()).contains("recs"));
    }
}
