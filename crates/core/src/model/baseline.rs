//! The machine's healthy baseline: how far a window's spectrum lies from that machine's own
//! healthy windows, and the gate that stops a window far from it being called healthy.
//!
//! Distance: the RMS of the [`TOP`] largest `((l_j - r_j) * inv_spread)^2` over the scale-free
//! log ratios `l = ln(x / mean(x) + floor)` (the graph's own transform), with `r` the mean of
//! the machine's healthy windows and `inv_spread` one pooled 1/std of those windows. A fault
//! changes a few bins (its orders, harmonics, sidebands); a mean over all bins would dilute it
//! (on the fan-end records the top-10 RMS flags 47-79 % of the windows of the faint 0.007 in
//! outer-race faults at 3 and 12 o'clock where the all-bin RMS flags 5-53 %;
//! `docs/study/baseline_distance.py`). A window with
//! `d > threshold` cannot be `healthy`: the healthy probability is set to zero and the others
//! renormalised, so the record raises an alarm even when the network, trained on simulation,
//! sees no fault it knows. The same arithmetic runs in the ONNX graph ([`super::export`]).

use super::preprocess::Preprocess;
use anyhow::{bail, Result};
use ndarray::{Array1, ArrayView2, Axis};

/// How many of the largest squared deviations the distance averages.
pub const TOP: usize = 10;
/// Margin on the largest leave-one-out distance of the healthy windows (see [`fit`]).
pub const MARGIN: f32 = 1.5;
/// Probability given to each non-healthy class when the gate closes (keeps 0/0 away).
pub const GATE_EPS: f32 = 1e-6;

/// A fitted healthy baseline (stored in the model as initializers `baseline_*`).
#[derive(Debug, Clone, PartialEq)]
pub struct HealthyBaseline {
    /// Mean log ratio per feature of the machine's healthy windows.
    pub reference: Array1<f32>,
    /// 1 / pooled standard deviation of those windows around `reference`.
    pub inv_spread: f32,
    /// Distances above this close the healthy gate.
    pub threshold: f32,
}

impl HealthyBaseline {
    /// Fit from the machine's healthy windows (raw features, rows = windows). The threshold
    /// is `MARGIN` x the largest leave-one-out distance: each window measured against the mean
    /// of the others, so it is an out-of-sample distance even with a handful of windows.
    pub fn fit(windows: ArrayView2<f32>, floor: f32) -> Result<HealthyBaseline> {
        let n = windows.nrows();
        if n < 3 {
            bail!("a healthy baseline needs at least 3 windows, got {n}");
        }
        let l = Preprocess::log_ratio(windows, floor);
        let reference = l.mean_axis(Axis(0)).expect("rows > 0");
        let dev = &l - &reference;
        let var = dev.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / dev.len() as f64;
        let inv_spread = (1.0 / var.sqrt().max(1e-6)) as f32;
        let sum = l.sum_axis(Axis(0));
        let mut worst = 0.0f32;
        for row in l.rows() {
            let others = (&sum - &row) / (n - 1) as f32;
            worst = worst.max(distance(row.iter().copied(), &others, inv_spread));
        }
        Ok(HealthyBaseline {
            reference,
            inv_spread,
            threshold: MARGIN * worst,
        })
    }

    /// Distance of each window (raw features) from the baseline.
    pub fn distances(&self, x: ArrayView2<f32>, floor: f32) -> Array1<f32> {
        let l = Preprocess::log_ratio(x, floor);
        l.rows()
            .into_iter()
            .map(|r| distance(r.iter().copied(), &self.reference, self.inv_spread))
            .collect()
    }

    /// Close the healthy gate in `probs` (rows = windows) where `d > threshold`.
    pub fn gate(&self, probs: &mut ndarray::Array2<f32>, d: &Array1<f32>, healthy: usize) {
        for (mut row, &di) in probs.rows_mut().into_iter().zip(d.iter()) {
            if di > self.threshold {
                for (j, p) in row.iter_mut().enumerate() {
                    *p = if j == healthy { 0.0 } else { *p + GATE_EPS };
                }
                let s: f32 = row.sum();
                row.mapv_inplace(|p| p / s);
            }
        }
    }
}

fn distance(l: impl Iterator<Item = f32>, reference: &Array1<f32>, inv_spread: f32) -> f32 {
    let mut top = [0.0f32; TOP];
    let mut n = 0usize;
    for (v, r) in l.zip(reference.iter()) {
        let e = (v - r) * inv_spread;
        let e2 = e * e;
        // keep the TOP largest, smallest first
        if n < TOP {
            top[n] = e2;
            n += 1;
            top[..n].sort_by(f32::total_cmp);
        } else if e2 > top[0] {
            top[0] = e2;
            top.sort_by(f32::total_cmp);
        }
    }
    let k = n.max(1);
    (top[..n].iter().sum::<f32>() / k as f32).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn windows(line: f32, n: usize) -> Array2<f32> {
        Array2::from_shape_fn((n, 20), |(i, j)| {
            let noise = 1.0 + 0.05 * (((i * 31 + j * 17) % 7) as f32 - 3.0);
            let l = if j == 6 { line } else { 1.0 };
            l * noise
        })
    }

    #[test]
    fn healthy_windows_pass_a_new_line_closes_the_gate() {
        let b = HealthyBaseline::fit(windows(1.0, 8).view(), 1e-3).unwrap();
        let d_h = b.distances(windows(1.0, 5).view(), 1e-3);
        assert!(
            d_h.iter().all(|&d| d <= b.threshold),
            "{d_h} vs {}",
            b.threshold
        );
        let d_f = b.distances(windows(4.0, 5).view(), 1e-3);
        assert!(
            d_f.iter().all(|&d| d > b.threshold),
            "{d_f} vs {}",
            b.threshold
        );
        let mut p = Array2::from_shape_vec((1, 3), vec![0.9f32, 0.06, 0.04]).unwrap();
        b.gate(&mut p, &d_f.slice(ndarray::s![..1]).to_owned(), 0);
        assert_eq!(p[[0, 0]], 0.0);
        assert!((p.sum() - 1.0).abs() < 1e-6 && p[[0, 1]] > p[[0, 2]], "{p}");
    }

    #[test]
    fn too_few_windows_is_an_error() {
        assert!(HealthyBaseline::fit(windows(1.0, 2).view(), 1e-3).is_err());
    }
}
