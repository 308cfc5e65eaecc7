//! A trained classifier held in memory: normalisation, network, novelty detector and
//! metadata. This is what training produces, what [`super::export`] writes as ONNX and what
//! fine-tuning reads back; its `predict` is the reference the ONNX runtimes are checked against.

use super::baseline::HealthyBaseline;
use super::meta::ModelMeta;
use super::mlp::{softmax, Mlp};
use super::novelty::Mahalanobis;
use super::preprocess::Preprocess;
use crate::vocabulary::Condition;
use ndarray::{Array1, Array2, ArrayView2};

#[derive(Debug, Clone, PartialEq)]
pub struct TrainedModel {
    pub pre: Preprocess,
    pub mlp: Mlp,
    pub novelty: Mahalanobis,
    pub meta: ModelMeta,
    /// The machine's healthy baseline gate, once the model has been aligned to a machine.
    pub baseline: Option<HealthyBaseline>,
}

/// Outputs for a batch of windows.
#[derive(Debug, Clone)]
pub struct BatchOutput {
    /// `[N, classes]`.
    pub probs: Array2<f32>,
    /// `[N]`.
    pub novelty: Array1<f32>,
    /// Last hidden layer `[N, 128]`.
    pub hidden: Array2<f32>,
}

impl TrainedModel {
    /// Run raw feature windows (rows) through the whole model.
    pub fn predict(&self, x: ArrayView2<f32>) -> BatchOutput {
        let z = self.pre.apply(x);
        let (hidden, logits) = self.mlp.forward(z.view());
        let mut probs = softmax(logits.view());
        if let (Some(b), Some(h)) = (
            &self.baseline,
            Condition::Healthy.index_in(&self.meta.labels),
        ) {
            let d = b.distances(x, self.pre.floor);
            b.gate(&mut probs, &d, h);
        }
        let novelty = self.novelty.score(hidden.view());
        BatchOutput {
            probs,
            novelty,
            hidden,
        }
    }

    /// Class index with the highest probability, per row.
    pub fn argmax(probs: ArrayView2<f32>) -> Vec<usize> {
        probs
            .rows()
            .into_iter()
            .map(|r| {
                r.iter()
                    .enumerate()
                    .fold(
                        (0, f32::NEG_INFINITY),
                        |b, (i, &v)| if v > b.1 { (i, v) } else { b },
                    )
                    .0
            })
            .collect()
    }
}
