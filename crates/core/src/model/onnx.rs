//! Inference on a classifier file with tract: [`OnnxClassifier`] loads an ONNX model written
//! by `rigmon train`, checks its metadata and whether it was trained for a rig
//! ([`super::identity`]), and predicts class probabilities plus a novelty score for one
//! window of raw features. The daemon, `evaluate`, `align` and `finetune` use it.

use super::digest::sha256_hex;
use super::identity::{self, Mismatch};
use super::meta::props;
pub use super::meta::ModelMeta;
use crate::config::RigConfig;
use anyhow::{anyhow, bail, Context, Result};
use prost::Message;
use std::path::Path;
use std::sync::Arc;
use tract_onnx::prelude::*;

type Plan = Arc<TypedRunnableModel>;

/// The result for one window.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Prediction {
    /// Probability per class, in `meta().labels` order.
    pub probs: Vec<f32>,
    /// Index of the most probable class.
    pub class: usize,
    /// Its label.
    pub label: String,
    /// Novelty score (Mahalanobis distance of the last hidden layer to the nearest class).
    pub novelty: f32,
    /// `novelty > meta().novelty_threshold`: the window is unlike the training data.
    pub unknown: bool,
    /// Distance from the machine's healthy baseline (aligned models only: the graph's third
    /// output `baseline_distance`).
    pub baseline_distance: Option<f32>,
    /// `baseline_distance` above the aligned model's threshold: the window is not healthy
    /// for this machine (None for a model that is not aligned).
    pub beyond_baseline: Option<bool>,
    /// Each feature bin's deviation from the machine's healthy reference, in units of the
    /// baseline's pooled spread (aligned models written since the graph's fourth output
    /// `baseline_deviation` exists; [`super::evidence`] reads the fault-family bins of it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baseline_deviation: Option<Vec<f32>>,
}

/// A classifier loaded from an ONNX file, ready to run one window at a time.
pub struct OnnxClassifier {
    plan: Plan,
    meta: ModelMeta,
    /// Where it was read from (the file's path).
    name: String,
}

impl std::fmt::Debug for OnnxClassifier {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxClassifier")
            .field("meta", &self.meta)
            .finish_non_exhaustive()
    }
}

impl OnnxClassifier {
    /// Load and optimise a model file; errors name the file and what is wrong with it.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path)
            .with_context(|| format!("cannot read model file {}", path.display()))?;
        Self::from_bytes(&bytes, &path.display().to_string())
    }

    /// Load from ONNX bytes; `what` names the source in errors.
    pub fn from_bytes(bytes: &[u8], what: &str) -> Result<Self> {
        let proto = tract_onnx::pb::ModelProto::decode(bytes).with_context(|| {
            format!("{what}: not an ONNX model (protobuf decode failed); is the file truncated?")
        })?;
        let mut meta = ModelMeta::from_props(&props(&proto), what)?;
        meta.sha256 = sha256_hex(bytes);
        let n = meta.n_features;
        let plan = tract_onnx::onnx()
            .model_for_read(&mut &bytes[..])
            .and_then(|m| m.with_input_fact(0, f32::fact([1, n]).into()))
            .and_then(|m| m.into_optimized())
            .and_then(|m| m.into_runnable())
            .map_err(|e| anyhow!("{what}: tract cannot load the model: {e:#}"))?;
        Ok(OnnxClassifier {
            plan,
            meta,
            name: what.to_string(),
        })
    }

    pub fn meta(&self) -> &ModelMeta {
        &self.meta
    }

    /// The file (or source) the model was read from, for messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Fail when the rig's feature layout differs from the model's (never overridable).
    pub fn check_layout(&self, rig: &RigConfig) -> Result<()> {
        identity::check_layout(&self.meta, rig)
    }

    /// How the model's identity (rig id, axis, bearing orders, low-pass, window) differs
    /// from the rig file's; empty when it was trained for this rig.
    pub fn foreign_to(&self, rig: &RigConfig) -> Vec<Mismatch> {
        identity::mismatches(&self.meta, rig)
    }

    /// Fail with a clear message unless the model was trained for this rig: the feature
    /// layout and the identity must both match.
    pub fn check_rig(&self, rig: &RigConfig) -> Result<()> {
        self.check_identity(rig, Path::new("<the rig file>"), false)
            .map(|_| ())
    }

    /// The layout must match; a different identity is refused unless `allow_foreign`, and
    /// then returned (and logged) so the caller can flag its output. `rig_file` is where
    /// `rig` was read from, for messages.
    pub fn check_identity(
        &self,
        rig: &RigConfig,
        rig_file: &Path,
        allow_foreign: bool,
    ) -> Result<Vec<Mismatch>> {
        self.check_layout(rig)
            .with_context(|| format!("model {}", self.name))?;
        let found = self.foreign_to(rig);
        if found.is_empty() {
            return Ok(found);
        }
        if !allow_foreign {
            let rig_file = rig_file.display().to_string();
            return Err(identity::refusal(&self.name, rig, &rig_file, &found));
        }
        tracing::warn!(
            "model {} is not rig {:?}'s, used anyway (foreign model allowed): {}",
            self.name,
            rig.machine.id,
            found
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        );
        Ok(found)
    }

    /// Classify one window of raw features (`meta().n_features` values).
    pub fn predict(&self, features: &[f32]) -> Result<Prediction> {
        let n = self.meta.n_features;
        if features.len() != n {
            bail!(
                "model expects {n} features per window, got {}",
                features.len()
            );
        }
        let input = tract_ndarray::Array2::from_shape_vec((1, n), features.to_vec())?;
        let out = self
            .plan
            .run(tvec!(Tensor::from(input).into()))
            .map_err(|e| anyhow!("model inference failed: {e:#}"))?;
        if out.len() < 2 {
            bail!(
                "model returned {} outputs; expected probabilities and novelty",
                out.len()
            );
        }
        let probs: Vec<f32> = out[0]
            .to_plain_array_view::<f32>()
            .map_err(|e| anyhow!("{e:#}"))?
            .iter()
            .copied()
            .collect();
        let novelty = *out[1]
            .to_plain_array_view::<f32>()
            .map_err(|e| anyhow!("{e:#}"))?
            .iter()
            .next()
            .context("empty novelty output")?;
        let class = probs
            .iter()
            .enumerate()
            .fold(
                (0, f32::NEG_INFINITY),
                |b, (i, &v)| if v > b.1 { (i, v) } else { b },
            )
            .0;
        let label = self.meta.labels.get(class).cloned().unwrap_or_default();
        let baseline_distance = match out.get(2) {
            Some(t) => t
                .to_plain_array_view::<f32>()
                .map_err(|e| anyhow!("{e:#}"))?
                .iter()
                .next()
                .copied(),
            None => None,
        };
        let baseline_deviation = match out.get(3) {
            Some(t) => Some(
                t.to_plain_array_view::<f32>()
                    .map_err(|e| anyhow!("{e:#}"))?
                    .iter()
                    .copied()
                    .collect(),
            ),
            None => None,
        };
        let beyond_baseline = baseline_distance
            .zip(self.meta.baseline_threshold())
            .map(|(d, t)| d.is_nan() || d > t);
        Ok(Prediction {
            baseline_distance,
            baseline_deviation,
            beyond_baseline,
            unknown: novelty.is_nan() || novelty > self.meta.novelty_threshold,
            probs,
            class,
            label,
            novelty,
        })
    }
}
