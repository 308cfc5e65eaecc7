//! rigmon's lab: what sits beside the stream and produces or judges models.
//!
//! [`sim`] (the rig simulator), [`train`] (features, fit, ONNX export), [`calibrate`] (fit the
//! simulator to measured recordings: residual views, effect catalog, held-out acceptance),
//! [`adapt`] (calibrate, simulate and train for one machine), [`evaluate`] (whole-record
//! scores), [`manifest`] (labels.csv), [`plots`] (PNG pictures) and [`embed`] (2-D maps of
//! feature windows). Built on the core alone: the daemon's runtime never links it.

pub mod adapt;
pub mod calibrate;
pub mod embed;
pub mod evaluate;
pub mod manifest;
pub mod plots;
pub mod sim;
pub mod train;

use rigmon_core::{
    analysis, bearing, config, dsp, health, importers, model, recording, usage, vocabulary, wire,
};
