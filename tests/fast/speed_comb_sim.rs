//! A bearing's comb is not the shaft on the project's own simulator (issue 34): an outer race
//! whose machine shows no shaft line of its own (the shipped LUT rig's `[simulation]` has no
//! shaft-order lines, so neither the raw spectrum nor the envelope has a line at 1x), its
//! tacho dropped, read by the tracker as `[speed] source = "estimate"` runs it (300-3600 rpm,
//! the rig's bearing, 1 s windows every 0.5 s). Cases other than the shipped replay's (LUT
//! bearing at 588 rpm): the LUT bearing at 450 rpm and the CWRU drive end's 6205 (BPFO 3.58
//! orders, from config/cwru-de.toml) in the LUT rig at 900 rpm. Before the comb without its
//! first line was read as the bearing's train (`speed_comb::bare_comb`), both read the BPFO
//! comb's fundamental as the shaft (2066 and 3226 rpm).

use crate::common::rig;
use rigmon::config::{ChannelKind, RigConfig};
use rigmon::dsp::fault_family::FamilySettings;
use rigmon::dsp::speed_tracker::{SpeedTracker, TrackerSettings};
use rigmon::sim::Scenario;
use rigmon::vocabulary::Condition;

/// Every window's speed (rpm) once the tracker's history is full.
fn tracked(r: &RigConfig, rpm: f64, seed: u64) -> Vec<f64> {
    let rec = rigmon::sim::simulate(
        r,
        &Scenario::constant(&[Condition::OuterRace], rpm, 12.0, seed),
    )
    .unwrap();
    let x = &rec.channel("vertical").unwrap().samples;
    let settings = TrackerSettings {
        min_rpm: 300.0,
        max_rpm: 3600.0,
        hint: None,
        families: Some(FamilySettings {
            orders: r.bearing.fault_orders(),
            band_top_hz: r.features.lowpass_hz,
        }),
    };
    let mut tr = SpeedTracker::new(settings, rec.sample_rate).unwrap();
    let (window, hop) = (rec.sample_rate as usize, rec.sample_rate as usize / 2);
    let (mut fed, mut end, mut out) = (0, window, Vec::new());
    while end <= x.len() {
        tr.push(fed as u64, &x[fed..end]);
        fed = end;
        if let Ok(e) = tr.estimate() {
            if end as f64 / rec.sample_rate >= tr.history_s() {
                out.push(e.rpm);
            }
        }
        end += hop;
    }
    out
}

fn lut_without_tacho() -> RigConfig {
    let mut r = rig("lut-rig.toml");
    r.channels.retain(|c| c.kind != ChannelKind::Tacho);
    r
}

fn every_window_within_half_a_percent(name: &str, r: &RigConfig, rpm: f64, seed: u64) {
    let w = tracked(r, rpm, seed);
    eprintln!("{name} at {rpm} rpm: {w:.1?}");
    assert!(w.len() >= 10, "{name}: {} windows", w.len());
    for v in w {
        assert!(
            (v / rpm - 1.0).abs() <= 0.005,
            "{name} at {rpm} rpm read {v:.1}"
        );
    }
}

#[test]
fn an_outer_race_comb_without_a_shaft_line_is_the_bearings_train() {
    every_window_within_half_a_percent("LUT bearing", &lut_without_tacho(), 450.0, 5);
    let mut r = lut_without_tacho();
    r.bearing = rig("cwru-de.toml").bearing;
    every_window_within_half_a_percent("CWRU 6205", &r, 900.0, 5);
}
