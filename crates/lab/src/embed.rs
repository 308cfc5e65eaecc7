//! 2-D embeddings of feature windows for the domain-gap picture (thesis Fig. 4.5): exact
//! t-SNE (O(N^2), fine for a few thousand windows) and PCA. Inputs are rows of already
//! normalised features; colouring by class and domain is done by `plots::embedding`.

use anyhow::{bail, Result};
use ndarray::{Array1, Array2, ArrayView2, Axis};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// Which embedding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    Tsne,
    Pca,
}

/// t-SNE settings.
#[derive(Debug, Clone)]
pub struct TsneConfig {
    pub perplexity: f64,
    pub iterations: usize,
    pub seed: u64,
}

impl Default for TsneConfig {
    fn default() -> Self {
        TsneConfig {
            perplexity: 30.0,
            iterations: 750,
            seed: 1,
        }
    }
}

/// First two principal components (scores), by power iteration with deflation.
pub fn pca(x: ArrayView2<f32>) -> Array2<f32> {
    let n = x.nrows();
    let xd = x.mapv(|v| v as f64);
    let mean = xd
        .mean_axis(Axis(0))
        .unwrap_or_else(|| Array1::zeros(x.ncols()));
    let c = &xd - &mean;
    let mut cov = c.t().dot(&c) / (n.max(2) - 1) as f64;
    let d = cov.nrows();
    let mut out = Array2::<f32>::zeros((n, 2));
    for k in 0..2 {
        let mut v = Array1::from_shape_fn(d, |i| 1.0 + (i as f64 * 0.618).fract());
        for _ in 0..500 {
            let w = cov.dot(&v);
            let norm = w.dot(&w).sqrt();
            if norm < 1e-300 {
                break;
            }
            v = w / norm;
        }
        let lambda = v.dot(&cov.dot(&v));
        for i in 0..d {
            for j in 0..d {
                cov[[i, j]] -= lambda * v[i] * v[j];
            }
        }
        let s = c.dot(&v);
        out.column_mut(k).assign(&s.mapv(|v| v as f32));
    }
    out
}

/// Exact t-SNE to two dimensions.
pub fn tsne(x: ArrayView2<f32>, cfg: &TsneConfig) -> Result<Array2<f32>> {
    let n = x.nrows();
    if n < 5 {
        bail!("t-SNE needs at least 5 windows, got {n}");
    }
    let perp = cfg.perplexity.min((n as f64 - 1.0) / 3.0).max(2.0);
    // Squared distances.
    let sq: Vec<f64> = x
        .rows()
        .into_iter()
        .map(|r| r.iter().map(|&v| (v as f64).powi(2)).sum())
        .collect();
    let xd = x.mapv(|v| v as f64);
    let g = xd.dot(&xd.t());
    // Conditional probabilities with a per-point bandwidth matching the perplexity.
    let target = perp.ln();
    let rows: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let d: Vec<f64> = (0..n)
                .map(|j| (sq[i] + sq[j] - 2.0 * g[[i, j]]).max(0.0))
                .collect();
            let (mut lo, mut hi, mut beta) = (0.0f64, f64::INFINITY, 1.0f64);
            let mut p = vec![0.0; n];
            for _ in 0..64 {
                let mut sum = 0.0;
                for j in 0..n {
                    p[j] = if j == i { 0.0 } else { (-d[j] * beta).exp() };
                    sum += p[j];
                }
                let sum = sum.max(1e-300);
                let mut h = 0.0;
                for j in 0..n {
                    p[j] /= sum;
                    if p[j] > 1e-300 {
                        h -= p[j] * p[j].ln();
                    }
                }
                if (h - target).abs() < 1e-5 {
                    break;
                }
                if h > target {
                    lo = beta;
                    beta = if hi.is_finite() {
                        (beta + hi) / 2.0
                    } else {
                        beta * 2.0
                    };
                } else {
                    hi = beta;
                    beta = (beta + lo) / 2.0;
                }
            }
            p
        })
        .collect();
    let mut p = Array2::<f64>::zeros((n, n));
    for i in 0..n {
        for j in 0..n {
            p[[i, j]] = ((rows[i][j] + rows[j][i]) / (2.0 * n as f64)).max(1e-12);
        }
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(cfg.seed);
    let init = Normal::new(0.0, 1e-4).expect("valid sd");
    let mut y = Array2::<f64>::from_shape_fn((n, 2), |_| init.sample(&mut rng));
    let mut vel = Array2::<f64>::zeros((n, 2));
    let mut gains = Array2::<f64>::ones((n, 2));
    let lr = (n as f64 / 12.0).max(50.0);
    for it in 0..cfg.iterations {
        let exag = if it < 250 { 12.0 } else { 1.0 };
        let mom = if it < 250 { 0.5 } else { 0.8 };
        // Student-t affinities.
        let num: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|i| {
                (0..n)
                    .map(|j| {
                        if i == j {
                            0.0
                        } else {
                            let dx = y[[i, 0]] - y[[j, 0]];
                            let dy = y[[i, 1]] - y[[j, 1]];
                            1.0 / (1.0 + dx * dx + dy * dy)
                        }
                    })
                    .collect()
            })
            .collect();
        let z: f64 = num
            .iter()
            .map(|r| r.iter().sum::<f64>())
            .sum::<f64>()
            .max(1e-300);
        let grad: Vec<[f64; 2]> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut gx = [0.0; 2];
                for j in 0..n {
                    let q = num[i][j];
                    let m = (exag * p[[i, j]] - q / z) * q;
                    gx[0] += m * (y[[i, 0]] - y[[j, 0]]);
                    gx[1] += m * (y[[i, 1]] - y[[j, 1]]);
                }
                [4.0 * gx[0], 4.0 * gx[1]]
            })
            .collect();
        for i in 0..n {
            for k in 0..2 {
                let gk = grad[i][k];
                gains[[i, k]] = if (gk > 0.0) != (vel[[i, k]] > 0.0) {
                    gains[[i, k]] + 0.2
                } else {
                    (gains[[i, k]] * 0.8).max(0.01)
                };
                vel[[i, k]] = mom * vel[[i, k]] - lr * gains[[i, k]] * gk;
                y[[i, k]] += vel[[i, k]];
            }
        }
        let mean = y.mean_axis(Axis(0)).expect("n > 0");
        y -= &mean;
    }
    Ok(y.mapv(|v| v as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clusters() -> (Array2<f32>, Vec<usize>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let noise = Normal::new(0.0f32, 0.3).unwrap();
        let mut x = Array2::<f32>::zeros((60, 10));
        let mut lab = Vec::new();
        for i in 0..60 {
            let c = i % 3;
            for j in 0..10 {
                x[[i, j]] = if j == c * 3 { 5.0 } else { 0.0 } + noise.sample(&mut rng);
            }
            lab.push(c);
        }
        (x, lab)
    }

    /// Each point's nearest neighbour in the embedding belongs to its own cluster.
    fn neighbour_purity(y: &Array2<f32>, lab: &[usize]) -> f64 {
        let n = y.nrows();
        let mut ok = 0;
        for i in 0..n {
            let nn = (0..n)
                .filter(|&j| j != i)
                .min_by(|&a, &b| {
                    let da = (y[[i, 0]] - y[[a, 0]]).powi(2) + (y[[i, 1]] - y[[a, 1]]).powi(2);
                    let db = (y[[i, 0]] - y[[b, 0]]).powi(2) + (y[[i, 1]] - y[[b, 1]]).powi(2);
                    da.total_cmp(&db)
                })
                .unwrap();
            ok += usize::from(lab[nn] == lab[i]);
        }
        ok as f64 / n as f64
    }

    #[test]
    fn tsne_and_pca_keep_clusters_apart() {
        let (x, lab) = clusters();
        let t = tsne(
            x.view(),
            &TsneConfig {
                iterations: 300,
                perplexity: 10.0,
                seed: 1,
            },
        )
        .unwrap();
        assert!(neighbour_purity(&t, &lab) > 0.95);
        let p = pca(x.view());
        assert!(neighbour_purity(&p, &lab) > 0.95);
    }
}
