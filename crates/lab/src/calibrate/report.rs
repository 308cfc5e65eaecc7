//! Calibration outputs: the JSON object (`--json`; per recording the rate it was analysed
//! at and the rate it was recorded at), the Markdown summary, the calibrated rig
//! file (the rig's TOML with the calibrated `[simulation]` section and a `[calibration]` stamp
//! `{id, effects}`), and the calibration id (hash of the calibrated section and the inputs).

use super::error::{min_cut, ErrorComponent, ErrorParts};
use super::fit::{Outcome, Trial, FIT_CUT, HELD_CUT};
use super::measured::Measured;
use super::views::Views;
use crate::config::RigConfig;
use anyhow::{Context, Result};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use std::fmt::Write as _;
use std::path::Path;

/// `cal-` + 12 hex digits of SHA-256 over the calibrated section and the measured inputs.
pub fn calibration_id(o: &Outcome, ops: &[Measured]) -> String {
    let mut h = Sha256::new();
    h.update(serde_json::to_string(&o.calibrated).unwrap_or_default());
    for m in ops {
        h.update(m.name.as_bytes());
        h.update(m.label.as_bytes());
    }
    let d = h.finalize();
    format!(
        "cal-{}",
        d.iter()
            .take(6)
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    )
}

/// A sample rate for the Markdown report: whole Hz as they are, else to the mHz.
fn hz(v: f64) -> String {
    if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.3}")
    }
}

fn r3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

fn parts(e: &ErrorParts) -> Value {
    let mut m = serde_json::Map::new();
    for c in ErrorComponent::ALL {
        m.insert(c.name().into(), json!(r3(e.get(c))));
    }
    m.insert("total".into(), json!(r3(e.total)));
    Value::Object(m)
}

/// What each component compares, for the Markdown table.
fn description(c: ErrorComponent) -> &'static str {
    use ErrorComponent as C;
    match c {
        C::Env => "envelope order spectrum, mean dB",
        C::Peaks => "fault-order locations, per mille",
        C::Ratios => "harmonic and sideband ratios, summed dB / 10",
        C::Lines => "raw-spectrum lines of healthy recordings, summed dB / 10",
        C::Orders => "1x and 2x lines, mean dB",
        C::Harmonics => "shaft orders 3x-30x, summed dB / 10",
        C::Bands => "100 Hz band energies, mean dB",
        C::Modes => "dominant resonance location, 100 Hz bands",
        C::Floor => "absolute broadband floor, dB",
        C::Speed => "speed-deviation spectrum",
        C::Fractional => "sub-synchronous and fractional shaft orders, summed dB / 100",
        C::HalfOrders => "half-order lines 0.5x-3.5x (looseness, rub), summed dB / 10",
        C::Impacts => {
            "envelope spectrum of the band energy in Hz (healthy recordings), summed dB / 20"
        }
    }
}

/// A recording's landings once every two revolutions ([`super::landing_comb`]): the measured
/// comb's strongest band and its ratio there, and the twins' ratios in that band before and
/// after calibration.
fn landings(m: &Views, before: &Views, after: &Views) -> Value {
    match (m.landings.strongest(), m.landings.best_band_hz()) {
        (Some(k), Some((lo, hi))) => json!({
            "detected": m.landings.detected(),
            "band_hz": [lo.round(), hi.round()],
            "ratio": r3(m.landings.ratio[k]),
            "standing_lines": m.landings.standing_lines(),
            "levels_db": m.landings.levels_db[k].iter().map(|d| r3(*d)).collect::<Vec<_>>(),
            "ratio_before": r3(before.landings.ratio_in(k)),
            "ratio_after": r3(after.landings.ratio_in(k)),
        }),
        _ => Value::Null,
    }
}

/// Where an accepted `looseness_impacts` took its damping from the ring's half-power width
/// ([`super::ring_width`]), the line that says so.
fn ring_note(o: &Outcome, t: &Trial) -> Option<String> {
    let r = o.ring.filter(|_| t.name == "looseness_impacts")?;
    Some(format!(
        "  - damping {:.4} not searched: read from the half-power width ({:.1} Hz) of the mode \
         the fit part's healthy recordings ring at {:.0} Hz, {:.1} dB above its floor",
        r.damping,
        2.0 * r.damping * r.hz,
        r.hz,
        r.snr_db
    ))
}

/// The report object printed by `--json`.
pub fn json(rig: &RigConfig, o: &Outcome, ops: &[Measured], id: &str) -> Value {
    let effects: Vec<Value> = o
        .accepted
        .iter()
        .map(|t| {
            json!({"name": t.name, "params": t.params, "at_bound": t.at_bound, "refits": t.refits,
                   "error_before": r3(t.error_before),
                   "error_after": r3(t.error_after), "fit_before": r3(t.fit_before),
                   "fit_after": r3(t.fit_after), "held_before": r3(t.held_before),
                   "held_after": r3(t.held_after)})
        })
        .collect();
    let split: Vec<Value> = ops
        .iter()
        .zip(&o.fit_part)
        .map(|(m, f)| json!({"recording": m.name, "label": m.label, "rpm": (m.rpm * 10.0).round() / 10.0, "part": if *f {"fit"} else {"held_out"}}))
        .collect();
    let per: Vec<Value> = ops
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let b = super::error::pair(&o.measured_views[i], &o.views_before[i]);
            let a = super::error::pair(&o.measured_views[i], &o.views_after[i]);
            let v = &o.measured_views[i];
            json!({"recording": m.name, "seconds": (v.seconds * 1000.0).round() / 1000.0,
                   "segments": v.segments, "sample_rate_hz": m.recording.sample_rate,
                   "recorded_sample_rate_hz": m.recorded_sample_rate,
                   "before": parts(&b), "after": parts(&a),
                   "landings": landings(v, &o.views_before[i], &o.views_after[i])})
        })
        .collect();
    json!({
        "calibration_id": id,
        "recordings": per,
        "ring_width": o.ring,
        "rig": rig.machine.id,
        "error_before": r3(o.before.total),
        "error_after": r3(o.after.total),
        "components_before": parts(&o.before),
        "components_after": parts(&o.after),
        "effects": effects,
        "unexplained": o.unexplained,
        "rounds": o.rounds,
        "split": split,
        "timings": {"wall_s": o.wall_s, "measured_views_wall_s": o.measured_views_wall_s,
                    "stages": o.timings, "recordings": o.recording_times, "rounds": o.round_times},
        "acceptance": {"fit_cut_relative": FIT_CUT.0, "fit_cut_min_cuts": FIT_CUT.1,
                        "held_cut_relative": HELD_CUT.0, "held_cut_min_cuts": HELD_CUT.1,
                        "min_cuts_combined": "root of the sum of squares over the effect's own components",
                        "min_cut": ErrorComponent::ALL.iter().map(|&c| (c.name(), min_cut(c))).collect::<std::collections::BTreeMap<_, _>>()},
    })
}

/// The Markdown summary.
pub fn markdown(rig: &RigConfig, o: &Outcome, ops: &[Measured], id: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Calibration `{id}` of rig `{}`\n", rig.machine.id);
    let _ = writeln!(
        s,
        "Error (sum of components, mean over {} recordings): **{:.3} -> {:.3}**\n",
        ops.len(),
        o.before.total,
        o.after.total
    );
    s.push_str(&component_table(o));
    s.push_str(&split_table(o, ops));
    let _ = writeln!(s, "\n## Effects added (in order)\n");
    if o.accepted.is_empty() {
        let _ = writeln!(s, "None: no catalog effect passed the acceptance rule.");
    }
    for t in &o.accepted {
        let _ = writeln!(
            s,
            "- `{}` {:?}: all {:.3} -> {:.3}, fit {:.3} -> {:.3}, held-out {:.3} -> {:.3}",
            t.name,
            t.params,
            t.error_before,
            t.error_after,
            t.fit_before,
            t.fit_after,
            t.held_before,
            t.held_after
        );
        if let Some(why) = &t.preferred_over {
            let _ = writeln!(s, "  - preferred over {why}");
        }
        if let Some(note) = ring_note(o, t) {
            let _ = writeln!(s, "{note}");
        }
        if !t.at_bound.is_empty() {
            let _ = writeln!(
                s,
                "  - at a search bound (the bound, not the data, may have set it): {}",
                t.at_bound.join(", ")
            );
        }
    }
    s.push_str(&trial_table(o));
    let _ = writeln!(s, "\n## Unexplained\n");
    if o.unexplained.is_empty() {
        let _ = writeln!(
            s,
            "Nothing above the thresholds (lines/envelope 10 dB, bands 6 dB)."
        );
    } else {
        let _ = writeln!(s, "| location | unit | locked to | view | excess dB | recordings | usual causes (candidates, not findings) |\n|---|---|---|---|---|---|---|");
        for u in &o.unexplained {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                u.location,
                u.unit,
                u.locked_to,
                u.view,
                u.excess_db,
                u.recordings,
                u.candidates.join("; ")
            );
        }
    }
    let _ = writeln!(
        s,
        "\n![measured vs simulated](spectra.png)\n\n![residual](residual.png)\n\n\
         ![where looseness shows](looseness.png)"
    );
    s.push_str(&time_tables(o));
    s
}

/// Every trial of every round, with its wall time.
fn trial_table(o: &Outcome) -> String {
    let mut s = String::from("\n## Every trial, by round\n\n| round | effect | params | fit before -> after | held-out before -> after | accepted | wall s |\n|---|---|---|---|---|---|---|\n");
    for (r, round) in o.rounds.iter().enumerate() {
        for t in round {
            let _ = writeln!(
                s,
                "| {} | {} | {:?} | {:.3} -> {:.3} | {:.3} -> {:.3} | {} | {:.1} |",
                r + 1,
                t.name,
                t.params,
                t.fit_before,
                t.fit_after,
                t.held_before,
                t.held_after,
                if t.accepted { "yes" } else { "no" },
                t.seconds
            );
        }
    }
    s
}

/// Where the time went: wall time of the views and of each round, and per stage and
/// recording the summed time of every call (over all threads: about CPU time).
fn time_tables(o: &Outcome) -> String {
    let mut s = format!(
        "\n## Where the time went\n\n{:.1} s wall: measured views {:.1} s, then rounds of {}; stages summed over threads (about CPU time): {}.\n\n| recording | measured views s | engine s | sensor s | simulated views s | error s |\n|---|---|---|---|---|---|\n",
        o.wall_s,
        o.measured_views_wall_s,
        o.round_times
            .iter()
            .map(|r| match r.skipped.is_empty() {
                true => format!("{:.1} s", r.wall_s),
                false => format!("{:.1} s (not tried again: {})", r.wall_s, r.skipped.join(", ")),
            })
            .collect::<Vec<_>>()
            .join(", "),
        o.timings
            .iter()
            .map(|t| format!("{} {:.1} s ({} calls)", t.stage, t.seconds, t.calls))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for r in &o.recording_times {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} |",
            r.recording, r.measured_views_s, r.engine_s, r.sensor_s, r.simulated_views_s, r.error_s
        );
    }
    s
}

/// The error components of the Markdown summary, before and after.
fn component_table(o: &Outcome) -> String {
    let mut s = String::from("| component | before | after |\n|---|---|---|\n");
    for c in ErrorComponent::ALL {
        let (before, after) = (o.before.get(c), o.after.get(c));
        let _ = writeln!(s, "| {c} ({}) | {before:.3} | {after:.3} |", description(c));
    }
    s
}

/// The split table of the Markdown summary: each recording's part, what of it was analysed
/// and at which rate (and the rate it was recorded at).
fn split_table(o: &Outcome, ops: &[Measured]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "\n## Split (checkerboard by recording)\n\n| recording | label | rpm | seconds analysed (segments) | analysed at, Hz (recorded at) | part |\n|---|---|---|---|---|---|");
    for ((m, f), v) in ops.iter().zip(&o.fit_part).zip(&o.measured_views) {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.2} ({}) | {} ({}) | {} |",
            m.name,
            m.label,
            m.rpm,
            v.seconds,
            v.segments,
            hz(m.recording.sample_rate),
            hz(m.recorded_sample_rate),
            if *f { "fit" } else { "held out" }
        );
    }
    if ops
        .iter()
        .any(|m| m.recording.sample_rate < m.recorded_sample_rate)
    {
        let _ = writeln!(
            s,
            "\nRecordings made faster than the simulator's output rate were resampled to it (band-limited) before they were analysed: the classifier is trained on signals at that rate."
        );
    }
    s
}

/// Write the calibrated rig file: the original TOML with `[simulation]` replaced and a
/// `[calibration]` stamp. The result is parsed back as a rig file before it is written.
pub fn write_rig(rig_path: &Path, out: &Path, o: &Outcome, id: &str) -> Result<()> {
    let text = std::fs::read_to_string(rig_path)
        .with_context(|| format!("cannot read rig file {}", rig_path.display()))?;
    let mut table: toml::Table = toml::from_str(&text)
        .with_context(|| format!("rig file {} is not valid TOML", rig_path.display()))?;
    table.insert(
        "simulation".into(),
        toml::Value::Table(
            toml::Table::try_from(&o.calibrated).context("serialising [simulation]")?,
        ),
    );
    let mut effects = toml::value::Array::new();
    for t in &o.accepted {
        let mut e = toml::Table::new();
        e.insert("name".into(), toml::Value::String(t.name.clone()));
        for (k, v) in &t.params {
            e.insert(k.clone(), toml::Value::Float(*v));
        }
        effects.push(toml::Value::Table(e));
    }
    let mut cal = toml::Table::new();
    cal.insert("id".into(), toml::Value::String(id.into()));
    cal.insert("effects".into(), toml::Value::Array(effects));
    table.insert("calibration".into(), toml::Value::Table(cal));
    let body = toml::to_string(&table).context("serialising the calibrated rig")?;
    let head = format!(
        "# Calibrated by `rigmon calibrate` ({id}) from {}; the [simulation] section carries the\n# fitted effects, [calibration] names them.\n\n",
        rig_path.display()
    );
    let text = head + &body;
    RigConfig::parse(&text).context("the calibrated rig file does not parse back (bug)")?;
    std::fs::write(out, text).with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}
