//! Half-order lines of the fractional view: 0.5x, 1.5x, 2.5x, 3.5x, the sub-harmonics of
//! mechanical looseness or a rub (a motion that repeats every other revolution), as the
//! `half_orders` error component compares them.
//!
//! Each line is the demodulated amplitude at the exact half order with the local floor the
//! fractional view uses there ([`HalfOrders`], measured by [`super::fractional_orders`]). A
//! pair is compared like the integer shaft orders: in dB above the higher of the two floors,
//! less a 6 dB threshold, so a floor that differs between rig and model does not count. And a
//! half order counts only where the fractional view **peaks** on it (its level within
//! [`PEAK_TOL_DB`] of the highest within [`PEAK_HALF_WIDTH`] orders): a two-second segment at
//! 600 rpm resolves 0.05 orders, so a whirl line at 0.46x spills onto 0.5x; it peaks at 0.46x,
//! not on the half order, and is no half-order line.

/// The half orders compared: those inside the fractional view (0.2x-4x).
pub const ORDERS: [f64; 4] = [0.5, 1.5, 2.5, 3.5];
/// A half order counts when the fractional view peaks on it within this many orders...
pub const PEAK_HALF_WIDTH: f64 = 0.04;
/// ... to this many dB (a noisy top is not always exactly on the line).
pub const PEAK_TOL_DB: f64 = 1.0;
/// A line counts only this far above the common floor, dB.
pub const THRESHOLD_DB: f64 = 6.0;

/// Amplitude and local floor of each of [`ORDERS`], channel units (empty when the fractional
/// view was not computed).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HalfOrders {
    pub amplitude: Vec<f64>,
    pub floor: Vec<f64>,
}

/// Whether the thresholded fractional `view` on the order `grid` peaks at `order`.
fn peaks_at(grid: &[f64], view: &[f64], order: f64) -> bool {
    let Some(k) = grid.iter().position(|g| (g - order).abs() < 1e-6) else {
        return false;
    };
    let top = grid
        .iter()
        .zip(view)
        .filter(|(g, _)| (*g - order).abs() <= PEAK_HALF_WIDTH + 1e-9)
        .map(|(_, v)| *v)
        .fold(f64::MIN, f64::max);
    view.get(k).is_some_and(|v| *v >= top - PEAK_TOL_DB)
}

/// Levels of the half-order lines of a measured (`m`, with its fractional view `m_view`) and a
/// simulated (`s`, `s_view`) recording on the fractional view's order `grid`: dB above the
/// higher of the two floors less [`THRESHOLD_DB`] (0 below), and 0 where that recording's view
/// does not peak on the half order.
pub fn levels_db(
    grid: &[f64],
    m_view: &[f64],
    m: &HalfOrders,
    s_view: &[f64],
    s: &HalfOrders,
) -> (Vec<f64>, Vec<f64>) {
    let level = |amp: f64, floor: f64| {
        let f = floor.max(1e-12);
        (20.0 * (amp.max(f) / f).log10() - THRESHOLD_DB).max(0.0)
    };
    ORDERS
        .iter()
        .zip(m.amplitude.iter().zip(&m.floor))
        .zip(s.amplitude.iter().zip(&s.floor))
        .map(|((o, (am, fm)), (a_s, fs))| {
            let f = fm.max(*fs);
            let lm = if peaks_at(grid, m_view, *o) {
                level(*am, f)
            } else {
                0.0
            };
            let ls = if peaks_at(grid, s_view, *o) {
                level(*a_s, f)
            } else {
                0.0
            };
            (lm, ls)
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_beside_the_half_order_is_no_half_order_line() {
        let grid: Vec<f64> = (0..20).map(|k| 0.3 + 0.02 * k as f64).collect();
        let at = |o: f64| grid.iter().position(|g| (g - o).abs() < 1e-6).unwrap();
        // a line centred on 0.5x, and one centred on 0.46x that spills onto 0.5x
        let mut centred = vec![0.0; grid.len()];
        let mut beside = vec![0.0; grid.len()];
        for (o, db) in [
            (0.46, 20.0),
            (0.48, 23.0),
            (0.5, 24.0),
            (0.52, 23.0),
            (0.54, 20.0),
        ] {
            centred[at(o)] = db;
        }
        for (o, db) in [
            (0.42, 25.0),
            (0.44, 28.0),
            (0.46, 29.0),
            (0.48, 28.0),
            (0.5, 25.0),
        ] {
            beside[at(o)] = db;
        }
        let line = HalfOrders {
            amplitude: vec![0.1, 0.001, 0.001, 0.001],
            floor: vec![0.001; 4],
        };
        let quiet = HalfOrders {
            amplitude: vec![0.001; 4],
            floor: vec![0.001; 4],
        };
        let (m, s) = levels_db(&grid, &centred, &line, &centred, &quiet);
        assert!((m[0] - 34.0).abs() < 1e-9, "{m:?}");
        assert_eq!(&m[1..], &[0.0; 3]);
        assert_eq!(s, vec![0.0; 4]);
        let (m, _) = levels_db(&grid, &beside, &line, &centred, &quiet);
        assert_eq!(m, vec![0.0; 4], "a 0.46x line counted as 0.5x");
        // the common floor: a higher simulated floor lowers both levels alike
        let high = HalfOrders {
            amplitude: vec![0.01; 4],
            floor: vec![0.01; 4],
        };
        let (m, s) = levels_db(&grid, &centred, &line, &centred, &high);
        assert!((m[0] - 14.0).abs() < 1e-9 && s[0] == 0.0, "{m:?} {s:?}");
    }
}
