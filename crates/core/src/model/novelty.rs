//! Novelty score: Mahalanobis distance of the last hidden layer to the nearest class centroid,
//! with one shared (shrunk) covariance fitted on the training windows. The graph computes
//! `sqrt(min_c |(h - mu_c) W|^2)` with `W` a whitening matrix (`W W^T = Sigma^-1`); a window
//! whose score exceeds the threshold (calibrated on validation windows) is `unknown`.

use anyhow::{bail, Result};
use ndarray::{Array1, Array2, ArrayView2, Axis};

/// The fitted novelty detector.
#[derive(Debug, Clone, PartialEq)]
pub struct Mahalanobis {
    /// Whitening matrix `[K, K]` applied as `g = h W`.
    pub whiten: Array2<f32>,
    /// Class centroids in whitened space `[C, K]`.
    pub centroids: Array2<f32>,
    /// Scores above this are `unknown`.
    pub threshold: f32,
}

impl Mahalanobis {
    /// Fit centroids and a shared covariance (shrunk towards its mean variance by
    /// `shrinkage` in 0..1, so dead ReLU units keep it invertible).
    pub fn fit(
        h: ArrayView2<f32>,
        labels: &[usize],
        n_classes: usize,
        shrinkage: f64,
    ) -> Result<Mahalanobis> {
        let (n, k) = h.dim();
        if n != labels.len() || n == 0 {
            bail!(
                "novelty fit: {n} hidden vectors but {} labels",
                labels.len()
            );
        }
        let mut mu = Array2::<f64>::zeros((n_classes, k));
        let mut count = vec![0usize; n_classes];
        for (row, &c) in h.rows().into_iter().zip(labels) {
            count[c] += 1;
            for (m, &v) in mu.row_mut(c).iter_mut().zip(row.iter()) {
                *m += v as f64;
            }
        }
        for (mut row, &n_c) in mu.rows_mut().into_iter().zip(&count) {
            if n_c > 0 {
                row.mapv_inplace(|v| v / n_c as f64);
            }
        }
        let mut cov = Array2::<f64>::zeros((k, k));
        let mut d = Array1::<f64>::zeros(k);
        for (row, &c) in h.rows().into_iter().zip(labels) {
            for j in 0..k {
                d[j] = row[j] as f64 - mu[[c, j]];
            }
            for a in 0..k {
                let da = d[a];
                if da == 0.0 {
                    continue;
                }
                for b in 0..k {
                    cov[[a, b]] += da * d[b];
                }
            }
        }
        cov.mapv_inplace(|v| v / n as f64);
        let avg_var = (0..k).map(|j| cov[[j, j]]).sum::<f64>() / k as f64;
        let floor = avg_var.max(1e-6);
        for a in 0..k {
            for b in 0..k {
                cov[[a, b]] *= 1.0 - shrinkage;
            }
            cov[[a, a]] += shrinkage * floor;
        }
        // Sigma = L L^T  =>  Sigma^-1 = L^-T L^-1, so |L^-1 d|^2 is the squared distance and
        // W = (L^-1)^T makes it |d W|^2 for row vectors.
        let l = cholesky(&cov)?;
        let linv = lower_inverse(&l);
        let whiten64 = linv.t().to_owned();
        let whiten = whiten64.mapv(|v| v as f32);
        let centroids = mu.dot(&whiten64).mapv(|v| v as f32);
        Ok(Mahalanobis {
            whiten,
            centroids,
            threshold: f32::INFINITY,
        })
    }

    /// Scores for a batch of last-hidden-layer vectors, computed as the ONNX graph does.
    pub fn score(&self, h: ArrayView2<f32>) -> Array1<f32> {
        let g = h.dot(&self.whiten);
        g.axis_iter(Axis(0))
            .map(|row| {
                self.centroids
                    .rows()
                    .into_iter()
                    .map(|c| {
                        row.iter()
                            .zip(c.iter())
                            .map(|(a, b)| (a - b) * (a - b))
                            .sum::<f32>()
                    })
                    .fold(f32::INFINITY, f32::min)
                    .sqrt()
            })
            .collect()
    }

    /// Set the threshold to the `q` quantile of `scores` times `margin`.
    pub fn calibrate(&mut self, scores: &[f32], q: f64, margin: f32) {
        let mut s: Vec<f32> = scores.iter().copied().filter(|v| v.is_finite()).collect();
        if s.is_empty() {
            return;
        }
        s.sort_by(f32::total_cmp);
        let idx = ((s.len() - 1) as f64 * q).round() as usize;
        self.threshold = s[idx.min(s.len() - 1)] * margin;
    }
}

fn cholesky(a: &Array2<f64>) -> Result<Array2<f64>> {
    let n = a.nrows();
    let mut l = Array2::<f64>::zeros((n, n));
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[[i, j]];
            for p in 0..j {
                s -= l[[i, p]] * l[[j, p]];
            }
            if i == j {
                if s <= 0.0 {
                    bail!(
                        "novelty fit: covariance is not positive definite at row {i} (pivot {s:e})"
                    );
                }
                l[[i, i]] = s.sqrt();
            } else {
                l[[i, j]] = s / l[[j, j]];
            }
        }
    }
    Ok(l)
}

fn lower_inverse(l: &Array2<f64>) -> Array2<f64> {
    let n = l.nrows();
    let mut inv = Array2::<f64>::zeros((n, n));
    for col in 0..n {
        for i in col..n {
            let mut s = if i == col { 1.0 } else { 0.0 };
            for p in col..i {
                s -= l[[i, p]] * inv[[p, col]];
            }
            inv[[i, col]] = s / l[[i, i]];
        }
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn whitening_gives_mahalanobis_distance() {
        // Two correlated dimensions, one class: distance of a point along the narrow axis is
        // larger than the same Euclidean offset along the wide axis.
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let mut rows = Vec::new();
        for _ in 0..2000 {
            let a: f32 = rng.random::<f32>() - 0.5;
            let b: f32 = (rng.random::<f32>() - 0.5) * 0.1;
            rows.extend_from_slice(&[a + b, a - b]);
        }
        let h = Array2::from_shape_vec((2000, 2), rows).unwrap();
        let m = Mahalanobis::fit(h.view(), &vec![0; 2000], 1, 0.0).unwrap();
        let probe = ndarray::array![[0.2f32, 0.2], [0.2, -0.2]];
        let s = m.score(probe.view());
        assert!(
            s[1] > 5.0 * s[0],
            "narrow-axis offset {} should be far beyond wide-axis offset {}",
            s[1],
            s[0]
        );
    }

    #[test]
    fn threshold_is_a_quantile() {
        let mut m = Mahalanobis {
            whiten: Array2::eye(1),
            centroids: Array2::zeros((1, 1)),
            threshold: 0.0,
        };
        let scores: Vec<f32> = (0..101).map(|v| v as f32).collect();
        m.calibrate(&scores, 0.99, 1.0);
        assert_eq!(m.threshold, 99.0);
    }
}
