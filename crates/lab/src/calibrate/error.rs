//! The calibration error: one scalar, the sum of named components, each comparing one view
//! of a measured recording with its simulated twin. Each component is averaged over the
//! recordings it applies to (a recording where it does not apply has it `NaN`, shown as
//! `null` in reports):
//! - `env` (every recording), `bands` (every recording): mean absolute difference in dB over
//!   the view's grid;
//! - `peaks` (recordings with a located fault comb): fault-order location difference in per
//!   mille of the fault order, per located fault family (a family the simulation does not
//!   show counts the search half-width, 80 per mille);
//! - `ratios` (the same recordings): harmonic (2nd / 1st) and sideband ratio differences of
//!   the located fault families, summed dB / 10;
//! - `lines` (recordings labelled **healthy**): summed absolute dB difference over the 1 Hz
//!   bins, divided by [`LINES_PER`] (one missing 10 dB line counts 1); in a faulty recording
//!   the raw-spectrum lines are the fault's own harmonics, which `env` compares, while in a
//!   healthy one they are what unbalance and electrical pick-up put there;
//! - `orders` (every recording: the shaft lines are there whatever the bearing's state): the
//!   1x and 2x lines in dB above the higher of the two floors (6 dB threshold), mean absolute
//!   dB difference;
//! - `harmonics` (every recording): the shaft orders 3x-30x the same way, summed dB / 10
//!   (looseness);
//! - `modes` (recordings whose measured dominant resonance stands out): distance, in 100 Hz
//!   bands, from the measured dominant resonance to the model's dominant structural mode on
//!   the classifier axis (the calibrator puts the model's mode in the simulated view, so a
//!   healthy simulation that hardly excites its resonances is still compared; a simulated
//!   view without one that stands out counts [`MODE_MISSING_BANDS`]);
//! - `floor` (recordings labelled healthy: in a faulty one the impacts' skirts cover the
//!   quiet part of the spectrum): difference of the absolute broadband floors, dB;
//! - `speed` (every recording): half the summed absolute difference of the speed-deviation
//!   spectra, percent;
//! - `fractional` (every recording): sub-synchronous and fractional shaft orders
//!   (0.2x-4x between the integers), summed dB / [`FRACTIONAL_PER`] (a 10 dB line about five
//!   grid points wide counts 0.5);
//! - `half_orders` (every recording): the half-order lines 0.5x, 1.5x, 2.5x, 3.5x of the
//!   fractional view (looseness or rub sub-harmonics), each in dB above the higher of the two
//!   floors (6 dB threshold) where the view peaks on the half order
//!   ([`super::half_orders`]), summed dB / [`LINES_PER`];
//! - `impacts` (recordings labelled healthy: in a faulty one the fault's own comb, which `env`,
//!   `peaks` and `ratios` compare, fills it): envelope spectrum in Hz of the broadband
//!   energy, summed dB / [`IMPACTS_PER`]; its residuals are located in faulty recordings too
//!   ([`super::locate`], away from the labelled fault's comb).
//!
//! The README defines it too.

use super::fault_peaks::SEARCH;
use super::fractional_orders;
use super::half_orders;
use super::shaft_orders::levels_db;
use super::views::{Views, BAND_HZ};
pub use crate::vocabulary::ErrorComponent;
use serde::ser::{Serialize, SerializeMap, Serializer};

/// Error components, indexed by [`ErrorComponent`]; `total` is their sum. Serializes as
/// `{"env": .., ..., "impacts": .., "total": ..}` (NaN as null).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ErrorParts {
    parts: [f64; 13],
    pub total: f64,
}

impl Serialize for ErrorParts {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(ErrorComponent::ALL.len() + 1))?;
        for c in ErrorComponent::ALL {
            m.serialize_entry(c.name(), &self.get(c))?;
        }
        m.serialize_entry("total", &self.total)?;
        m.end()
    }
}

/// `modes` when the measured resonance stands out and the simulated one does not (its
/// location is then only noise), in bands.
pub const MODE_MISSING_BANDS: f64 = 10.0;

/// Divisor of the summed `lines` and `ratios` differences, dB.
pub const LINES_PER: f64 = 10.0;
/// Divisor of the summed `fractional` differences (0.02-order grid), dB.
pub const FRACTIONAL_PER: f64 = 100.0;
/// Divisor of the summed `impacts` differences (1 Hz grid), dB.
pub const IMPACTS_PER: f64 = 20.0;

fn summed_abs(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum()
}

/// The smallest cut of each component that counts as a change (acceptance, see
/// [`super::fit::accepts`]), in the component's unit.
pub fn min_cut(c: ErrorComponent) -> f64 {
    use ErrorComponent as C;
    match c {
        C::Peaks => 2.0,
        C::Orders => 0.5,
        C::Modes => 1.0,
        C::Floor => 0.5,
        C::Harmonics | C::HalfOrders => 0.5,
        C::Env | C::Ratios | C::Lines | C::Bands | C::Speed | C::Fractional | C::Impacts => 0.05,
    }
}

/// The smallest cut of an effect's own error (the sum of its components `own`) that counts
/// as a change: the components' smallest cuts ([`min_cut`]) combined as independent
/// scatter, the root of their sum of squares. (Summed outright, an effect seen in five
/// views had to cut twice what one seen in its strongest view alone had to.)
pub fn least_cut(own: &[ErrorComponent]) -> f64 {
    own.iter().map(|&c| min_cut(c).powi(2)).sum::<f64>().sqrt()
}

fn mean_abs(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / n as f64
}

/// `peaks` and `ratios` of one pair (NaN without a located measured comb).
fn fault_parts(m: &Views, s: &Views) -> (f64, f64) {
    if m.fault_peaks.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let (mut peaks, mut ratios) = (0.0, 0.0);
    for p in &m.fault_peaks {
        match s.fault_peaks.iter().find(|q| q.family == p.family) {
            Some(q) => {
                peaks += 1000.0 * (p.order - q.order).abs() / p.order;
                let d = |a: Option<f64>, b: Option<f64>| match (a, b) {
                    (Some(a), Some(b)) => (a - b).abs(),
                    _ => 0.0,
                };
                ratios +=
                    (d(p.harmonic_db, q.harmonic_db) + d(p.sideband_db, q.sideband_db)) / LINES_PER;
            }
            None => peaks += 1000.0 * SEARCH,
        }
    }
    let n = m.fault_peaks.len() as f64;
    (peaks / n, ratios / n)
}

/// Whether a component applies to a measured recording (see the module doc): a pair where
/// it does not has it `NaN`.
pub fn applies(c: ErrorComponent, m: &Views) -> bool {
    use ErrorComponent as C;
    match c {
        C::Lines | C::Floor | C::Impacts => m.healthy,
        C::Peaks | C::Ratios => !m.fault_peaks.is_empty(),
        C::Modes => m.mode.prominent,
        C::Env | C::Orders | C::Harmonics | C::Bands | C::Speed | C::Fractional | C::HalfOrders => {
            true
        }
    }
}

/// Error of one measured/simulated pair.
pub fn pair(m: &Views, s: &Views) -> ErrorParts {
    pair_only(m, s, &ErrorComponent::ALL)
}

/// (`orders`, `harmonics`): the 1x and 2x lines' mean dB difference and the 3x-30x lines'
/// summed dB difference per [`LINES_PER`].
fn shaft_parts(m: &Views, s: &Views) -> (f64, f64) {
    let (lm, ls) = levels_db(&m.shaft, &s.shaft);
    let orders = mean_abs(&lm[..2], &ls[..2]);
    (orders, summed_abs(&lm[2..], &ls[2..]) / LINES_PER)
}

/// [`pair`] for the given components only (the others `NaN`, `total` their sum): the
/// simulated views need hold only what these read ([`super::views::Parts::for_components`]).
/// Each computed component is the same as [`pair`]'s.
pub fn pair_only(m: &Views, s: &Views, components: &[ErrorComponent]) -> ErrorParts {
    use ErrorComponent as C;
    let want = |c: ErrorComponent| components.contains(&c);
    let nan = f64::NAN;
    let env = if want(C::Env) {
        mean_abs(&m.env, &s.env)
    } else {
        nan
    };
    let (peaks, ratios) = if want(C::Peaks) || want(C::Ratios) {
        fault_parts(m, s)
    } else {
        (nan, nan)
    };
    let lines = if m.healthy && want(C::Lines) {
        m.lines
            .iter()
            .zip(&s.lines)
            .map(|(x, y)| (x - y).abs())
            .sum::<f64>()
            / LINES_PER
    } else {
        nan
    };
    let (orders, harmonics) = if want(C::Orders) || want(C::Harmonics) {
        shaft_parts(m, s)
    } else {
        (nan, nan)
    };
    let bands = if want(C::Bands) {
        mean_abs(&m.bands, &s.bands)
    } else {
        nan
    };
    let modes = match (want(C::Modes), m.mode.prominent, s.mode.prominent) {
        (false, _, _) | (true, false, _) => nan,
        (true, true, true) => (m.mode.hz - s.mode.hz).abs() / BAND_HZ,
        (true, true, false) => MODE_MISSING_BANDS,
    };
    let floor = if m.healthy && want(C::Floor) {
        (m.floor_db - s.floor_db).abs()
    } else {
        nan
    };
    let speed = if want(C::Speed) {
        let n = m.speed.len().min(s.speed.len());
        0.5 * m.speed[..n]
            .iter()
            .zip(&s.speed[..n])
            .map(|(x, y)| (x - y).abs())
            .sum::<f64>()
    } else {
        nan
    };
    let fractional = if want(C::Fractional) {
        summed_abs(&m.fractional, &s.fractional) / FRACTIONAL_PER
    } else {
        nan
    };
    let half = if want(C::HalfOrders) {
        let grid = fractional_orders::orders();
        let (lm, ls) = half_orders::levels_db(
            &grid,
            &m.fractional,
            &m.half_orders,
            &s.fractional,
            &s.half_orders,
        );
        summed_abs(&lm, &ls) / LINES_PER
    } else {
        nan
    };
    let impacts = if m.healthy && want(C::Impacts) {
        summed_abs(&m.impacts, &s.impacts) / IMPACTS_PER
    } else {
        nan
    };
    // the pairs computed together keep only the wanted one
    let only = |c: ErrorComponent, v: f64| if want(c) { v } else { nan };
    let mut parts = ErrorParts::default();
    for (c, v) in [
        (C::Env, env),
        (C::Peaks, only(C::Peaks, peaks)),
        (C::Ratios, only(C::Ratios, ratios)),
        (C::Lines, lines),
        (C::Orders, only(C::Orders, orders)),
        (C::Harmonics, only(C::Harmonics, harmonics)),
        (C::Bands, bands),
        (C::Modes, modes),
        (C::Floor, floor),
        (C::Speed, speed),
        (C::Fractional, fractional),
        (C::HalfOrders, half),
        (C::Impacts, impacts),
    ] {
        *parts.get_mut(c) = v;
    }
    parts.summed()
}

impl ErrorParts {
    /// The value of one component.
    pub fn get(&self, c: ErrorComponent) -> f64 {
        self.parts[c as usize]
    }

    fn get_mut(&mut self, c: ErrorComponent) -> &mut f64 {
        &mut self.parts[c as usize]
    }

    /// Sum of the given components (those that apply).
    pub fn of(&self, components: &[ErrorComponent]) -> f64 {
        components
            .iter()
            .map(|&c| self.get(c))
            .filter(|v| v.is_finite())
            .sum()
    }

    /// With `total` set to the sum of the components.
    fn summed(mut self) -> Self {
        self.total = self.of(&ErrorComponent::ALL);
        self
    }
}

/// Mean over pairs, each component over the pairs it applies to (0 when none).
pub fn mean(parts: &[ErrorParts]) -> ErrorParts {
    let mut e = ErrorParts::default();
    for c in ErrorComponent::ALL {
        let v: Vec<f64> = parts
            .iter()
            .map(|p| p.get(c))
            .filter(|v| v.is_finite())
            .collect();
        *e.get_mut(c) = v.iter().fold(0.0, |a, b| a + b) / v.len().max(1) as f64;
    }
    e.summed()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_index_their_own_slot_and_keep_their_names() {
        let mut e = ErrorParts::default();
        for (k, c) in ErrorComponent::ALL.into_iter().enumerate() {
            assert_eq!(c as usize, k);
            *e.get_mut(c) = k as f64;
        }
        e.parts[ErrorComponent::Modes as usize] = f64::NAN;
        let e = e.summed();
        assert_eq!(e.total, (0..13).sum::<usize>() as f64 - 7.0);
        // JSON: every component by name in report order, NaN as null, then the total.
        let json = serde_json::to_string(&e).unwrap();
        assert!(
            json.starts_with(r#"{"env":0.0,"peaks":1.0,"ratios":2.0,"#)
                && json.contains(r#""modes":null,"#)
                && json.ends_with(r#""half_orders":11.0,"impacts":12.0,"total":71.0}"#),
            "{json}"
        );
    }
}
