//! Where a residual is: peaks of measured-minus-simulated views, expressed in orders or Hz,
//! and whether they follow the shaft (`speed`: same order at different speeds), stay put
//! (`frequency`: same Hz at different speeds) or cannot be told (`undetermined`: one speed
//! only). Narrowband content comes from the `lines` and `env` views, sub-synchronous and
//! fractional shaft orders from `fractional`, repeated impacting from `impacts` (envelope of
//! the band energy, in Hz), landings once every two revolutions that the model lacks from
//! `landings` (found in the band where they ring, [`landing_comb`], at 0.5x), broadband from `bands`, modulation from the fault combs'
//! sideband ratios (`modulation`) and misplaced fault lines from their located orders
//! (`peaks`). Each finding carries the physical causes that usually produce such a
//! signature ([`super::trace`]): candidates, not findings.

use super::fractional_orders;
use super::impacts;
use super::landing_comb;
use super::measured::{distinct_speeds, several_speeds};
use super::views::{env_order, Views, BAND_HZ, LINES_MIN_HZ};
use serde::Serialize;

/// A residual no accepted effect explains.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unexplained {
    /// Where: in `unit`.
    pub location: f64,
    /// `order` or `Hz`.
    pub unit: String,
    /// `speed`, `frequency` or `undetermined`.
    pub locked_to: String,
    /// `lines` (narrowband, raw spectrum), `env` (envelope order spectrum), `fractional`,
    /// `impacts` (envelope of the broadband energy), `landings` (a half-order comb of impacts
    /// in the band where they ring), `bands` (broadband), `modulation` (sideband ratio of a
    /// fault comb) or `peaks` (a fault comb located elsewhere than simulated).
    pub view: String,
    /// Measured above simulated, dB (largest over recordings); for `modulation` the
    /// measured minus the simulated sideband ratio, dB, negative when the simulation's
    /// sidebands are the stronger; for `peaks` the location difference in per mille; for
    /// `landings` the measured comb's ratio over the simulated one's in that band, dB.
    pub excess_db: f64,
    /// Recordings showing it.
    pub recordings: usize,
    /// The location in shaft orders (Hz over each recording's shaft speed, mean over the
    /// recordings showing it); meaningful unless `locked_to` is `frequency`.
    pub order: f64,
    /// Physical causes that usually produce this signature ([`super::trace`]); candidates
    /// to check, never findings.
    pub candidates: Vec<String>,
}

struct Peak {
    rec: usize,
    hz: f64,
    order: f64,
    excess: f64,
}

const LINE_EXCESS_DB: f64 = 10.0;
const BAND_EXCESS_DB: f64 = 6.0;
/// Sideband ratio mismatch reported as modulation, dB.
const SIDEBAND_EXCESS_DB: f64 = 6.0;
/// Fault-order location mismatch reported, per mille.
const PEAK_OFF_PER_MILLE: f64 = 5.0;

fn peaks(res: &[f64], min_db: f64) -> Vec<(usize, f64)> {
    (0..res.len())
        .filter(|&i| {
            res[i] > min_db
                && (i.saturating_sub(2)..(i + 3).min(res.len())).all(|j| res[j] <= res[i])
        })
        .map(|i| (i, res[i]))
        .collect()
}

/// Harmonics of a located fault order, and its modulation sidebands (+-1x, +-2x), masked in
/// the `impacts` view of a faulty recording: that comb is the labelled fault's own, compared
/// in `env`, `peaks` and `ratios`.
const COMB_HARMONICS: usize = 12;
/// Relative width of the mask around each comb line.
const COMB_TOL: f64 = 0.03;
/// Width of the mask around each integer order, orders.
const INTEGER_TOL: f64 = 0.05;

/// Whether `order` lies on the located fault comb of a faulty recording (or on an integer
/// order, the inner-race load-zone modulation).
fn on_fault_comb(m: &Views, order: f64) -> bool {
    if m.healthy {
        return false;
    }
    let near = |target: f64| target > 0.0 && (order - target).abs() <= COMB_TOL * target.max(1.0);
    if order.round() >= 1.0 && (order - order.round()).abs() <= INTEGER_TOL {
        return true;
    }
    m.fault_peaks.iter().any(|p| {
        (1..=COMB_HARMONICS).any(|k| (-2..=2).any(|j| near(k as f64 * p.order + j as f64)))
    })
}

/// Measured minus simulated, element by element.
fn difference(m: &[f64], s: &[f64]) -> Vec<f64> {
    m.iter().zip(s).map(|(a, b)| a - b).collect()
}

/// Landings the model lacks in recording `rec` (turning at `fr`): a measured half-order comb
/// ([`landing_comb`]) where the twin, judged in the band where the measured landings ring,
/// shows none and the measured comb stands the detection ratio above the twin's (as a comb
/// must stand above noise); a residual at 0.5x, its excess the two combs' ratio in dB.
fn landing_peak(m: &Views, s: &Views, rec: usize, fr: f64) -> Option<Peak> {
    let b = m.landings.strongest().filter(|_| m.landings.detected())?;
    let simulated = s.landings.ratio_in(b);
    let apart = m.landings.best_ratio() >= landing_comb::DETECT_RATIO * simulated.max(1.0);
    (simulated < landing_comb::DETECT_RATIO && apart).then(|| Peak {
        rec,
        hz: 0.5 * fr,
        order: 0.5,
        excess: 10.0 * (m.landings.best_ratio() / simulated.max(1.0)).log10(),
    })
}

/// Residual locations for pairs of (measured, simulated) views.
pub fn locate(pairs: &[(&Views, &Views)]) -> Vec<Unexplained> {
    let speeds: Vec<f64> = pairs.iter().map(|(m, _)| m.rpm / 60.0).collect();
    let mut out = Vec::new();
    // narrowband in the raw spectrum (Hz known, order = Hz / f_r)
    let mut line_peaks = Vec::new();
    let mut env_peaks = Vec::new();
    let mut band_peaks = Vec::new();
    let mut fractional_peaks = Vec::new();
    let mut impact_peaks = Vec::new();
    let mut landing_peaks = Vec::new();
    let frac_orders = fractional_orders::orders();
    let impact_hz = impacts::frequencies();
    let mut modulation = Vec::new();
    let mut misplaced = Vec::new();
    for (r, (m, s)) in pairs.iter().enumerate() {
        for p in &m.fault_peaks {
            let Some(q) = s.fault_peaks.iter().find(|q| q.family == p.family) else {
                continue;
            };
            if let (Some(a), Some(b)) = (p.sideband_db, q.sideband_db) {
                if (a - b).abs() > SIDEBAND_EXCESS_DB {
                    modulation.push(Peak {
                        rec: r,
                        hz: p.order * speeds[r],
                        order: p.order,
                        excess: a - b,
                    });
                }
            }
            let off = 1000.0 * (p.order - q.order).abs() / p.order;
            if off > PEAK_OFF_PER_MILLE {
                misplaced.push(Peak {
                    rec: r,
                    hz: p.order * speeds[r],
                    order: p.order,
                    excess: off,
                });
            }
        }
        let fr = speeds[r];
        let res = difference(&m.lines, &s.lines);
        for (i, e) in peaks(&res, LINE_EXCESS_DB) {
            let hz = (i + LINES_MIN_HZ) as f64;
            line_peaks.push(Peak {
                rec: r,
                hz,
                order: hz / fr,
                excess: e,
            });
        }
        let res = difference(&m.env, &s.env);
        for (i, e) in peaks(&res, LINE_EXCESS_DB) {
            let o = env_order(i);
            env_peaks.push(Peak {
                rec: r,
                hz: o * fr,
                order: o,
                excess: e,
            });
        }
        let res = difference(&m.fractional, &s.fractional);
        for (i, e) in peaks(&res, LINE_EXCESS_DB) {
            let o = frac_orders[i];
            fractional_peaks.push(Peak {
                rec: r,
                hz: o * fr,
                order: o,
                excess: e,
            });
        }
        let res = difference(&m.impacts, &s.impacts);
        for (i, e) in peaks(&res, LINE_EXCESS_DB) {
            let hz = impact_hz[i];
            if on_fault_comb(m, hz / fr) {
                continue;
            }
            impact_peaks.push(Peak {
                rec: r,
                hz,
                order: hz / fr,
                excess: e,
            });
        }
        landing_peaks.extend(landing_peak(m, s, r, fr));
        for (i, (a, b)) in m.bands.iter().zip(&s.bands).enumerate() {
            if a - b > BAND_EXCESS_DB {
                let hz = m.band_lo_hz[i] + BAND_HZ / 2.0;
                band_peaks.push(Peak {
                    rec: r,
                    hz,
                    order: hz / fr,
                    excess: a - b,
                });
            }
        }
    }
    group(&line_peaks, &speeds, "lines", &mut out);
    group(&env_peaks, &speeds, "env", &mut out);
    group(&fractional_peaks, &speeds, "fractional", &mut out);
    group(&impact_peaks, &speeds, "impacts", &mut out);
    group(&landing_peaks, &speeds, "landings", &mut out);
    group(&band_peaks, &speeds, "bands", &mut out);
    group(&modulation, &speeds, "modulation", &mut out);
    group(&misplaced, &speeds, "peaks", &mut out);
    out.sort_by(|a, b| b.excess_db.total_cmp(&a.excess_db));
    out
}

/// The number of recordings among `peaks[idx]`.
fn recordings(peaks: &[Peak], idx: &[usize]) -> usize {
    let mut v: Vec<usize> = idx.iter().map(|&j| peaks[j].rec).collect();
    v.sort_unstable();
    v.dedup();
    v.len()
}

fn group(peaks: &[Peak], speeds: &[f64], view: &str, out: &mut Vec<Unexplained>) {
    let several_speeds = several_speeds(speeds);
    let broadband = view == "bands";
    // envelope, fault-comb and landing findings are orders by nature
    let by_order = matches!(view, "env" | "modulation" | "peaks" | "landings");
    let alone_counts = view == "landings"; // a detection with its own false-alarm rate
    let mut used = vec![false; peaks.len()];
    for (i, p) in peaks.iter().enumerate() {
        if used[i] {
            continue;
        }
        let hz_tol = if broadband { BAND_HZ } else { 1.5 };
        let same_hz: Vec<usize> = (0..peaks.len())
            .filter(|&j| !used[j] && (peaks[j].hz - p.hz).abs() <= hz_tol)
            .collect();
        let same_order: Vec<usize> = (0..peaks.len())
            .filter(|&j| !used[j] && (peaks[j].order - p.order).abs() <= 0.01 * p.order + 0.03)
            .collect();
        let speeds_of = |idx: &[usize]| {
            let mut v: Vec<f64> = idx.iter().map(|&j| speeds[peaks[j].rec]).collect();
            v.sort_by(f64::total_cmp);
            v.dedup_by(|a, b| !distinct_speeds(*a, *b));
            v.len()
        };
        let (members, unit, locked) = if several_speeds {
            if speeds_of(&same_order) >= 2 && (by_order || speeds_of(&same_hz) < 2) {
                (same_order, "order", "speed")
            } else if speeds_of(&same_hz) >= 2 {
                (same_hz, "Hz", "frequency")
            } else if alone_counts {
                (same_order, "order", "undetermined")
            } else {
                continue;
            }
        } else if by_order {
            (same_order, "order", "undetermined")
        } else {
            (same_hz, "Hz", "undetermined")
        };
        // one recording alone is noise unless there is only one
        let n = recordings(peaks, &members);
        if n < 2 && speeds.len() > 1 && !alone_counts {
            continue;
        }
        // the largest in magnitude, sign kept (a modulation mismatch may go either way)
        let excess = members
            .iter()
            .map(|&j| peaks[j].excess)
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(0.0);
        for &j in &members {
            used[j] = true;
        }
        let mean = members
            .iter()
            .map(|&j| {
                if unit == "order" {
                    peaks[j].order
                } else {
                    peaks[j].hz
                }
            })
            .sum::<f64>()
            / members.len() as f64;
        out.push(Unexplained {
            location: (mean * 1000.0).round() / 1000.0,
            unit: unit.into(),
            locked_to: locked.into(),
            view: view.into(),
            excess_db: (excess * 10.0).round() / 10.0,
            recordings: n,
            order: (members.iter().map(|&j| peaks[j].order).sum::<f64>() / members.len() as f64
                * 1000.0)
                .round()
                / 1000.0,
            candidates: Vec::new(),
        });
    }
}
