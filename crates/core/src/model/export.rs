//! ONNX writer and reader for [`TrainedModel`] (via the `tract_onnx::pb` protobuf types):
//! opset 13, IR version 8, input `features` `[N, n_bins]` (raw RMS bins), outputs
//! `probabilities` `[N, classes]` and `novelty` `[N]` (an aligned model adds the healthy-
//! baseline gate, a third output `baseline_distance` `[N]` and a fourth `baseline_deviation`
//! `[N, n_bins]`), all normalisation inside the graph,
//! metadata in `metadata_props`. The reader only understands graphs this writer made
//! (fine-tuning reads a shipped model back to retrain its output layer). [`stamp_bytes`]
//! writes a model's identity keys for a rig file and changes nothing else.

use super::baseline::{HealthyBaseline, GATE_EPS, TOP};
use super::classifier::TrainedModel;
use super::digest::sha256_hex;
use super::identity::{self, NOT_STORED};
use super::meta::{props, ModelMeta};
use super::mlp::{Dense, Mlp};
use super::novelty::Mahalanobis;
use super::preprocess::{Preprocess, TINY};
use crate::config::RigConfig;
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use ndarray::{Array1, Array2};
use prost::Message;
use std::collections::BTreeMap;
use std::path::Path;
use tract_onnx::pb;

/// ONNX IR version written.
pub const IR_VERSION: i64 = 8;
/// Default-domain opset written.
pub const OPSET: i64 = 13;
/// Graph input name.
pub const INPUT: &str = "features";
/// Graph output names.
pub const OUT_PROBS: &str = "probabilities";
pub const OUT_NOVELTY: &str = "novelty";
/// Third output of an aligned model: distance from the machine's healthy baseline.
pub const OUT_BASELINE: &str = "baseline_distance";
/// Fourth output of an aligned model: each bin's deviation from the machine's healthy
/// reference in units of the baseline's pooled spread (what the distance is taken over).
pub const OUT_DEVIATION: &str = "baseline_deviation";

fn f32_tensor(name: &str, dims: &[usize], data: impl IntoIterator<Item = f32>) -> pb::TensorProto {
    let raw: Vec<u8> = data.into_iter().flat_map(|v| v.to_le_bytes()).collect();
    pb::TensorProto {
        name: name.into(),
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: pb::tensor_proto::DataType::Float as i32,
        raw_data: raw,
        ..Default::default()
    }
}

fn i64_tensor(name: &str, data: &[i64]) -> pb::TensorProto {
    pb::TensorProto {
        name: name.into(),
        dims: vec![data.len() as i64],
        data_type: pb::tensor_proto::DataType::Int64 as i32,
        raw_data: data.iter().flat_map(|v| v.to_le_bytes()).collect(),
        ..Default::default()
    }
}

fn attr_int(name: &str, v: i64) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Int as i32,
        i: v,
        ..Default::default()
    }
}

fn attr_ints(name: &str, v: &[i64]) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: v.to_vec(),
        ..Default::default()
    }
}

fn node(
    op: &str,
    name: &str,
    inputs: &[&str],
    outputs: &[&str],
    attrs: Vec<pb::AttributeProto>,
) -> pb::NodeProto {
    pb::NodeProto {
        op_type: op.into(),
        name: name.into(),
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: outputs.iter().map(|s| s.to_string()).collect(),
        attribute: attrs,
        ..Default::default()
    }
}

enum Dim {
    Batch,
    Fixed(usize),
}

fn value_info(name: &str, dims: &[Dim]) -> pb::ValueInfoProto {
    use pb::tensor_shape_proto::{dimension::Value, Dimension};
    let dim = dims
        .iter()
        .map(|d| Dimension {
            denotation: String::new(),
            value: Some(match d {
                Dim::Batch => Value::DimParam("N".into()),
                Dim::Fixed(n) => Value::DimValue(*n as i64),
            }),
        })
        .collect();
    pb::ValueInfoProto {
        name: name.into(),
        r#type: Some(pb::TypeProto {
            denotation: String::new(),
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: pb::tensor_proto::DataType::Float as i32,
                shape: Some(pb::TensorShapeProto { dim }),
            })),
        }),
        ..Default::default()
    }
}

/// Build the ONNX model.
pub fn to_proto(m: &TrainedModel) -> pb::ModelProto {
    let n_in = m.pre.n_features();
    let n_cls = m.mlp.n_classes();
    let mut init = vec![
        f32_tensor("pre_tiny", &[], [TINY]),
        f32_tensor("pre_floor", &[], [m.pre.floor]),
        f32_tensor("pre_mean", &[n_in], m.pre.mean.iter().copied()),
        f32_tensor("pre_inv_std", &[n_in], m.pre.inv_std.iter().copied()),
    ];
    let mut nodes = vec![
        node(
            "ReduceMean",
            "window_mean",
            &[INPUT],
            &["win_mean"],
            vec![attr_ints("axes", &[1]), attr_int("keepdims", 1)],
        ),
        node(
            "Add",
            "window_mean_safe",
            &["win_mean", "pre_tiny"],
            &["win_mean_safe"],
            vec![],
        ),
        node(
            "Div",
            "ratio",
            &[INPUT, "win_mean_safe"],
            &["ratio"],
            vec![],
        ),
        node(
            "Add",
            "ratio_floor",
            &["ratio", "pre_floor"],
            &["ratio_floor"],
            vec![],
        ),
        node("Log", "log_ratio", &["ratio_floor"], &["log_ratio"], vec![]),
        node(
            "Sub",
            "centre",
            &["log_ratio", "pre_mean"],
            &["centred"],
            vec![],
        ),
        node("Mul", "scale", &["centred", "pre_inv_std"], &["z"], vec![]),
    ];
    let n_layers = m.mlp.layers.len();
    let mut prev = "z".to_string();
    for (i, l) in m.mlp.layers.iter().enumerate() {
        let k = i + 1;
        let (w, b) = (format!("dense_{k}_w"), format!("dense_{k}_b"));
        init.push(f32_tensor(&w, &[l.n_out(), l.n_in()], l.w.iter().copied()));
        init.push(f32_tensor(&b, &[l.n_out()], l.b.iter().copied()));
        let is_out = i + 1 == n_layers;
        let gemm_out = if is_out {
            "logits".to_string()
        } else {
            format!("dense_{k}")
        };
        nodes.push(node(
            "Gemm",
            &format!("dense_{k}"),
            &[&prev, &w, &b],
            &[&gemm_out],
            vec![attr_int("transB", 1)],
        ));
        if is_out {
            let probs = if m.baseline.is_some() {
                "probs_network"
            } else {
                OUT_PROBS
            };
            nodes.push(node(
                "Softmax",
                "softmax",
                &["logits"],
                &[probs],
                vec![attr_int("axis", -1)],
            ));
        } else {
            let act = format!("relu_{k}");
            nodes.push(node("Relu", &act, &[&gemm_out], &[&act], vec![]));
            prev = act;
        }
    }
    let k = m.novelty.whiten.nrows();
    init.push(f32_tensor(
        "novelty_whiten",
        &[k, k],
        m.novelty.whiten.iter().copied(),
    ));
    init.push(f32_tensor(
        "novelty_centroids",
        &[n_cls, k],
        m.novelty.centroids.iter().copied(),
    ));
    init.push(i64_tensor("novelty_unsqueeze_axes", &[1]));
    nodes.extend([
        node(
            "MatMul",
            "novelty_whitening",
            &[&prev, "novelty_whiten"],
            &["whitened"],
            vec![],
        ),
        node(
            "Unsqueeze",
            "novelty_unsqueeze",
            &["whitened", "novelty_unsqueeze_axes"],
            &["whitened_3d"],
            vec![],
        ),
        node(
            "Sub",
            "novelty_offset",
            &["whitened_3d", "novelty_centroids"],
            &["offsets"],
            vec![],
        ),
        node(
            "ReduceSumSquare",
            "novelty_d2",
            &["offsets"],
            &["d2"],
            vec![attr_ints("axes", &[2]), attr_int("keepdims", 0)],
        ),
        node(
            "ReduceMin",
            "novelty_nearest",
            &["d2"],
            &["d2_min"],
            vec![attr_ints("axes", &[1]), attr_int("keepdims", 0)],
        ),
        node("Sqrt", "novelty_sqrt", &["d2_min"], &[OUT_NOVELTY], vec![]),
    ]);
    let mut outputs = vec![
        value_info(OUT_PROBS, &[Dim::Batch, Dim::Fixed(n_cls)]),
        value_info(OUT_NOVELTY, &[Dim::Batch]),
    ];
    if let Some(b) = &m.baseline {
        let healthy = Condition::Healthy.index_in(&m.meta.labels);
        baseline_gate(b, healthy, n_in, n_cls, &mut init, &mut nodes);
        outputs.push(value_info(OUT_BASELINE, &[Dim::Batch]));
        outputs.push(value_info(OUT_DEVIATION, &[Dim::Batch, Dim::Fixed(n_in)]));
    }
    let graph = pb::GraphProto {
        name: "rigmon_classifier".into(),
        node: nodes,
        initializer: init,
        input: vec![value_info(INPUT, &[Dim::Batch, Dim::Fixed(n_in)])],
        output: outputs,
        doc_string: "Envelope-order-spectrum bearing classifier: raw RMS order bins in, class probabilities and a Mahalanobis novelty score out.".into(),
        ..Default::default()
    };
    pb::ModelProto {
        ir_version: IR_VERSION,
        opset_import: vec![pb::OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
        producer_name: "rigmon".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(graph),
        metadata_props: m
            .meta
            .to_props()
            .into_iter()
            .map(|(key, value)| pb::StringStringEntryProto { key, value })
            .collect(),
        ..Default::default()
    }
}

/// The healthy-baseline gate of an aligned model ([`HealthyBaseline`]): the distance from the
/// machine's healthy windows on `log_ratio`, and `probabilities` = the network's, or, where
/// the distance exceeds the threshold, the network's with the healthy class zeroed and the
/// rest renormalised (`p + g * (closed - p)`, g = 1 beyond the threshold).
fn baseline_gate(
    b: &HealthyBaseline,
    healthy: Option<usize>,
    n_in: usize,
    n_cls: usize,
    init: &mut Vec<pb::TensorProto>,
    nodes: &mut Vec<pb::NodeProto>,
) {
    let keep = (0..n_cls).map(|j| if Some(j) == healthy { 0.0 } else { 1.0 });
    let eps = (0..n_cls).map(|j| if Some(j) == healthy { 0.0 } else { GATE_EPS });
    init.extend([
        f32_tensor("baseline_ref", &[n_in], b.reference.iter().copied()),
        f32_tensor("baseline_inv_spread", &[], [b.inv_spread]),
        f32_tensor("baseline_threshold", &[], [b.threshold]),
        f32_tensor("gate_keep", &[n_cls], keep),
        f32_tensor("gate_eps", &[n_cls], eps),
        i64_tensor("gate_axes", &[1]),
        i64_tensor("baseline_k", &[TOP.min(n_in) as i64]),
    ]);
    let cast_float = attr_int("to", pb::tensor_proto::DataType::Float as i64);
    nodes.extend([
        node(
            "Sub",
            "baseline_dev",
            &["log_ratio", "baseline_ref"],
            &["b_dev"],
            vec![],
        ),
        node(
            "Mul",
            "baseline_scale",
            &["b_dev", "baseline_inv_spread"],
            &["b_scaled"],
            vec![],
        ),
        node(
            "Identity",
            "baseline_deviation",
            &["b_scaled"],
            &[OUT_DEVIATION],
            vec![],
        ),
        node(
            "Mul",
            "baseline_square",
            &["b_scaled", "b_scaled"],
            &["b_sq"],
            vec![],
        ),
        node(
            "TopK",
            "baseline_largest",
            &["b_sq", "baseline_k"],
            &["b_top", "b_top_index"],
            vec![attr_int("axis", 1)],
        ),
        node(
            "ReduceMean",
            "baseline_mean_square",
            &["b_top"],
            &["b_ms"],
            vec![attr_ints("axes", &[1]), attr_int("keepdims", 1)],
        ),
        node("Sqrt", "baseline_rms", &["b_ms"], &["b_dist"], vec![]),
        node(
            "Squeeze",
            "baseline_flat",
            &["b_dist", "gate_axes"],
            &[OUT_BASELINE],
            vec![],
        ),
        node(
            "Greater",
            "baseline_far",
            &["b_dist", "baseline_threshold"],
            &["b_far"],
            vec![],
        ),
        node(
            "Cast",
            "baseline_gate",
            &["b_far"],
            &["g"],
            vec![cast_float],
        ),
        node(
            "Mul",
            "gate_drop_healthy",
            &["probs_network", "gate_keep"],
            &["p_kept"],
            vec![],
        ),
        node(
            "Add",
            "gate_floor",
            &["p_kept", "gate_eps"],
            &["p_closed_raw"],
            vec![],
        ),
        node(
            "ReduceSum",
            "gate_total",
            &["p_closed_raw", "gate_axes"],
            &["p_closed_sum"],
            vec![attr_int("keepdims", 1)],
        ),
        node(
            "Div",
            "gate_renormalise",
            &["p_closed_raw", "p_closed_sum"],
            &["p_closed"],
            vec![],
        ),
        node(
            "Sub",
            "gate_change",
            &["p_closed", "probs_network"],
            &["p_change"],
            vec![],
        ),
        node(
            "Mul",
            "gate_apply",
            &["p_change", "g"],
            &["p_gated_change"],
            vec![],
        ),
        node(
            "Add",
            "gate_out",
            &["probs_network", "p_gated_change"],
            &[OUT_PROBS],
            vec![],
        ),
    ]);
}

/// Serialise to ONNX bytes.
pub fn to_bytes(m: &TrainedModel) -> Vec<u8> {
    to_proto(m).encode_to_vec()
}

/// Write the model to `path` (parent folders created).
pub fn write(m: &TrainedModel, path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create folder {}", dir.display()))?;
    }
    std::fs::write(path, to_bytes(m))
        .with_context(|| format!("cannot write model {}", path.display()))
}

fn tensor_f32(t: &pb::TensorProto) -> Vec<f32> {
    if !t.raw_data.is_empty() {
        t.raw_data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else {
        t.float_data.clone()
    }
}

/// Read a model written by [`write`] back into memory. `what` names the file in errors.
pub fn from_bytes(bytes: &[u8], what: &str) -> Result<TrainedModel> {
    let proto = pb::ModelProto::decode(bytes)
        .with_context(|| format!("{what}: not an ONNX model (protobuf decode failed)"))?;
    let meta = ModelMeta::from_props(&props(&proto), what)?;
    let graph = proto
        .graph
        .as_ref()
        .with_context(|| format!("{what}: ONNX model has no graph"))?;
    let inits: BTreeMap<&str, &pb::TensorProto> = graph
        .initializer
        .iter()
        .map(|t| (t.name.as_str(), t))
        .collect();
    let get = |name: &str, shape: &[usize]| -> Result<Vec<f32>> {
        let t = inits.get(name).with_context(|| {
            format!("{what}: initializer {name:?} missing; only models written by `rigmon train` can be read back")
        })?;
        let v = tensor_f32(t);
        let want: usize = shape.iter().product();
        if v.len() != want {
            bail!(
                "{what}: initializer {name:?} has {} values, expected {want} (shape {shape:?})",
                v.len()
            );
        }
        Ok(v)
    };
    let floor = get("pre_floor", &[])?[0];
    let n_in = meta.n_features;
    let pre = Preprocess {
        floor,
        mean: Array1::from(get("pre_mean", &[n_in])?),
        inv_std: Array1::from(get("pre_inv_std", &[n_in])?),
    };
    let mut layers = Vec::new();
    let mut k = 1;
    while let Some(t) = inits.get(format!("dense_{k}_w").as_str()) {
        if t.dims.len() != 2 {
            bail!("{what}: dense_{k}_w is not a matrix (dims {:?})", t.dims);
        }
        let (o, i) = (t.dims[0] as usize, t.dims[1] as usize);
        let w = Array2::from_shape_vec((o, i), get(&format!("dense_{k}_w"), &[o, i])?)?;
        let b = Array1::from(get(&format!("dense_{k}_b"), &[o])?);
        layers.push(Dense { w, b });
        k += 1;
    }
    if layers.len() < 2 {
        bail!("{what}: found {} dense layers; a rigmon classifier has hidden layers and an output layer", layers.len());
    }
    let hidden = layers[layers.len() - 2].n_out();
    let n_cls = layers.last().map(Dense::n_out).unwrap_or(0);
    if n_cls != meta.labels.len() {
        bail!(
            "{what}: output layer has {n_cls} classes but metadata lists {} labels",
            meta.labels.len()
        );
    }
    let novelty = Mahalanobis {
        whiten: Array2::from_shape_vec(
            (hidden, hidden),
            get("novelty_whiten", &[hidden, hidden])?,
        )?,
        centroids: Array2::from_shape_vec(
            (n_cls, hidden),
            get("novelty_centroids", &[n_cls, hidden])?,
        )?,
        threshold: meta.novelty_threshold,
    };
    let baseline = if inits.contains_key("baseline_ref") {
        Some(HealthyBaseline {
            reference: Array1::from(get("baseline_ref", &[n_in])?),
            inv_spread: get("baseline_inv_spread", &[])?[0],
            threshold: get("baseline_threshold", &[])?[0],
        })
    } else {
        None
    };
    Ok(TrainedModel {
        pre,
        mlp: Mlp { layers },
        novelty,
        meta,
        baseline,
    })
}

/// Read a model file written by [`write`].
pub fn read(path: &Path) -> Result<TrainedModel> {
    let bytes =
        std::fs::read(path).with_context(|| format!("cannot read model {}", path.display()))?;
    let mut m = from_bytes(&bytes, &path.display().to_string())?;
    m.meta.sha256 = sha256_hex(&bytes);
    Ok(m)
}

/// The metadata keys [`stamp_bytes`] writes.
pub const IDENTITY_KEYS: [&str; 3] = ["lowpass_hz", "window_s", "bearing_orders"];

/// Stamp a model's identity keys (low-pass, window, bearing orders) for the rig file it was
/// trained for (`rigmon model stamp`). Only `metadata_props` change: the graph, its weights
/// and every other entry are re-encoded from the decoded protobuf as they were. Refused when
/// what the model already says (rig id, axis, layout, a stored key) contradicts `rig`: a
/// stamp records what a model was trained for, it does not make it fit another rig. `what`
/// names the file in errors. Returns the new bytes and the keys that were added.
pub fn stamp_bytes(bytes: &[u8], rig: &RigConfig, what: &str) -> Result<(Vec<u8>, Vec<String>)> {
    let mut proto = pb::ModelProto::decode(bytes)
        .with_context(|| format!("{what}: not an ONNX model (protobuf decode failed)"))?;
    let meta = ModelMeta::from_props(&props(&proto), what)?;
    identity::check_layout(&meta, rig).with_context(|| what.to_string())?;
    let contradictions: Vec<String> = identity::mismatches(&meta, rig)
        .iter()
        .filter(|m| m.model != NOT_STORED)
        .map(ToString::to_string)
        .collect();
    if !contradictions.is_empty() {
        bail!(
            "{what} was trained for another rig than {:?} ({}); stamping it for this rig file would be false. Stamp it with the rig file it was trained for, or train a model for this rig",
            rig.machine.id,
            contradictions.join("; ")
        );
    }
    let mut stamped = meta.clone();
    identity::stamp(&mut stamped, rig);
    let mut added = Vec::new();
    for (key, value) in stamped.to_props() {
        if !IDENTITY_KEYS.contains(&key.as_str()) {
            continue;
        }
        match proto.metadata_props.iter_mut().find(|e| e.key == key) {
            Some(e) => e.value = value,
            None => {
                added.push(key.clone());
                proto
                    .metadata_props
                    .push(pb::StringStringEntryProto { key, value });
            }
        }
    }
    Ok((proto.encode_to_vec(), added))
}
