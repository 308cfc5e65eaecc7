//! Labelled faults shape the plan: each measured recording labelled with a fault gets plan
//! cases of its own, at its operating speed and with a defect as strong as the one measured.
//! Its strength is the rule's statistic for its fault family (the envelope-order band at the
//! fault order and twice it, over the median band, median over the windows:
//! [`crate::model::rule::EnvelopeRule`]); the defect width is the one whose simulated twin
//! (the calibrated rig at the recording's speed, the defect in the load zone, the plan's
//! mid-range load, preload and contact angle) gives the nearest statistic, from a log grid
//! over 0.4-16 % of the ball diameter ([`WIDTH_GRID`]). The shaped cases draw widths between
//! the neighbouring grid points, speeds within +-2 % of the measured one, outer-race
//! defects within +-30 deg of the load zone (where the width was fitted), and the plan's
//! other ranges; they take [`SHAPED_SHARE`] of their class's recordings, so the dataset keeps
//! its size. A recording whose family band does not stand the rule's threshold (3x) above
//! the median shows no measurable signature: its case keeps the plan's sizes and positions
//! and is only placed at its speed.

use super::plan::plannable_speeds;
use crate::config::RigConfig;
use crate::model::rule::RuleSettings;
use crate::recording::Recording;
use crate::sim::plan::{Plan, PlanCase, RandomRanges};
use crate::sim::Scenario;
use crate::vocabulary::Condition;
use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;

/// Defect widths tried, as fractions of the ball diameter (log spaced, ratio ~1.59, from a
/// slot the ball barely drops into to twice the plan's widest).
pub const WIDTH_GRID: [f64; 9] = [
    0.004, 0.0063, 0.01, 0.0159, 0.0252, 0.04, 0.0635, 0.1008, 0.16,
];
/// Fraction of a class's recordings given to the cases shaped by its labelled recordings.
pub const SHAPED_SHARE: f64 = 0.3;
/// Speed spread of a shaped case around the measured speed (fraction).
pub const SPEED_SPREAD: f64 = 0.02;
/// Outer-race position range of a shaped case, degrees from the load zone.
pub const LOAD_ZONE_DEG: [f64; 2] = [-30.0, 30.0];

/// One labelled fault recording and what it did to the plan.
#[derive(Debug, Clone, Serialize)]
pub struct ShapedFault {
    pub recording: String,
    pub label: String,
    pub rpm: f64,
    /// The rule's statistic of its fault family, median over its windows.
    pub measured_ratio: f64,
    /// The fitted defect width, mm (`None`: no signature to fit, see the module doc).
    pub fitted_width_mm: Option<f64>,
    /// The twin's statistic at the fitted width.
    pub simulated_ratio: Option<f64>,
    /// The fitted width is at an end of [`WIDTH_GRID`].
    pub at_grid_edge: bool,
    /// Name of its plan case and the recordings it holds.
    pub case: String,
    pub recordings: usize,
}

/// The rule's statistic for `label`'s fault family, as the analysis stage measures it on
/// every window ([`crate::dsp::fault_band_ratios::FaultBandRatios`]: the band at the fault
/// order and at twice it, over the median band); median over the recording's windows.
pub fn family_ratio(rec: &Recording, rig: &RigConfig, label: &str) -> Result<f64> {
    let windows = crate::analysis::analyze_recording(rec, rig)?;
    let mut v: Vec<f64> = windows
        .iter()
        .filter_map(|w| w.fault_bands.as_ref())
        .map(|b| match Condition::parse(label) {
            Some(Condition::InnerRace) => b.inner_race(),
            Some(Condition::Ball) => b.ball(),
            _ => b.outer_race(),
        })
        .collect();
    anyhow::ensure!(!v.is_empty(), "no window to measure");
    v.sort_by(f64::total_cmp);
    Ok(v[v.len() / 2])
}

fn mid(r: Option<[f64; 2]>) -> Option<f64> {
    r.map(|[a, b]| 0.5 * (a + b))
}

/// The twin's statistic with a defect `width_mm` wide.
fn twin_ratio(
    rig: &RigConfig,
    plan: &Plan,
    fault: Condition,
    label: &str,
    rpm: f64,
    width_mm: f64,
) -> Result<f64> {
    let r = &plan.random;
    let mut sc = Scenario::constant(&[fault], rpm, plan.seconds.max(2.0), 0x5A9E);
    let o = &mut sc.overrides;
    o.defect_width_mm = Some(width_mm);
    o.defect_depth_mm = mid(r.defect_depth_mm);
    o.outer_race_position_deg = Some(0.0);
    o.radial_load_n = mid(r.radial_load_n);
    o.preload_n = mid(r.preload_n);
    let fitted_angle = rig.calibration.as_ref().is_some_and(|c| {
        c.effects
            .iter()
            .any(|e| e.get("name").and_then(|n| n.as_str()) == Some("contact_angle"))
    });
    if !fitted_angle {
        o.contact_angle_deg = mid(r.contact_angle_deg);
    }
    let rec = crate::sim::simulate(rig, &sc)?;
    family_ratio(&rec, rig, label)
}

/// Fit one labelled recording: (width mm, twin ratio, at the grid's edge).
fn fit_width(
    rig: &RigConfig,
    plan: &Plan,
    fault: Condition,
    label: &str,
    rpm: f64,
    measured: f64,
) -> Result<(f64, f64, bool)> {
    let d = rig.bearing.ball_diameter_mm;
    let tried = WIDTH_GRID
        .par_iter()
        .map(|f| Ok((f * d, twin_ratio(rig, plan, fault, label, rpm, f * d)?)))
        .collect::<Result<Vec<(f64, f64)>>>()?;
    let gap = |r: f64| (r.max(1e-9).ln() - measured.max(1e-9).ln()).abs();
    let (k, &(w, r)) = tried
        .iter()
        .enumerate()
        .min_by(|a, b| gap(a.1 .1).total_cmp(&gap(b.1 .1)))
        .context("no width tried")?;
    Ok((w, r, k == 0 || k + 1 == tried.len()))
}

/// A file-name-safe case name.
fn case_name(label: &str, i: usize) -> String {
    format!("{label}_as_measured_{i}")
}

/// `plan` with cases shaped by the labelled fault recordings `faults` (recording name,
/// label, speed, the recording); `rig` is the calibrated rig. Healthy recordings are
/// ignored. Returns the plan and what each recording did.
pub fn shape(
    plan: &Plan,
    rig: &RigConfig,
    faults: &[(String, String, f64, &Recording)],
) -> Result<(Plan, Vec<ShapedFault>)> {
    let is_fault = |f: &&(String, String, f64, &Recording)| !Condition::is_healthy(&f.1);
    let labelled: Vec<&(String, String, f64, &Recording)> =
        faults.iter().filter(is_fault).collect();
    let mut out = plan.clone();
    if labelled.is_empty() {
        return Ok((out, Vec::new()));
    }
    let threshold = RuleSettings::default().threshold;
    let allowed = plannable_speeds(rig);
    let mut shaped = Vec::new();
    for (i, (name, label, rpm, rec)) in labelled.iter().enumerate() {
        let Some(class) = plan.cases.iter().position(|c| &c.faults == label) else {
            continue;
        };
        let siblings = labelled.iter().filter(|f| &f.1 == label).count();
        let total = plan.cases[class].recordings;
        let k = ((SHAPED_SHARE * total as f64 / siblings as f64).round() as usize).max(1);
        if out.cases[class].recordings <= k {
            continue;
        }
        let fault = Condition::parse_faults(label)?
            .first()
            .copied()
            .with_context(|| format!("label {label:?} of {name}"))?;
        let measured = family_ratio(rec, rig, label)
            .with_context(|| format!("the {label} signature of {name}"))?;
        let fitted = if measured >= threshold {
            Some(
                fit_width(rig, plan, fault, label, *rpm, measured)
                    .with_context(|| format!("fitting the defect of {name}"))?,
            )
        } else {
            None
        };
        let mut speeds = [(1.0 - SPEED_SPREAD) * rpm, (1.0 + SPEED_SPREAD) * rpm];
        if let Some([a, b]) = allowed {
            speeds = [speeds[0].clamp(a, b), speeds[1].clamp(a, b)];
        }
        let step = (WIDTH_GRID[1] / WIDTH_GRID[0]).sqrt();
        let random = RandomRanges {
            rpm: Some(speeds),
            defect_width_mm: fitted.map(|(w, ..)| [w / step, w * step]),
            outer_race_position_deg: (fitted.is_some() && *label == Condition::OuterRace)
                .then_some(LOAD_ZONE_DEG),
            ..RandomRanges::default()
        };
        out.cases[class].recordings -= k;
        let case = case_name(label, i);
        out.cases.push(PlanCase {
            name: Some(case.clone()),
            faults: label.to_string(),
            rpm: None,
            profile: None,
            recordings: k,
            seconds: None,
            overrides: Default::default(),
            random,
        });
        shaped.push(ShapedFault {
            recording: name.clone(),
            label: label.to_string(),
            rpm: *rpm,
            measured_ratio: measured,
            fitted_width_mm: fitted.map(|f| f.0),
            simulated_ratio: fitted.map(|f| f.1),
            at_grid_edge: fitted.is_some_and(|f| f.2),
            case,
            recordings: k,
        });
    }
    out.description += "; cases shaped by the labelled fault recordings";
    out.validate()?;
    super::plan::check_speeds(&out, rig)?;
    Ok((out, shaped))
}
