//! The classifier: in-memory network ([`mlp`]), in-graph normalisation ([`preprocess`]),
//! novelty detector ([`novelty`]), the trained bundle ([`classifier`]), its metadata
//! ([`meta`]) and whether it fits a rig file ([`identity`]), file digests ([`digest`]), the
//! ONNX writer/reader and metadata stamp ([`export`]), tract inference ([`onnx`]) and the
//! alignment to one machine: reference levels ([`align`]), the healthy baseline it stores
//! ([`alignment`]) and the healthy-baseline gate ([`baseline`]), and the fault-family evidence ([`evidence`]) and the impulsiveness
//! ([`impulsiveness`]) against that baseline. The
//! envelope-order rule every model is compared
//! with ([`rule`]), and its statistic under kurtogram-chosen envelope bands ([`band_ratios`]);
//! the classic RMS 3-sigma early-warning rule ([`rms_rule`]); the speed-free health indicators
//! against the healthy baseline ([`indicators`], per window of a recording:
//! [`indicator_series`]) and when they have left it for good ([`departure`]).

pub mod align;
pub mod alignment;
pub mod band_ratios;
pub mod baseline;
pub mod classifier;
pub mod departure;
pub mod digest;
pub mod evidence;
pub mod export;
pub mod identity;
pub mod impulsiveness;
pub mod indicator_series;
pub mod indicators;
pub mod meta;
pub mod mlp;
pub mod novelty;
pub mod onnx;
pub mod preprocess;
pub mod rms_rule;
pub mod rule;

pub use meta::ModelMeta;
pub use onnx::{OnnxClassifier, Prediction};

/// The class labels a rigmon classifier may use, in canonical output order.
pub const ALL_LABELS: [&str; 4] = crate::vocabulary::Condition::NAMES;
