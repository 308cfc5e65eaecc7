//! Sub-synchronous and fractional shaft orders of the raw signal: what lies below 1x and
//! between the integer orders, where `orders` (1x-2x) and `harmonics` (3x-30x) do not look
//! and where the `lines` view (healthy recordings only) cannot help in a faulty recording.
//! Whirl (0.38-0.48x), half orders of looseness or rub (0.5x, 1.5x, 2.5x...), the cage rate.
//!
//! Amplitude by synchronous demodulation against the shaft angle (a Hann-windowed DFT at
//! each order of a [`STEP`] grid from [`MIN_ORDER`] to [`MAX_ORDER`]), orders within
//! [`INTEGER_GAP`] of an integer left out (the integer lines' own leakage). Each order's
//! level is in dB above the median of the grid within [`FLOOR_HALF_WIDTH`] orders (its local
//! floor), less a 6 dB threshold (0 below), capped at 60 dB. The same demodulation gives the
//! half-order lines' amplitudes and floors ([`super::half_orders`]).

use super::half_orders::{self, HalfOrders};
use crate::dsp::speed::SpeedTrack;

pub const MIN_ORDER: f64 = 0.2;
pub const MAX_ORDER: f64 = 4.0;
pub const STEP: f64 = 0.02;
/// Orders closer than this to an integer are not in the view.
pub const INTEGER_GAP: f64 = 0.2;
/// Half-width of the local floor, orders.
pub const FLOOR_HALF_WIDTH: f64 = 0.5;
const THRESHOLD_DB: f64 = 6.0;
const CAP_DB: f64 = 60.0;

fn full_grid_len() -> usize {
    ((MAX_ORDER - MIN_ORDER) / STEP).round() as usize + 1
}

fn kept(o: f64) -> bool {
    (o - o.round()).abs() >= INTEGER_GAP - 1e-9
}

/// The orders of the view, ascending.
pub fn orders() -> Vec<f64> {
    (0..full_grid_len())
        .map(|k| MIN_ORDER + k as f64 * STEP)
        .filter(|o| kept(*o))
        .collect()
}

type C = (f64, f64);

#[inline]
fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

/// The fractional view of one recording.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Fractional {
    /// Thresholded levels (dB above the local floor) at [`orders`].
    pub levels: Vec<f64>,
    /// Amplitude and local floor at each of [`half_orders::ORDERS`], channel units.
    pub half: HalfOrders,
}

/// The view of `x` (sampled at `fs`): levels all 0 and half-order lines 0 for fewer than 16
/// samples. Orders above 0.45 fs at the mean speed are 0.
pub fn measure(x: &[f32], fs: f64, track: &SpeedTrack) -> Fractional {
    let keep = orders();
    let n = x.len();
    if n < 16 {
        return Fractional {
            levels: vec![0.0; keep.len()],
            half: HalfOrders {
                amplitude: vec![0.0; half_orders::ORDERS.len()],
                floor: vec![0.0; half_orders::ORDERS.len()],
            },
        };
    }
    let w = |i: usize| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
    let wsum: f64 = (0..n).map(w).sum();
    let mean = x
        .iter()
        .enumerate()
        .map(|(i, v)| *v as f64 * w(i))
        .sum::<f64>()
        / wsum;
    let mut angles = vec![0.0; n];
    track.angles_at_times(0.0, 1.0 / fs, &mut angles);
    let m = full_grid_len();
    let mut sums = vec![(0.0f64, 0.0f64); m];
    for (i, (v, rev)) in x.iter().zip(&angles).enumerate() {
        let th = std::f64::consts::TAU * rev;
        let y = (*v as f64 - mean) * w(i);
        let (s0, c0) = (MIN_ORDER * th).sin_cos();
        let (s, c) = (STEP * th).sin_cos();
        let step = (c, -s);
        let mut e = (y * c0, -y * s0);
        for acc in sums.iter_mut() {
            acc.0 += e.0;
            acc.1 += e.1;
            e = mul(e, step);
        }
    }
    let top = 0.45 * fs / (track.mean_rpm(0.0, n as f64 / fs) / 60.0).max(1e-9);
    let amp: Vec<(f64, f64)> = sums
        .iter()
        .enumerate()
        .map(|(k, z)| {
            (
                MIN_ORDER + k as f64 * STEP,
                2.0 * (z.0 * z.0 + z.1 * z.1).sqrt() / wsum,
            )
        })
        .filter(|(o, _)| kept(*o))
        .collect();
    let floor_at = |o: f64| {
        let local: Vec<f64> = amp
            .iter()
            .filter(|(p, _)| (p - o).abs() <= FLOOR_HALF_WIDTH)
            .map(|(_, b)| *b)
            .collect();
        super::stats::median(&local).max(1e-30)
    };
    let levels = amp
        .iter()
        .map(|&(o, a)| {
            if o > top {
                return 0.0;
            }
            (20.0 * (a / floor_at(o)).max(1e-6).log10() - THRESHOLD_DB).clamp(0.0, CAP_DB)
        })
        .collect();
    let mut half = HalfOrders::default();
    for h in half_orders::ORDERS {
        let a = amp
            .iter()
            .find(|(o, _)| (o - h).abs() < 1e-6)
            .map_or(0.0, |(_, a)| *a);
        let (a, f) = if h > top {
            (0.0, 0.0)
        } else {
            (a, floor_at(h))
        };
        half.amplitude.push(a);
        half.floor.push(f);
    }
    Fractional { levels, half }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_half_order_and_a_whirl_line_but_not_the_integer_orders() {
        let fs = 2000.0;
        let n = 8000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
        let hz: Vec<f64> = t.iter().map(|t| 10.0 + 0.3 * t).collect();
        let track =
            SpeedTrack::from_profile(&t, &hz, crate::vocabulary::SpeedSourceKind::Simulator)
                .unwrap();
        let mut seed = 1u64;
        let x: Vec<f32> = t
            .iter()
            .map(|&ti| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                let noise = ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.02;
                let th = std::f64::consts::TAU * track.angle_at(ti);
                (1.0 * th.cos()
                    + 0.3 * (2.0 * th).cos()
                    + 0.05 * (0.5 * th + 0.3).cos()
                    + 0.05 * (0.44 * th).sin()
                    + 0.05 * (2.5 * th).cos()
                    + noise) as f32
            })
            .collect();
        let o = orders();
        let f = measure(&x, fs, &track);
        let v = &f.levels;
        let at = |order: f64| {
            let k = o
                .iter()
                .position(|p| (p - order).abs() < 1e-6)
                .unwrap_or_else(|| panic!("{order} not on the grid"));
            v[k]
        };
        assert!(at(0.5) > 10.0, "0.5x: {}", at(0.5));
        assert!(at(0.44) > 10.0, "0.44x: {}", at(0.44));
        assert!(at(2.5) > 10.0, "2.5x: {}", at(2.5));
        assert_eq!(at(1.6), 0.0);
        assert_eq!(at(3.5), 0.0);
        assert!(o
            .iter()
            .all(|p| (p - p.round()).abs() >= INTEGER_GAP - 1e-9));
        // the half-order lines: every one on the grid, 0.5x and 2.5x at their amplitudes
        // (0.05), the others at the floor
        for h in half_orders::ORDERS {
            assert!(
                o.iter().any(|p| (p - h).abs() < 1e-6),
                "{h} not on the grid"
            );
        }
        let (a, fl) = (&f.half.amplitude, &f.half.floor);
        assert!(
            (a[0] - 0.05).abs() < 0.005 && (a[2] - 0.05).abs() < 0.005,
            "{a:?}"
        );
        assert!(
            a[1] < 0.005 && a[3] < 0.005 && fl.iter().all(|x| *x < 0.005),
            "{a:?} {fl:?}"
        );
    }
}
