//! Condition-order peak locations and their harmonic and sideband ratios, read off a whole-
//! recording envelope order spectrum with a harmonic comb: the fault order `o` that
//! maximises the summed height of the peaks at `o, 2o, 3o, ...` (up to [`MAX_ORDER`]) within
//! +-[`SEARCH`] of the kinematic order. A comb is far harder to fool than a single peak (a
//! strong line near one harmonic cannot move it), and its harmonics give sub-line accuracy.

use crate::vocabulary::Condition;
use serde::Serialize;

/// Harmonics are used up to this order.
pub const MAX_ORDER: f64 = 20.0;
/// Search half-width around the kinematic order, relative (slip up to 6 %, contact angles up
/// to 40 deg move fault orders by less than this).
pub const SEARCH: f64 = 0.08;
/// A comb is located only if its harmonics stand this far above the spectrum's median on
/// average, dB.
pub const MIN_COMB_DB: f64 = 6.0;
/// Comb positions per search half-width.
const STEPS: usize = 400;

/// One located fault family.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FaultPeak {
    /// `bpfo`, `bpfi` or `2xbsf`.
    pub family: &'static str,
    /// The kinematic order the search started from.
    pub nominal: f64,
    /// The located fault order.
    pub order: f64,
    /// Mean height of the comb's harmonics above the median, dB.
    pub height_db: f64,
    /// Second harmonic minus fundamental, dB (None when 2o is beyond the spectrum).
    pub harmonic_db: Option<f64>,
    /// Mean of the modulation sidebands minus the fundamental, dB: +-1 shaft order for an
    /// inner race (the defect turns through the load zone), +-FTF for a ball (it turns with
    /// the cage); None for an outer race (fixed defect, no sidebands).
    pub sideband_db: Option<f64>,
}

/// The fault family a fault shows as, its kinematic order and its sideband spacing (None for
/// `healthy`, which has no family).
pub fn family(
    fault: Condition,
    orders: &crate::bearing::FaultOrders,
) -> Option<(&'static str, f64, f64)> {
    Some(match fault {
        Condition::Healthy => return None,
        Condition::OuterRace => ("bpfo", orders.bpfo, 0.0),
        Condition::InnerRace => ("bpfi", orders.bpfi, 1.0),
        Condition::Ball => ("2xbsf", orders.two_bsf, orders.ftf),
    })
}

/// A spectrum in dB above its median on a uniform order grid.
pub struct DbSpectrum<'a> {
    pub db: &'a [f64],
    pub step: f64,
}

impl DbSpectrum<'_> {
    /// dB at order `o` (linear interpolation; very low outside the grid).
    pub fn at(&self, o: f64) -> f64 {
        let x = o / self.step;
        if x < 0.0 || x >= (self.db.len() - 1) as f64 {
            return -60.0;
        }
        let j = x.floor() as usize;
        let f = x - j as f64;
        self.db[j] * (1.0 - f) + self.db[j + 1] * f
    }

    /// Highest value within +-`half` of `o` (a peak smeared by jitter still counts).
    fn peak_near(&self, o: f64, half: f64) -> f64 {
        let a = ((o - half) / self.step).floor().max(0.0) as usize;
        let b = (((o + half) / self.step).ceil() as usize).min(self.db.len() - 1);
        if a > b {
            return -60.0;
        }
        self.db[a..=b].iter().copied().fold(f64::MIN, f64::max)
    }
}

/// Locate one fault family. `None` when no comb stands [`MIN_COMB_DB`] above the median.
pub fn locate(
    spec: &DbSpectrum,
    fault: Condition,
    orders: &crate::bearing::FaultOrders,
) -> Option<FaultPeak> {
    let (name, nominal, sb) = family(fault, orders)?;
    let top = MAX_ORDER.min(spec.step * (spec.db.len() - 1) as f64);
    let harmonics = ((top / (nominal * (1.0 + SEARCH))).floor() as usize).max(1);
    if nominal * (1.0 + SEARCH) > top {
        return None;
    }
    let score = |o: f64| -> f64 {
        (1..=harmonics)
            .map(|h| spec.at(h as f64 * o).max(0.0))
            .sum::<f64>()
    };
    let lo = nominal * (1.0 - SEARCH);
    let d = nominal * SEARCH / STEPS as f64;
    let (mut best, mut best_s) = (lo, f64::MIN);
    for k in 0..=2 * STEPS {
        let o = lo + k as f64 * d;
        let s = score(o);
        if s > best_s {
            best = o;
            best_s = s;
        }
    }
    // parabolic refinement of the comb score
    let (sm, sp) = (score(best - d), score(best + d));
    let den = sm - 2.0 * best_s + sp;
    if den < 0.0 {
        best += (0.5 * (sm - sp) / den).clamp(-1.0, 1.0) * d;
    }
    let height = (1..=harmonics)
        .map(|h| spec.at(h as f64 * best))
        .sum::<f64>()
        / harmonics as f64;
    if height < MIN_COMB_DB {
        return None;
    }
    let width = 2.0 * spec.step;
    let fundamental = spec.peak_near(best, width);
    let harmonic_db = (harmonics >= 2).then(|| spec.peak_near(2.0 * best, width) - fundamental);
    let sideband_db = (sb > 0.0 && best - sb > 0.0).then(|| {
        0.5 * (spec.peak_near(best - sb, width) + spec.peak_near(best + sb, width)) - fundamental
    });
    Some(FaultPeak {
        family: name,
        nominal,
        order: best,
        height_db: height,
        harmonic_db,
        sideband_db,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bearing::BearingGeometry;

    fn orders() -> crate::bearing::FaultOrders {
        BearingGeometry {
            balls: 11,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 48.0,
            contact_angle_deg: 0.0,
        }
        .fault_orders()
    }

    /// A comb of peaks 2 % below BPFO, a stronger stray line near the 4th harmonic and
    /// noise: the comb lands on the shifted order, not on the stray line.
    #[test]
    fn finds_a_shifted_comb_past_a_stray_line() {
        let o = orders();
        let step = 0.01;
        let n = (21.0 / step) as usize;
        let true_o = o.bpfo * 0.98;
        let mut db = vec![0.0; n];
        for (j, v) in db.iter_mut().enumerate() {
            let x = j as f64 * step;
            *v = ((j * 7919) % 13) as f64 * 0.3 - 2.0;
            for h in 1..=4 {
                let dx = (x - h as f64 * true_o) / 0.03;
                *v += 20.0 * (-dx * dx).exp();
            }
            let dx = (x - 17.3) / 0.03;
            *v += 35.0 * (-dx * dx).exp();
        }
        let p = locate(&DbSpectrum { db: &db, step }, Condition::OuterRace, &o).unwrap();
        assert!((p.order / true_o - 1.0).abs() < 5e-4, "{p:?}");
        assert!(p.sideband_db.is_none());
        assert!(p.harmonic_db.unwrap().abs() < 1.0, "{p:?}");
    }

    #[test]
    fn flat_spectrum_has_no_comb() {
        let db = vec![1.0; 2100];
        assert!(locate(
            &DbSpectrum {
                db: &db,
                step: 0.01
            },
            Condition::InnerRace,
            &orders()
        )
        .is_none());
    }
}
