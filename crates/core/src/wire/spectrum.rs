//! The spectrum message (`rigmon/<rig>/<asset>/<point>/spectrum`, JSON, schema
//! `rigmon.spectrum` version 1): the classifier channel's envelope order spectrum of one
//! window, published beside its health message (same `seq`) when `pipeline.spectrum` is on.

use crate::dsp::features::FeatureWindow;
use serde::{Deserialize, Serialize};

/// Schema name carried in every message.
pub const SCHEMA: &str = "rigmon.spectrum";
/// Current schema version.
pub const SCHEMA_VERSION: u32 = 1;

/// One window's spectrum. `W` is the window as owned ([`FeatureWindow`], when read) or
/// borrowed (`&FeatureWindow`, when the daemon writes it without a copy).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpectrumMessage<W = FeatureWindow> {
    pub schema: String,
    pub schema_version: u32,
    pub rig: String,
    pub asset: String,
    pub point: String,
    /// The health message's `seq` for the same window.
    pub seq: u64,
    /// Width of one order bin of the spectrum.
    pub bin_width_order: f64,
    pub window: W,
}
