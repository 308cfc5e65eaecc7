//! Which rig a model was trained for, and whether it fits a rig file. A model carries the rig
//! id, classifier axis, bearing fault orders, envelope low-pass and window of its training
//! data ([`ModelMeta`]); every command that takes a model compares them with the rig file.
//!
//! Two kinds of difference:
//! - the feature layout (bin count, bin width, highest order): the network cannot take another
//!   input, so this is always refused ([`check_layout`]);
//! - the model's identity (everything else, [`mismatches`]): refused by default, naming both
//!   values; a caller may allow a foreign model on purpose (`--allow-foreign-model`,
//!   `[model] allow_foreign`), and the daemon then lists the differences in every health
//!   message. A model written before these keys were stored says nothing about them: that is
//!   a mismatch too, fixed once with `rigmon model stamp` ([`stamp`]).

use super::meta::{BearingOrders, ModelMeta};
use crate::config::RigConfig;
use anyhow::{bail, Result};

/// Fault orders may differ by this fraction of a feature bin and still count as the same
/// bearing: a quarter bin (0.125 orders with 0.5-order bins), so each fault line's
/// fundamental stays in or next to the bin the model learnt it in. A pitch diameter 1 % off
/// (the thesis' 48 vs 48.5 mm) moves the orders by at most 0.07 and passes; one ball fewer
/// (the 6205's 9 vs 8) moves BPFO by 0.4 orders, and the fan-end 6203 differs from the
/// drive-end 6205 by 0.5, and do not.
pub const ORDER_TOLERANCE_BINS: f64 = 0.25;

/// Relative difference under which two low-pass frequencies or window lengths are the same.
const SAME: f64 = 1e-6;

/// One way a model differs from a rig file.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Mismatch {
    /// What differs: `rig_id`, `axis`, `bearing_orders`, `lowpass_hz`, `window_s`.
    pub key: &'static str,
    /// The model's value (`not stored` for a model written before the key existed).
    pub model: String,
    /// The rig file's value.
    pub rig: String,
}

/// What a model stores when it has none.
pub const NOT_STORED: &str = "not stored";

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: model {}, rig file {}",
            self.key, self.model, self.rig
        )
    }
}

/// The fault orders of the rig file's bearing, as a model stores them.
pub fn bearing_orders(rig: &RigConfig) -> BearingOrders {
    let o = rig.bearing.fault_orders();
    BearingOrders {
        ftf: o.ftf,
        bpfo: o.bpfo,
        bpfi: o.bpfi,
        two_bsf: o.two_bsf,
    }
}

/// Write what `rig` says into the identity keys of `meta` (training, `rigmon model stamp`).
pub fn stamp(meta: &mut ModelMeta, rig: &RigConfig) {
    meta.rig_id = rig.machine.id.clone();
    meta.axis = rig.features.classifier_axis.clone();
    meta.lowpass_hz = Some(rig.features.lowpass_hz);
    meta.window_s = Some(rig.features.window_s);
    meta.bearing_orders = Some(bearing_orders(rig));
}

/// The feature layout must match: the model takes `n_features` bins of `bin_width` orders up
/// to `max_order`. Never overridable.
pub fn check_layout(meta: &ModelMeta, rig: &RigConfig) -> Result<()> {
    let f = &rig.features;
    if (f.bin_width_order - meta.bin_width).abs() > 1e-9
        || (f.max_order - meta.max_order).abs() > 1e-9
        || f.n_bins() != meta.n_features
    {
        bail!(
            "model expects {} bins of {} orders up to order {}, but rig {:?} gives {} bins of {} up to {}; use a model trained for this rig",
            meta.n_features,
            meta.bin_width,
            meta.max_order,
            rig.machine.id,
            f.n_bins(),
            f.bin_width_order,
            f.max_order
        );
    }
    Ok(())
}

/// Every way the model's identity differs from the rig file's (empty: it was trained for it).
pub fn mismatches(meta: &ModelMeta, rig: &RigConfig) -> Vec<Mismatch> {
    let mut out = Vec::new();
    let mut differ = |key: &'static str, model: String, rig: String| {
        out.push(Mismatch { key, model, rig });
    };
    if meta.rig_id != rig.machine.id {
        differ("rig_id", meta.rig_id.clone(), rig.machine.id.clone());
    }
    let axis = &rig.features.classifier_axis;
    if &meta.axis != axis {
        differ("axis", meta.axis.clone(), axis.clone());
    }
    let want = bearing_orders(rig);
    let tolerance = ORDER_TOLERANCE_BINS * rig.features.bin_width_order;
    match &meta.bearing_orders {
        None => differ("bearing_orders", NOT_STORED.into(), orders_text(&want)),
        Some(have) => {
            let off = have
                .named()
                .iter()
                .zip(want.named())
                .any(|((_, a), (_, b))| (a - b).abs() > tolerance);
            if off {
                differ("bearing_orders", orders_text(have), orders_text(&want));
            }
        }
    }
    for (key, unit, stored, set) in [
        ("lowpass_hz", "Hz", meta.lowpass_hz, rig.features.lowpass_hz),
        ("window_s", "s", meta.window_s, rig.features.window_s),
    ] {
        match stored {
            None => differ(key, NOT_STORED.into(), format!("{set} {unit}")),
            Some(v) if (v - set).abs() > SAME * v.abs().max(set.abs()) => {
                differ(key, format!("{v} {unit}"), format!("{set} {unit}"))
            }
            Some(_) => {}
        }
    }
    out
}

/// `bpfo 3.585 bpfi 5.415 two_bsf 4.714 ftf 0.398`.
fn orders_text(o: &BearingOrders) -> String {
    o.named()
        .iter()
        .map(|(k, v)| format!("{k} {v:.3}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The error for a model that is not this rig's, naming every difference and what to do.
/// `model` names the model file, `rig_file` the rig file.
pub fn refusal(model: &str, rig: &RigConfig, rig_file: &str, found: &[Mismatch]) -> anyhow::Error {
    let list = found
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("; ");
    let unstamped: Vec<&str> = found
        .iter()
        .filter(|m| m.model == NOT_STORED)
        .map(|m| m.key)
        .collect();
    let allow = "or use it on purpose with --allow-foreign-model (`[model] allow_foreign = true` in rigmon.toml; every health message then lists the differences in model.foreign)";
    if !unstamped.is_empty() && unstamped.len() == found.len() {
        return anyhow::anyhow!(
            "model {model} does not say which {} it was trained for (written before rigmon stored them); if it was trained for rig {:?}, stamp it once: `rigmon model stamp {model} --rig {rig_file}` (metadata only, the weights stay bit-identical), {allow}",
            unstamped.join(", "),
            rig.machine.id
        );
    }
    anyhow::anyhow!(
        "model {model} was trained for another rig than {:?} ({rig_file}): {list}. Use a model trained for this rig (`rigmon train --rig {rig_file}`), {allow}",
        rig.machine.id
    )
}
