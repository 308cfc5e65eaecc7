//! The in-memory classifier network (thesis Table 4.1): dense layers with ReLU and dropout
//! between them and a softmax output. Forward for inference, forward with dropout masks and
//! backward for training. Weights are stored `[out, in]`, as ONNX `Gemm(transB = 1)` reads them.

use ndarray::{Array1, Array2, ArrayView2, Axis};
use rand::Rng;
use rand_distr::{Distribution, Uniform};

/// One fully-connected layer: `y = x W^T + b`.
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    /// `[out, in]`.
    pub w: Array2<f32>,
    /// `[out]`.
    pub b: Array1<f32>,
}

impl Dense {
    /// He-uniform initialisation (suits ReLU), zero bias.
    pub fn init(n_in: usize, n_out: usize, rng: &mut impl Rng) -> Dense {
        let limit = (6.0 / n_in as f64).sqrt() as f32;
        let dist = Uniform::new_inclusive(-limit, limit).expect("valid range");
        let w = Array2::from_shape_fn((n_out, n_in), |_| dist.sample(rng));
        Dense {
            w,
            b: Array1::zeros(n_out),
        }
    }

    pub fn forward(&self, x: ArrayView2<f32>) -> Array2<f32> {
        let mut y = x.dot(&self.w.t());
        y += &self.b;
        y
    }

    pub fn n_in(&self) -> usize {
        self.w.ncols()
    }
    pub fn n_out(&self) -> usize {
        self.w.nrows()
    }
}

/// Hidden ReLU layers followed by a linear output layer (softmax applied on top).
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    /// Hidden layers then the output layer (last).
    pub layers: Vec<Dense>,
}

/// What a training forward pass keeps for the backward pass.
pub struct Trace {
    /// Input of each layer (after ReLU and dropout of the previous one).
    inputs: Vec<Array2<f32>>,
    /// Pre-activation of each hidden layer (for the ReLU derivative).
    pre: Vec<Array2<f32>>,
    /// Dropout scale mask per hidden layer (0 or 1/(1-p)).
    masks: Vec<Array2<f32>>,
}

/// Gradients, one `Dense` per layer.
pub type Grads = Vec<Dense>;

impl Mlp {
    /// `sizes` = [inputs, hidden..., classes], e.g. [100, 128, 128, 128, 3].
    pub fn new(sizes: &[usize], rng: &mut impl Rng) -> Mlp {
        let layers = sizes
            .windows(2)
            .map(|w| Dense::init(w[0], w[1], rng))
            .collect();
        Mlp { layers }
    }

    pub fn n_classes(&self) -> usize {
        self.layers.last().map_or(0, Dense::n_out)
    }

    pub fn n_inputs(&self) -> usize {
        self.layers.first().map_or(0, Dense::n_in)
    }

    /// Inference: returns (last hidden activation, logits).
    pub fn forward(&self, x: ArrayView2<f32>) -> (Array2<f32>, Array2<f32>) {
        let (hidden, out) = self.layers.split_at(self.layers.len() - 1);
        let mut h = x.to_owned();
        for l in hidden {
            h = l.forward(h.view());
            h.mapv_inplace(|v| v.max(0.0));
        }
        let logits = out[0].forward(h.view());
        (h, logits)
    }

    /// Training forward pass with inverted dropout of rate `p` after every hidden layer.
    pub fn forward_train(
        &self,
        x: ArrayView2<f32>,
        p: f32,
        rng: &mut impl Rng,
    ) -> (Array2<f32>, Trace) {
        let n_hidden = self.layers.len() - 1;
        let mut tr = Trace {
            inputs: Vec::new(),
            pre: Vec::new(),
            masks: Vec::new(),
        };
        let mut h = x.to_owned();
        let keep = 1.0 - p;
        for l in &self.layers[..n_hidden] {
            let pre = l.forward(h.view());
            let mask = Array2::from_shape_fn(pre.raw_dim(), |_| {
                if p > 0.0 && rng.random::<f32>() < p {
                    0.0
                } else {
                    1.0 / keep
                }
            });
            let mut a = pre.mapv(|v| v.max(0.0));
            a *= &mask;
            tr.inputs.push(h);
            tr.pre.push(pre);
            tr.masks.push(mask);
            h = a;
        }
        let logits = self.layers[n_hidden].forward(h.view());
        tr.inputs.push(h);
        (logits, tr)
    }

    /// Backward pass from d(loss)/d(logits). With `only_output` the hidden layers get no
    /// gradient (fine-tuning), and their entries in the result are zero.
    pub fn backward(&self, tr: &Trace, dlogits: Array2<f32>, only_output: bool) -> Grads {
        let n = self.layers.len();
        let mut grads: Vec<Dense> = self
            .layers
            .iter()
            .map(|l| Dense {
                w: Array2::zeros(l.w.raw_dim()),
                b: Array1::zeros(l.b.raw_dim()),
            })
            .collect();
        let mut d = dlogits;
        for i in (0..n).rev() {
            grads[i].w = d.t().dot(&tr.inputs[i]);
            grads[i].b = d.sum_axis(Axis(0));
            if i == 0 || only_output {
                break;
            }
            let mut dh = d.dot(&self.layers[i].w);
            dh *= &tr.masks[i - 1];
            ndarray::Zip::from(&mut dh)
                .and(&tr.pre[i - 1])
                .for_each(|g, &z| {
                    if z <= 0.0 {
                        *g = 0.0
                    }
                });
            d = dh;
        }
        grads
    }
}

/// Row-wise softmax, computed as the ONNX operator does (max subtracted first).
pub fn softmax(logits: ArrayView2<f32>) -> Array2<f32> {
    let mut p = logits.to_owned();
    for mut row in p.axis_iter_mut(Axis(0)) {
        let m = row.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
        row.mapv_inplace(|v| (v - m).exp());
        let s = row.sum();
        row.mapv_inplace(|v| v / s);
    }
    p
}

/// Adam optimiser state for an [`Mlp`].
pub struct Adam {
    pub lr: f32,
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    /// Decoupled weight decay (AdamW), applied to weights only.
    pub weight_decay: f32,
    t: i32,
    m: Grads,
    v: Grads,
}

impl Adam {
    pub fn new(model: &Mlp, lr: f32, weight_decay: f32) -> Adam {
        let zeros = || -> Grads {
            model
                .layers
                .iter()
                .map(|l| Dense {
                    w: Array2::zeros(l.w.raw_dim()),
                    b: Array1::zeros(l.b.raw_dim()),
                })
                .collect()
        };
        Adam {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay,
            t: 0,
            m: zeros(),
            v: zeros(),
        }
    }

    /// One update. Layers whose index is below `first_layer` are left untouched.
    pub fn step(&mut self, model: &mut Mlp, grads: &Grads, first_layer: usize) {
        self.t += 1;
        let (b1, b2) = (self.beta1, self.beta2);
        let c1 = 1.0 - b1.powi(self.t);
        let c2 = 1.0 - b2.powi(self.t);
        let (lr, eps, wd) = (self.lr, self.eps, self.weight_decay);
        for i in first_layer..model.layers.len() {
            let upd = |p: &mut f32, g: f32, m: &mut f32, v: &mut f32, decay: bool| {
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                let mh = *m / c1;
                let vh = *v / c2;
                if decay {
                    *p -= lr * wd * *p;
                }
                *p -= lr * mh / (vh.sqrt() + eps);
            };
            let layer = &mut model.layers[i];
            ndarray::Zip::from(&mut layer.w)
                .and(&grads[i].w)
                .and(&mut self.m[i].w)
                .and(&mut self.v[i].w)
                .for_each(|p, &g, m, v| upd(p, g, m, v, true));
            ndarray::Zip::from(&mut layer.b)
                .and(&grads[i].b)
                .and(&mut self.m[i].b)
                .and(&mut self.v[i].b)
                .for_each(|p, &g, m, v| upd(p, g, m, v, false));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// Finite-difference check of the analytic gradient (no dropout).
    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut mlp = Mlp::new(&[5, 6, 4, 3], &mut rng);
        let x = Array2::from_shape_fn((4, 5), |(i, j)| ((i * 5 + j) as f32 * 0.37).sin());
        let y = [0usize, 2, 1, 2];
        let loss = |m: &Mlp| -> f64 {
            let (_, lg) = m.forward(x.view());
            let p = softmax(lg.view());
            y.iter()
                .enumerate()
                .map(|(i, &c)| -(p[[i, c]] as f64).ln())
                .sum::<f64>()
        };
        let (logits, tr) = mlp.forward_train(x.view(), 0.0, &mut rng);
        let mut d = softmax(logits.view());
        for (i, &c) in y.iter().enumerate() {
            d[[i, c]] -= 1.0;
        }
        let g = mlp.backward(&tr, d, false);
        for (li, (r, c)) in [(0usize, (1usize, 2usize)), (1, (3, 0)), (2, (2, 3))] {
            let h = 1e-2f32;
            let orig = mlp.layers[li].w[[r, c]];
            mlp.layers[li].w[[r, c]] = orig + h;
            let lp = loss(&mlp);
            mlp.layers[li].w[[r, c]] = orig - h;
            let lm = loss(&mlp);
            mlp.layers[li].w[[r, c]] = orig;
            let num = (lp - lm) / (2.0 * h as f64);
            let ana = g[li].w[[r, c]] as f64;
            assert!(
                (num - ana).abs() < 2e-3 * (1.0 + num.abs()),
                "layer {li} w[{r},{c}]: numeric {num} analytic {ana}"
            );
        }
    }

    #[test]
    fn softmax_rows_sum_to_one() {
        let l = ndarray::array![[1000.0f32, 0.0, -3.0], [0.1, 0.2, 0.3]];
        let p = softmax(l.view());
        for row in p.rows() {
            assert!((row.sum() - 1.0).abs() < 1e-6 && row.iter().all(|v| v.is_finite()));
        }
    }
}
