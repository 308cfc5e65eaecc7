//! Model metadata: what a classifier file says about itself (class labels, feature layout,
//! the rig and recipe it was trained for, provenance), stored as ONNX `metadata_props` and
//! read back by [`super::onnx`]. Whether it fits a rig file is [`super::identity`]'s question.

use super::alignment::Alignment;
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use tract_onnx::pb;

/// Metadata of a classifier model file.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct ModelMeta {
    /// Class labels in output order (e.g. healthy, outer_race, inner_race).
    pub labels: Vec<String>,
    /// Width of one feature bin in orders.
    pub bin_width: f64,
    /// Highest order (the last bin ends here).
    pub max_order: f64,
    /// Channel name or axis whose features feed the model.
    pub axis: String,
    /// Rig the model was trained for (`machine.id`).
    pub rig_id: String,
    /// SHA-256 over the training recordings and their labels.
    pub data_hash: String,
    /// Calibration id of the rig file used to simulate the training data ("none" if none).
    pub calibration_id: String,
    /// rigmon version that wrote the file.
    pub rigmon_version: String,
    /// Novelty scores above this are reported as `unknown`.
    pub novelty_threshold: f32,
    /// SHA-256 of the model file itself (empty for a model not yet written).
    pub sha256: String,
    /// Number of input features (bins).
    pub n_features: usize,
    /// Name of the in-graph feature normalisation.
    pub normalization: String,
    /// Training summary (JSON text): plan, seed, epochs, split, validation figures.
    pub training: String,
    /// Fine-tuning summary (JSON text), empty when the model was never fine-tuned.
    pub finetune: String,
    /// Per-feature mean log ratio (`ln(x / mean(x) + floor)`) of the simulated healthy
    /// training windows: the reference a healthy-only alignment moves a machine onto. Empty
    /// in models trained before it was stored.
    pub healthy_reference: Vec<f32>,
    /// The standardisation offsets as trained, kept once a model has been aligned.
    pub trained_mean: Vec<f32>,
    /// The alignment to one machine and the healthy baseline it fitted (None: never aligned).
    pub alignment: Option<Alignment>,
    /// The envelope low-pass the training features were computed with (`[features]
    /// lowpass_hz`), Hz; `None` in models written before it was stored.
    pub lowpass_hz: Option<f64>,
    /// The analysis window the training features were computed over (`[features]
    /// window_s`), s; `None` in models written before it was stored.
    pub window_s: Option<f64>,
    /// The fault orders of the bearing the model was trained for (from the rig file's
    /// `[bearing]`); `None` in models written before they were stored.
    pub bearing_orders: Option<BearingOrders>,
}

/// The fault orders a model was trained to recognise (multiples of shaft speed).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct BearingOrders {
    pub ftf: f64,
    pub bpfo: f64,
    pub bpfi: f64,
    pub two_bsf: f64,
}

impl BearingOrders {
    /// `(name, order)` pairs in a fixed order.
    pub fn named(&self) -> [(&'static str, f64); 4] {
        [
            ("bpfo", self.bpfo),
            ("bpfi", self.bpfi),
            ("two_bsf", self.two_bsf),
            ("ftf", self.ftf),
        ]
    }

    /// `bpfo=3.585,bpfi=5.415,two_bsf=4.714,ftf=0.398` (full precision, reads back exactly).
    pub fn to_text(&self) -> String {
        self.named()
            .iter()
            .map(|(k, v)| format!("{k}={v:?}"))
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Read [`to_text`](Self::to_text)'s form; `what` names the file in errors.
    pub fn from_text(s: &str, what: &str) -> Result<BearingOrders> {
        let mut o = BearingOrders::default();
        let mut seen = 0;
        for part in s.split(',').filter(|p| !p.trim().is_empty()) {
            let (k, v) = part.split_once('=').with_context(|| {
                format!("{what}: metadata bearing_orders holds {part:?}, not name=order; the file is damaged (re-stamp it with `rigmon model stamp`)")
            })?;
            let v: f64 = v.trim().parse().ok().filter(|v: &f64| v.is_finite()).with_context(|| {
                format!("{what}: metadata bearing_orders: {k} = {v:?} is not a number; the file is damaged (re-stamp it with `rigmon model stamp`)")
            })?;
            let slot = match k.trim() {
                "ftf" => &mut o.ftf,
                "bpfo" => &mut o.bpfo,
                "bpfi" => &mut o.bpfi,
                "two_bsf" => &mut o.two_bsf,
                _ => continue, // a later rigmon may store more orders
            };
            *slot = v;
            seen += 1;
        }
        if seen < 4 {
            bail!("{what}: metadata bearing_orders = {s:?} lacks some of bpfo, bpfi, two_bsf, ftf; re-stamp it with `rigmon model stamp`");
        }
        Ok(o)
    }
}

/// `metadata_props` of a decoded model as a map.
pub fn props(proto: &pb::ModelProto) -> BTreeMap<String, String> {
    proto
        .metadata_props
        .iter()
        .map(|e| (e.key.clone(), e.value.clone()))
        .collect()
}

/// Floats as a comma-separated list that reads back bit for bit.
fn floats_to_text(v: &[f32]) -> String {
    v.iter()
        .map(|x| format!("{x:?}"))
        .collect::<Vec<_>>()
        .join(",")
}

fn floats_from_text(s: &str, key: &str, what: &str) -> Result<Vec<f32>> {
    s.split(',')
        .filter(|t| !t.trim().is_empty())
        .map(|t| {
            t.trim().parse::<f32>().with_context(|| {
                format!("{what}: metadata {key} holds {t:?}, not a number; the file is damaged (re-export or retrain it)")
            })
        })
        .collect()
}

impl ModelMeta {
    /// The healthy-baseline threshold of an aligned model (from `alignment`), None when the
    /// model was never aligned.
    pub fn baseline_threshold(&self) -> Option<f32> {
        self.alignment.as_ref()?.gate()
    }

    /// As ONNX `metadata_props` entries (key, value), in a stable order.
    pub fn to_props(&self) -> Vec<(String, String)> {
        let mut v = vec![
            ("labels".to_string(), self.labels.join(",")),
            ("bin_width".into(), self.bin_width.to_string()),
            ("max_order".into(), self.max_order.to_string()),
            ("axis".into(), self.axis.clone()),
            ("rig_id".into(), self.rig_id.clone()),
            ("data_hash".into(), self.data_hash.clone()),
            ("calibration_id".into(), self.calibration_id.clone()),
            ("rigmon_version".into(), self.rigmon_version.clone()),
            (
                "novelty_threshold".into(),
                format!("{:?}", self.novelty_threshold),
            ),
            ("n_features".into(), self.n_features.to_string()),
            ("normalization".into(), self.normalization.clone()),
            ("training".into(), self.training.clone()),
        ];
        if !self.finetune.is_empty() {
            v.push(("finetune".into(), self.finetune.clone()));
        }
        if !self.healthy_reference.is_empty() {
            v.push((
                "healthy_reference".into(),
                floats_to_text(&self.healthy_reference),
            ));
        }
        if !self.trained_mean.is_empty() {
            v.push(("trained_mean".into(), floats_to_text(&self.trained_mean)));
        }
        if let Some(a) = &self.alignment {
            v.push(("alignment".into(), a.to_text()));
        }
        if let Some(hz) = self.lowpass_hz {
            v.push(("lowpass_hz".into(), hz.to_string()));
        }
        if let Some(s) = self.window_s {
            v.push(("window_s".into(), s.to_string()));
        }
        if let Some(o) = &self.bearing_orders {
            v.push(("bearing_orders".into(), o.to_text()));
        }
        v
    }

    /// Parse `metadata_props`; `what` names the file in errors.
    pub fn from_props(props: &BTreeMap<String, String>, what: &str) -> Result<ModelMeta> {
        let get = |k: &str| -> Result<&String> {
            props.get(k).with_context(|| {
                format!("{what}: metadata_props has no {k:?}; this is not a rigmon classifier (retrain it with `rigmon train`)")
            })
        };
        let num = |k: &str| -> Result<f64> {
            let s = get(k)?;
            s.parse::<f64>()
                .with_context(|| format!("{what}: metadata {k} = {s:?} is not a number"))
        };
        let labels: Vec<String> = get("labels")?
            .split(',')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect();
        if labels.len() < 2 {
            bail!(
                "{what}: metadata labels = {:?} needs at least two classes",
                get("labels")?
            );
        }
        Ok(ModelMeta {
            labels,
            bin_width: num("bin_width")?,
            max_order: num("max_order")?,
            axis: get("axis")?.clone(),
            rig_id: get("rig_id")?.clone(),
            data_hash: get("data_hash")?.clone(),
            calibration_id: get("calibration_id")?.clone(),
            rigmon_version: get("rigmon_version")?.clone(),
            novelty_threshold: num("novelty_threshold")? as f32,
            sha256: String::new(),
            n_features: num("n_features")? as usize,
            normalization: get("normalization")?.clone(),
            training: props.get("training").cloned().unwrap_or_default(),
            finetune: props.get("finetune").cloned().unwrap_or_default(),
            healthy_reference: match props.get("healthy_reference") {
                Some(s) => floats_from_text(s, "healthy_reference", what)?,
                None => Vec::new(),
            },
            trained_mean: match props.get("trained_mean") {
                Some(s) => floats_from_text(s, "trained_mean", what)?,
                None => Vec::new(),
            },
            alignment: match props.get("alignment").filter(|s| !s.trim().is_empty()) {
                Some(s) => Some(Alignment::from_text(s, what)?),
                None => None,
            },
            lowpass_hz: match props.get("lowpass_hz") {
                Some(_) => Some(num("lowpass_hz")?),
                None => None,
            },
            window_s: match props.get("window_s") {
                Some(_) => Some(num("window_s")?),
                None => None,
            },
            bearing_orders: match props.get("bearing_orders") {
                Some(s) => Some(BearingOrders::from_text(s, what)?),
                None => None,
            },
        })
    }
}
