//! The joint speed reading (issue 34, on by default) window by window on the seven shared
//! CWRU drive-end records of `dsp::cwru_estimated_speed_within_one_percent`, read without
//! their stored speed (300-3600 rpm, the rig's 6205, 1 s windows every 0.5 s as the
//! analysis runs them). That test checks the mean over a record; here every window counts:
//! a comb read as a bearing's train took whole stretches of 209_0 and 130@6_0 to 345-1077
//! rpm (docs/speed.md). The records were only read here; nothing was chosen on them.

use crate::common::{rig, shared_data};
use rigmon::dsp::fault_family::FamilySettings;
use rigmon::dsp::speed_tracker::{SpeedTracker, TrackedSpeed, TrackerSettings};
use rigmon::importers::{self, ImportOptions};

const RECORDS: [&str; 7] = [
    "97_Normal_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/IR/021/209_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/OR/007/@6/130@6_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/OR/021/@6/234_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/B/007/118_0.mat",
    "12k_Drive_End_Bearing_Fault_Data/B/021/222_0.mat",
];

/// Every window's speed over the record; `joint` false reads as before issue 34.
fn windows(x: &[f32], fs: f64, families: FamilySettings, joint: bool) -> Vec<TrackedSpeed> {
    let settings = TrackerSettings {
        min_rpm: 300.0,
        max_rpm: 3600.0,
        hint: None,
        families: Some(families),
    };
    let mut tr = SpeedTracker::new(settings, fs).unwrap();
    if !joint {
        tr.set_joint(false);
    }
    let (window, hop) = (fs.round() as usize, (0.5 * fs).round() as usize);
    let (mut fed, mut end, mut out) = (0, window, Vec::new());
    while end <= x.len() {
        tr.push(fed as u64, &x[fed..end]);
        fed = end;
        if let Ok(t) = tr.estimate() {
            out.push(t);
        }
        end += hop;
    }
    out
}

/// (largest, median) relative error of the windows against `rpm`, and how many windows
/// were uncertain.
fn spread(w: &[TrackedSpeed], rpm: f64) -> (f64, f64, usize) {
    let mut e: Vec<f64> = w.iter().map(|t| (t.rpm / rpm - 1.0).abs()).collect();
    e.sort_by(f64::total_cmp);
    let uncertain = w.iter().filter(|t| t.uncertain()).count();
    (e[e.len() - 1], e[e.len() / 2], uncertain)
}

/// Every window of every record is confident and within 1.5 % of the stored speed (the
/// stored rpm is itself a reading: the shaft lines sit up to 1.1 % from it in the first
/// window of 97_Normal_0 with either reading); the joint reading and the reading before it
/// are printed side by side.
#[test]
fn every_cwru_window_reads_the_shaft_with_the_joint_reading() {
    let rig = rig("cwru-de.toml");
    let families = FamilySettings {
        orders: rig.bearing.fault_orders(),
        band_top_hz: rig.features.lowpass_hz,
    };
    for file in RECORDS {
        let path = shared_data().join("cwru").join(file);
        let rec = importers::load(&path, &rig, &ImportOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let stored = rec.rpm.expect("CWRU files store the rpm");
        let x = &rec.channel("DE").unwrap().samples;
        let now = windows(x, rec.sample_rate, families, true);
        let before = windows(x, rec.sample_rate, families, false);
        assert!(now.len() >= 8, "{file}: {} windows", now.len());
        let (max, median, uncertain) = spread(&now, stored);
        let (bmax, bmedian, _) = spread(&before, stored);
        eprintln!(
            "{file}: joint max {:.2} % median {:.3} % ({} windows, {uncertain} uncertain); before max {:.2} % median {:.3} %",
            100.0 * max,
            100.0 * median,
            now.len(),
            100.0 * bmax,
            100.0 * bmedian
        );
        for (k, t) in now.iter().enumerate() {
            assert!(
                (t.rpm / stored - 1.0).abs() < 0.015 && !t.uncertain(),
                "{file} window {k}: {t:?} (stored {stored} rpm)"
            );
        }
    }
}
