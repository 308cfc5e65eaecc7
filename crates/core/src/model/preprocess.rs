//! The feature normalisation that lives inside the ONNX graph: a per-window scale-free
//! transform (log of each bin relative to the window's mean bin) followed by per-feature
//! standardisation fitted on the training windows. Simulated and measured amplitudes differ
//! by orders of magnitude; ratios within one spectrum transfer, absolute levels do not.

use ndarray::{Array1, Array2, ArrayView2, Axis};

/// Added to the window mean before dividing, so an all-zero window (dead sensor) stays finite.
pub const TINY: f32 = 1e-20;

/// Fixed part of the transform: `ln(x / (mean(x) + TINY) + floor)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Preprocess {
    /// Relative floor added to the ratio before the logarithm (keeps empty bins finite).
    pub floor: f32,
    /// Per-feature mean of the log ratios on the training windows.
    pub mean: Array1<f32>,
    /// Per-feature 1 / standard deviation of the log ratios on the training windows.
    pub inv_std: Array1<f32>,
}

/// Name stored in the model metadata for this transform.
pub const NORMALIZATION_NAME: &str = "log_mean_ratio+standardize";

impl Preprocess {
    /// Default relative floor: bins 60 dB below the window's mean bin are treated alike.
    pub const DEFAULT_FLOOR: f32 = 1e-3;

    /// The scale-free part alone (no standardisation), row by row.
    pub fn log_ratio(x: ArrayView2<f32>, floor: f32) -> Array2<f32> {
        let mut out = x.to_owned();
        for mut row in out.axis_iter_mut(Axis(0)) {
            let n = row.len().max(1) as f32;
            let mean = row.iter().sum::<f32>() / n;
            let denom = mean + TINY;
            row.mapv_inplace(|v| (v / denom + floor).ln());
        }
        out
    }

    /// Fit the standardisation on training windows (rows = windows, columns = raw features).
    pub fn fit(x: ArrayView2<f32>, floor: f32) -> Preprocess {
        let l = Self::log_ratio(x, floor);
        let n = l.nrows().max(1) as f64;
        let cols = l.ncols();
        let mut mean = Array1::<f32>::zeros(cols);
        let mut inv_std = Array1::<f32>::ones(cols);
        for j in 0..cols {
            let col = l.column(j);
            let m = col.iter().map(|&v| v as f64).sum::<f64>() / n;
            let var = col.iter().map(|&v| (v as f64 - m).powi(2)).sum::<f64>() / n;
            mean[j] = m as f32;
            // A feature that never varies carries no information: keep it at zero after centring.
            inv_std[j] = (1.0 / var.sqrt().max(1e-3)) as f32;
        }
        Preprocess {
            floor,
            mean,
            inv_std,
        }
    }

    /// Apply the whole transform, exactly as the ONNX graph does it (same operation order).
    pub fn apply(&self, x: ArrayView2<f32>) -> Array2<f32> {
        let mut l = Self::log_ratio(x, self.floor);
        for mut row in l.axis_iter_mut(Axis(0)) {
            for ((v, &m), &s) in row
                .iter_mut()
                .zip(self.mean.iter())
                .zip(self.inv_std.iter())
            {
                *v = (*v - m) * s;
            }
        }
        l
    }

    pub fn n_features(&self) -> usize {
        self.mean.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

    #[test]
    fn scale_free_per_window() {
        let x = array![[1.0f32, 2.0, 4.0, 0.5], [1000.0, 2000.0, 4000.0, 500.0]];
        let l = Preprocess::log_ratio(x.view(), 1e-3);
        for j in 0..4 {
            assert!(
                (l[[0, j]] - l[[1, j]]).abs() < 1e-5,
                "column {j}: {} vs {}",
                l[[0, j]],
                l[[1, j]]
            );
        }
    }

    #[test]
    fn standardised_training_columns_have_zero_mean_unit_std() {
        let x = array![
            [1.0f32, 2.0, 3.0],
            [2.0, 1.0, 3.0],
            [1.0, 1.0, 5.0],
            [3.0, 2.0, 1.0]
        ];
        let p = Preprocess::fit(x.view(), 1e-3);
        let z = p.apply(x.view());
        for j in 0..3 {
            let m: f32 = z.column(j).sum() / 4.0;
            let v: f32 = z.column(j).iter().map(|a| (a - m).powi(2)).sum::<f32>() / 4.0;
            assert!(
                m.abs() < 1e-5 && (v - 1.0).abs() < 1e-4,
                "column {j}: mean {m} var {v}"
            );
        }
    }

    #[test]
    fn dead_sensor_stays_finite() {
        let x = Array2::<f32>::zeros((1, 5));
        let l = Preprocess::log_ratio(x.view(), 1e-3);
        assert!(l.iter().all(|v| v.is_finite()));
    }
}
