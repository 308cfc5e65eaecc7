//! Supervised training of the classifier network: class-weighted cross-entropy, Adam,
//! inverted dropout, mini-batches, early stopping on the validation loss (best weights kept),
//! optional spectral augmentation, all driven by one seed so a run is reproducible.

use crate::model::mlp::{softmax, Adam, Mlp};
use crate::model::preprocess::Preprocess;
use ndarray::{Array2, ArrayView2, Axis};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Labelled feature windows and the recording each came from.
#[derive(Debug, Clone, Default)]
pub struct Windows {
    /// Raw features, one row per window.
    pub x: Array2<f32>,
    /// Class index per window.
    pub y: Vec<usize>,
    /// Recording index per window (into the caller's recording list).
    pub rec: Vec<usize>,
}

impl Windows {
    pub fn len(&self) -> usize {
        self.y.len()
    }
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }
}

/// Hyper-parameters (defaults follow the thesis network, Table 4.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrainConfig {
    pub seed: u64,
    /// Maximum number of epochs.
    pub epochs: usize,
    /// Stop when the validation loss has not improved for this many epochs.
    pub patience: usize,
    pub batch: usize,
    pub lr: f32,
    pub weight_decay: f32,
    pub dropout: f32,
    /// Hidden layer widths.
    pub hidden: Vec<usize>,
    /// Strength of the training-time spectral augmentation (0 = off): random spectral tilt
    /// and per-bin gain jitter, applied to raw features before the normalisation.
    pub augment: f32,
    /// Relative floor of the log-ratio normalisation.
    pub floor: f32,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            seed: 1,
            epochs: 200,
            patience: 25,
            batch: 64,
            lr: 1e-3,
            weight_decay: 1e-4,
            dropout: 0.2,
            hidden: vec![128, 128, 128],
            augment: 2.0,
            floor: Preprocess::DEFAULT_FLOOR,
        }
    }
}

/// Figures of one epoch.
#[derive(Debug, Clone, Serialize)]
pub struct EpochStats {
    pub epoch: usize,
    pub train_loss: f32,
    pub val_loss: f32,
    pub val_window_accuracy: f32,
}

/// What training returns.
pub struct Trained {
    pub pre: Preprocess,
    pub mlp: Mlp,
    pub history: Vec<EpochStats>,
    /// Epoch whose weights were kept (1-based).
    pub best_epoch: usize,
}

/// Per-class weights `n / (classes * n_c)` so every class counts alike in the loss.
pub fn class_weights(y: &[usize], n_classes: usize) -> Vec<f32> {
    let mut count = vec![0usize; n_classes];
    for &c in y {
        count[c] += 1;
    }
    count
        .iter()
        .map(|&n_c| {
            if n_c == 0 {
                0.0
            } else {
                y.len() as f32 / (n_classes as f32 * n_c as f32)
            }
        })
        .collect()
}

/// Weighted mean cross-entropy and its gradient w.r.t. the logits.
pub fn weighted_ce(logits: ArrayView2<f32>, y: &[usize], w: &[f32]) -> (f32, Array2<f32>) {
    let mut p = softmax(logits);
    let wsum: f32 = y.iter().map(|&c| w[c]).sum::<f32>().max(1e-12);
    let mut loss = 0.0f64;
    for (i, &c) in y.iter().enumerate() {
        loss -= (w[c] * p[[i, c]].max(1e-12).ln()) as f64;
        p[[i, c]] -= 1.0;
        p.row_mut(i).mapv_inplace(|v| v * w[c] / wsum);
    }
    ((loss / wsum as f64) as f32, p)
}

/// Random spectral tilt and per-bin gain jitter on raw (non-negative) features.
pub fn augment(x: &mut Array2<f32>, strength: f32, rng: &mut impl Rng) {
    if strength <= 0.0 {
        return;
    }
    let n = x.ncols().max(2);
    let jitter = Normal::new(0.0f32, 0.15 * strength).expect("valid sd");
    for mut row in x.axis_iter_mut(Axis(0)) {
        let tilt = (rng.random::<f32>() * 2.0 - 1.0) * 2.0 * strength;
        for (j, v) in row.iter_mut().enumerate() {
            let pos = j as f32 / (n - 1) as f32 - 0.5;
            *v *= (tilt * pos + jitter.sample(rng)).exp();
        }
    }
}

fn rows(x: &Array2<f32>, idx: &[usize]) -> Array2<f32> {
    x.select(Axis(0), idx)
}

/// Accuracy of argmax predictions.
pub fn accuracy(probs: ArrayView2<f32>, y: &[usize]) -> f32 {
    let pred = crate::model::classifier::TrainedModel::argmax(probs);
    let ok = pred.iter().zip(y).filter(|(a, b)| a == b).count();
    ok as f32 / y.len().max(1) as f32
}

/// Train from scratch. `val` may be empty (then the training loss drives early stopping).
/// `on_epoch` is called after every epoch (progress display).
pub fn train(
    train: &Windows,
    val: &Windows,
    n_classes: usize,
    cfg: &TrainConfig,
    mut on_epoch: impl FnMut(&EpochStats),
) -> Trained {
    let mut rng = rand::rngs::StdRng::seed_from_u64(cfg.seed);
    let pre = Preprocess::fit(train.x.view(), cfg.floor);
    let z_train = pre.apply(train.x.view());
    let z_val = pre.apply(val.x.view());
    let mut sizes = vec![train.x.ncols()];
    sizes.extend_from_slice(&cfg.hidden);
    sizes.push(n_classes);
    let mut mlp = Mlp::new(&sizes, &mut rng);
    let mut adam = Adam::new(&mlp, cfg.lr, cfg.weight_decay);
    let w = class_weights(&train.y, n_classes);
    let w_val = if val.is_empty() {
        w.clone()
    } else {
        class_weights(&val.y, n_classes)
    };
    let mut order: Vec<usize> = (0..train.len()).collect();
    let (mut best, mut best_epoch, mut best_mlp, mut wait) = (f32::INFINITY, 0, mlp.clone(), 0);
    let mut history = Vec::new();
    for epoch in 1..=cfg.epochs {
        order.shuffle(&mut rng);
        let mut tl = 0.0f64;
        for chunk in order.chunks(cfg.batch.max(1)) {
            let xb = if cfg.augment > 0.0 {
                let mut raw = rows(&train.x, chunk);
                augment(&mut raw, cfg.augment, &mut rng);
                pre.apply(raw.view())
            } else {
                rows(&z_train, chunk)
            };
            let yb: Vec<usize> = chunk.iter().map(|&i| train.y[i]).collect();
            let (logits, trace) = mlp.forward_train(xb.view(), cfg.dropout, &mut rng);
            let (loss, d) = weighted_ce(logits.view(), &yb, &w);
            tl += loss as f64 * chunk.len() as f64;
            let g = mlp.backward(&trace, d, false);
            adam.step(&mut mlp, &g, 0);
        }
        let train_loss = (tl / train.len().max(1) as f64) as f32;
        let (val_loss, val_acc) = if val.is_empty() {
            (train_loss, f32::NAN)
        } else {
            let (_, lg) = mlp.forward(z_val.view());
            let (l, _) = weighted_ce(lg.view(), &val.y, &w_val);
            (l, accuracy(softmax(lg.view()).view(), &val.y))
        };
        let st = EpochStats {
            epoch,
            train_loss,
            val_loss,
            val_window_accuracy: val_acc,
        };
        on_epoch(&st);
        history.push(st);
        if val_loss < best - 1e-5 {
            best = val_loss;
            best_epoch = epoch;
            best_mlp = mlp.clone();
            wait = 0;
        } else {
            wait += 1;
            if wait >= cfg.patience {
                break;
            }
        }
    }
    Trained {
        pre,
        mlp: best_mlp,
        history,
        best_epoch,
    }
}

/// Retrain only the output layer (hidden layers frozen) for `epochs` epochs on `data`:
/// the thesis' fine-tuning step. Returns the new network; `pre` is left as it is.
pub fn train_output_layer(pre: &Preprocess, mlp: &Mlp, data: &Windows, cfg: &TrainConfig) -> Mlp {
    let mut rng = rand::rngs::StdRng::seed_from_u64(cfg.seed);
    let mut mlp = mlp.clone();
    let n_classes = mlp.n_classes();
    let last = mlp.layers.len() - 1;
    let z = pre.apply(data.x.view());
    let w = class_weights(&data.y, n_classes);
    let mut adam = Adam::new(&mlp, cfg.lr, cfg.weight_decay);
    let mut order: Vec<usize> = (0..data.len()).collect();
    for _ in 0..cfg.epochs {
        order.shuffle(&mut rng);
        for chunk in order.chunks(cfg.batch.max(1)) {
            let xb = rows(&z, chunk);
            let yb: Vec<usize> = chunk.iter().map(|&i| data.y[i]).collect();
            let (logits, trace) = mlp.forward_train(xb.view(), cfg.dropout, &mut rng);
            let (_, d) = weighted_ce(logits.view(), &yb, &w);
            let g = mlp.backward(&trace, d, true);
            adam.step(&mut mlp, &g, last);
        }
    }
    mlp
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three separable synthetic "spectra" (peaks at different bins, random overall gain).
    pub(crate) fn synthetic(n_per: usize, seed: u64) -> Windows {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let n = 3 * n_per;
        let mut x = Array2::<f32>::zeros((n, 20));
        let mut y = Vec::new();
        for i in 0..n {
            let c = i % 3;
            let gain = 10f32.powf(rng.random::<f32>() * 4.0 - 2.0);
            for j in 0..20 {
                let peak = if c > 0 && j % (3 + 2 * c) == 0 {
                    4.0
                } else {
                    0.0
                };
                x[[i, j]] = gain * (1.0 + peak + rng.random::<f32>());
            }
            y.push(c);
        }
        Windows {
            x,
            y,
            rec: (0..n).map(|i| i / 10).collect(),
        }
    }

    #[test]
    fn learns_separable_data_and_is_reproducible() {
        let tr = synthetic(60, 1);
        let va = synthetic(15, 2);
        let cfg = TrainConfig {
            epochs: 40,
            patience: 10,
            hidden: vec![16, 16],
            augment: 0.0,
            ..Default::default()
        };
        let a = train(&tr, &va, 3, &cfg, |_| {});
        let b = train(&tr, &va, 3, &cfg, |_| {});
        assert_eq!(a.mlp, b.mlp, "same seed must give identical weights");
        let (_, lg) = a.mlp.forward(a.pre.apply(va.x.view()).view());
        let acc = accuracy(softmax(lg.view()).view(), &va.y);
        assert!(acc > 0.95, "validation accuracy {acc}");
    }

    #[test]
    fn augmentation_keeps_spectra_positive_and_is_seeded() {
        let x0 = synthetic(4, 9).x;
        let run = |seed| {
            let mut x = x0.clone();
            augment(&mut x, 2.0, &mut rand::rngs::StdRng::seed_from_u64(seed));
            x
        };
        let (a, b, c) = (run(1), run(1), run(2));
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|v| v.is_finite() && *v > 0.0));
        assert_ne!(a, x0);
        let mut same = x0.clone();
        augment(&mut same, 0.0, &mut rand::rngs::StdRng::seed_from_u64(1));
        assert_eq!(same, x0, "strength 0 is off");
    }

    #[test]
    fn output_layer_training_leaves_hidden_layers_alone() {
        let tr = synthetic(30, 3);
        let cfg = TrainConfig {
            epochs: 5,
            hidden: vec![8, 8],
            ..Default::default()
        };
        let t = train(&tr, &Windows::default_like(&tr), 3, &cfg, |_| {});
        let ft = train_output_layer(&t.pre, &t.mlp, &synthetic(10, 4), &cfg);
        for i in 0..2 {
            assert_eq!(ft.layers[i], t.mlp.layers[i], "hidden layer {i} changed");
        }
        assert_ne!(ft.layers[2], t.mlp.layers[2]);
    }

    impl Windows {
        fn default_like(w: &Windows) -> Windows {
            Windows {
                x: Array2::zeros((0, w.x.ncols())),
                y: vec![],
                rec: vec![],
            }
        }
    }
}
