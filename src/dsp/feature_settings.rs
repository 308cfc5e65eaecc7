//! The rig file's `[features]` section: the envelope-order-spectrum recipe (window, hop,
//! low-pass, order bins, classifier channel). Owned by the DSP layer; `config` embeds it in
//! the rig file.

use serde::{Deserialize, Serialize};

/// The envelope-order-spectrum recipe (thesis section 4.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeatureSettings {
    /// Low-pass cut-off before the envelope, Hz.
    #[serde(default = "default_lowpass")]
    pub lowpass_hz: f64,
    /// Window length, s.
    #[serde(default = "default_window")]
    pub window_s: f64,
    /// Hop between windows, s.
    #[serde(default = "default_hop")]
    pub hop_s: f64,
    /// Width of one RMS bin in orders.
    #[serde(default = "default_bin_width")]
    pub bin_width_order: f64,
    /// Highest order (the last bin ends here).
    #[serde(default = "default_max_order")]
    pub max_order: f64,
    /// Channel (by name or axis) whose features feed the classifier.
    #[serde(default = "default_axis")]
    pub classifier_axis: String,
}

/// Upper limit on order bins per channel (the thesis recipe uses 100).
pub const MAX_FEATURE_BINS: usize = 10_000;

fn default_lowpass() -> f64 {
    4000.0
}
fn default_window() -> f64 {
    1.0
}
fn default_hop() -> f64 {
    0.5
}
fn default_bin_width() -> f64 {
    0.5
}
fn default_max_order() -> f64 {
    50.0
}
fn default_axis() -> String {
    "vertical".into()
}

impl Default for FeatureSettings {
    fn default() -> Self {
        FeatureSettings {
            lowpass_hz: default_lowpass(),
            window_s: default_window(),
            hop_s: default_hop(),
            bin_width_order: default_bin_width(),
            max_order: default_max_order(),
            classifier_axis: default_axis(),
        }
    }
}

impl FeatureSettings {
    /// Number of RMS bins (100 for the default 0.5 .. 50 recipe).
    pub fn n_bins(&self) -> usize {
        (self.max_order / self.bin_width_order).round() as usize
    }

    /// Bin edges in orders: bin k covers (edges[k], edges[k+1]]; bin 0 ends at `bin_width`.
    pub fn bin_edges(&self) -> Vec<f64> {
        (0..=self.n_bins())
            .map(|k| k as f64 * self.bin_width_order)
            .collect()
    }
}
