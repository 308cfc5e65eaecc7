//! Shaft-order lines of the raw signal (1x, 2x, ... [`MAX_ORDER`]x): amplitude by
//! synchronous demodulation against the shaft angle from the speed source (a Hann-windowed
//! DFT at an exact order, so a slowly varying speed does not smear the line), and the local
//! floor around each order from the same demodulation at non-integer orders beside it.
//! Integer orders are the shaft's own content (unbalance, misalignment, looseness) in healthy
//! and faulty recordings alike: bearing fault lines fall between them.

use crate::dsp::speed::SpeedTrack;

/// Highest shaft order measured.
pub const MAX_ORDER: usize = 30;
/// Offsets (orders) at which the floor beside each line is sampled.
const FLOOR_OFFSETS: [f64; 6] = [-0.45, -0.35, -0.25, 0.25, 0.35, 0.45];
/// Orders on each side whose offsets also count for a line's floor.
const FLOOR_POOL: usize = 2;
/// A line counts only this far above the floor, dB (a noise bin exceeds its median by more
/// than 6 dB about 1 time in 20).
pub const THRESHOLD_DB: f64 = 6.0;

/// Amplitude and floor of orders 1..=[`MAX_ORDER`] (index 0 = 1x), channel units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShaftOrders {
    pub amplitude: Vec<f64>,
    pub floor: Vec<f64>,
}

type C = (f64, f64);

#[inline]
fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

/// Demodulate `x` (sampled at `fs`) at the shaft orders; orders above 0.45 fs are 0.
pub fn measure(x: &[f32], fs: f64, track: &SpeedTrack) -> ShaftOrders {
    let n = x.len();
    let mut out = ShaftOrders {
        amplitude: vec![0.0; MAX_ORDER],
        floor: vec![0.0; MAX_ORDER],
    };
    if n < 16 {
        return out;
    }
    let w = |i: usize| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
    let wsum: f64 = (0..n).map(w).sum();
    let mean = x
        .iter()
        .enumerate()
        .map(|(i, v)| *v as f64 * w(i))
        .sum::<f64>()
        / wsum;
    // sums[k][j]: order k+1, j = 0 the order itself, 1.. the floor offsets
    let mut sums = vec![[(0.0f64, 0.0f64); 1 + FLOOR_OFFSETS.len()]; MAX_ORDER];
    let mut offs = [(0.0f64, 0.0f64); FLOOR_OFFSETS.len()];
    let mut angles = vec![0.0; n];
    track.angles_at_times(0.0, 1.0 / fs, &mut angles);
    for (i, (v, rev)) in x.iter().zip(&angles).enumerate() {
        let th = std::f64::consts::TAU * rev;
        let y = (*v as f64 - mean) * w(i);
        let (s, c) = th.sin_cos();
        let step = (c, -s);
        for (o, d) in offs.iter_mut().zip(FLOOR_OFFSETS) {
            let (s, c) = (d * th).sin_cos();
            *o = (c, -s);
        }
        let mut e = (y, 0.0);
        for row in sums.iter_mut() {
            e = mul(e, step);
            row[0].0 += e.0;
            row[0].1 += e.1;
            for (acc, o) in row[1..].iter_mut().zip(&offs) {
                let z = mul(e, *o);
                acc.0 += z.0;
                acc.1 += z.1;
            }
        }
    }
    let top_hz = 0.45 * fs;
    let shaft_hz = track.mean_rpm(0.0, n as f64 / fs) / 60.0;
    let amp = |z: C| 2.0 * (z.0 * z.0 + z.1 * z.1).sqrt() / wsum;
    let valid = (0..MAX_ORDER)
        .take_while(|k| (k + 1) as f64 * shaft_hz <= top_hz)
        .count();
    for k in 0..valid {
        out.amplitude[k] = amp(sums[k][0]);
        // the floor beside order k pools the offsets of orders k-2..k+2 (30 values: a
        // steadier median than the 6 beside one order, and still local)
        let lo = k.saturating_sub(FLOOR_POOL);
        let hi = (k + FLOOR_POOL).min(valid - 1);
        let f: Vec<f64> = sums[lo..=hi]
            .iter()
            .flat_map(|row| row[1..].iter().map(|z| amp(*z)))
            .collect();
        out.floor[k] = super::stats::median(&f);
    }
    out
}

/// Level of each order above the common floor (the higher of the two per order), dB, less
/// [`THRESHOLD_DB`] (0 below that), for a measured (`a`) and simulated (`b`) recording.
pub fn levels_db(a: &ShaftOrders, b: &ShaftOrders) -> (Vec<f64>, Vec<f64>) {
    let level = |amp: f64, floor: f64| {
        let f = floor.max(1e-12);
        (20.0 * (amp.max(f) / f).log10() - THRESHOLD_DB).max(0.0)
    };
    a.amplitude
        .iter()
        .zip(&b.amplitude)
        .zip(a.floor.iter().zip(&b.floor))
        .map(|((x, y), (fa, fb))| {
            let f = fa.max(*fb);
            (level(*x, f), level(*y, f))
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_order_lines_under_a_drifting_speed() {
        let fs = 2000.0;
        let n = 8000;
        // speed ramps 10 -> 12 Hz; angle = integral
        let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
        let hz: Vec<f64> = t.iter().map(|t| 10.0 + 0.5 * t).collect();
        let track =
            SpeedTrack::from_profile(&t, &hz, crate::vocabulary::SpeedSourceKind::Simulator)
                .unwrap();
        let x: Vec<f32> = t
            .iter()
            .enumerate()
            .map(|(i, &ti)| {
                let th = std::f64::consts::TAU * track.angle_at(ti);
                (0.3 * (th + 0.4).cos()
                    + 0.05 * (2.0 * th).sin()
                    + 0.02 * (7.0 * th + 1.0).cos()
                    + 0.01 * ((i * 7) % 5) as f64) as f32
            })
            .collect();
        let o = measure(&x, fs, &track);
        assert!((o.amplitude[0] - 0.3).abs() < 0.01, "{o:?}");
        assert!((o.amplitude[1] - 0.05).abs() < 0.005, "{o:?}");
        assert!((o.amplitude[6] - 0.02).abs() < 0.003, "{o:?}");
        assert!(o.amplitude[4] < 0.005, "{o:?}");
        assert!(o.floor[0] < 0.01 && o.floor[1] < 0.01, "{o:?}");
    }
}
