//! The rig file's `[features]` section: the envelope-order-spectrum recipe (window, hop,
//! low-pass, order bins, classifier channel), and the bounds on everything in it that sizes
//! memory or cannot work at a sample rate ([`FeatureSettings::validate`],
//! [`FeatureSettings::check_at_rate`], [`FeatureSettings::check_speed`]). Owned by the DSP
//! layer; `config` embeds it in the rig file and checks it when the file is read, the feature
//! pipeline again before it sizes a buffer.

use anyhow::{bail, Result};
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

/// Longest analysis window a rig file may ask for, s. The thesis recipe uses 1 s; an hour is
/// far past anything an order spectrum for condition monitoring needs, and the bound stops a
/// typo such as `window_s = 1e9` before anything is sized by it.
pub const MAX_WINDOW_S: f64 = 3600.0;

/// Most samples one window may hold (2^21: 210 s at 10 kHz, 44 s at 48 kHz). The daemon keeps
/// about 106 bytes per window sample for the LUT rig's three accelerometers and tacho (ring
/// buffers, scratch copies, FFT and order-tracking buffers; measured in docs/rig-files.md), so
/// this bounds a window's memory to about 250 MB.
pub const MAX_WINDOW_SAMPLES: usize = 1 << 21;

/// Fewest samples per window the feature pipeline works with.
pub const MIN_WINDOW_SAMPLES: usize = 64;

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

    /// Checks on the recipe alone, when the rig file is read; errors name the key.
    pub fn validate(&self) -> Result<()> {
        if self.lowpass_hz.is_nan() || self.lowpass_hz <= 0.0 {
            bail!(
                "features.lowpass_hz = {}: must be a positive frequency",
                self.lowpass_hz
            );
        }
        if !(self.window_s > 0.0 && self.hop_s > 0.0 && self.hop_s <= self.window_s) {
            bail!(
                "features: need 0 < hop_s <= window_s (got window_s = {}, hop_s = {})",
                self.window_s,
                self.hop_s
            );
        }
        if self.window_s > MAX_WINDOW_S {
            bail!(
                "features.window_s = {} s: at most {MAX_WINDOW_S} s is supported (the thesis recipe uses 1 s)",
                self.window_s
            );
        }
        if !(self.bin_width_order > 0.0 && self.max_order > self.bin_width_order) {
            bail!("features: need 0 < bin_width_order < max_order");
        }
        let fit = self.max_order / self.bin_width_order;
        if !(fit.is_finite() && fit <= MAX_FEATURE_BINS as f64) {
            bail!(
                "features: max_order / bin_width_order = {fit} bins; at most {MAX_FEATURE_BINS} are supported (the default recipe has 100)"
            );
        }
        if (fit - fit.round()).abs() > 1e-9 {
            bail!(
                "features.max_order ({}) must be a whole number of bins of width {}",
                self.max_order,
                self.bin_width_order
            );
        }
        let slowest = self.min_shaft_hz();
        let top = self.max_order * slowest;
        if top > self.lowpass_hz {
            bail!(
                "features.max_order = {} puts the highest order at {top:.0} Hz even at the slowest speed a window can be analysed at ({:.0} rpm: 1 / bin_width_order revolutions in window_s), beyond features.lowpass_hz = {} Hz; every bin above order {:.1} would be empty — lower max_order, or raise lowpass_hz",
                self.max_order,
                60.0 * slowest,
                self.lowpass_hz,
                self.lowpass_hz / slowest
            );
        }
        Ok(())
    }

    /// The slowest shaft speed a window can be analysed at, Hz: a window must hold
    /// `1 / bin_width_order` revolutions to resolve one bin (slower windows are flagged
    /// `speed_out_of_range`).
    pub fn min_shaft_hz(&self) -> f64 {
        1.0 / (self.bin_width_order * self.window_s)
    }

    /// Samples per window at `fs`, bounded: at least [`MIN_WINDOW_SAMPLES`], at most
    /// [`MAX_WINDOW_SAMPLES`]. Errors name the key and both numbers.
    pub fn window_samples(&self, fs: f64) -> Result<usize> {
        if !(fs.is_finite() && fs > 0.0) {
            bail!("sample rate {fs} Hz: must be a positive number");
        }
        let n = (self.window_s * fs).round();
        if n.is_nan() || n > MAX_WINDOW_SAMPLES as f64 {
            bail!(
                "features.window_s = {} s at {fs} Hz is {n:.0} samples per window; at most {MAX_WINDOW_SAMPLES} ({:.1} s at this rate) are supported — shorten the window",
                self.window_s,
                MAX_WINDOW_SAMPLES as f64 / fs
            );
        }
        let n = n as usize;
        if n < MIN_WINDOW_SAMPLES {
            bail!(
                "features.window_s = {} s at {fs} Hz gives {n} samples; need at least {MIN_WINDOW_SAMPLES}",
                self.window_s
            );
        }
        Ok(n)
    }

    /// A recording of `n` samples at `fs` holds at least one window (checked before anything
    /// is sized for it).
    pub fn check_length(&self, n: usize, fs: f64) -> Result<()> {
        let need = self.window_samples(fs)?;
        if n < need {
            bail!(
                "{:.3} s ({n} samples) is shorter than one feature window (features.window_s = {} s = {need} samples at {fs} Hz); use a longer recording or a shorter window",
                n as f64 / fs,
                self.window_s
            );
        }
        Ok(())
    }

    /// Checks at a sample rate `fs` (the rig file's `acquisition.sample_rate_hz`, or a
    /// recording's): window and hop in samples, the low-pass below Nyquist, and some shaft
    /// speed at which the highest order stays inside the low-pass band.
    pub fn check_at_rate(&self, fs: f64) -> Result<()> {
        self.window_samples(fs)?;
        if (self.hop_s * fs).round() < 1.0 {
            bail!(
                "features.hop_s = {} s at {fs} Hz is less than one sample",
                self.hop_s
            );
        }
        let nyquist = fs / 2.0;
        if self.lowpass_hz >= nyquist {
            bail!(
                "features.lowpass_hz = {} Hz is at or above the Nyquist frequency {nyquist} Hz of {fs} Hz sampling; set it below {nyquist} Hz",
                self.lowpass_hz
            );
        }
        Ok(())
    }

    /// The highest order at shaft speed `rpm` (where `what` says it comes from, e.g.
    /// `speed.rpm`) must stay inside the low-pass band (and below Nyquist when `fs` is known).
    pub fn check_speed(&self, rpm: f64, what: &str, fs: Option<f64>) -> Result<()> {
        let top = self.max_order * rpm / 60.0;
        let (limit, name) = match fs {
            Some(fs) if fs / 2.0 < self.lowpass_hz => (
                fs / 2.0,
                format!("the Nyquist frequency of {fs} Hz sampling"),
            ),
            _ => (self.lowpass_hz, "features.lowpass_hz".to_string()),
        };
        if top > limit {
            bail!(
                "features.max_order = {} at {what} = {rpm} rpm puts the highest order at {top:.0} Hz, beyond {name} = {limit} Hz; lower max_order to at most {:.1} or raise lowpass_hz",
                self.max_order,
                limit * 60.0 / rpm
            );
        }
        Ok(())
    }

    /// Bin edges in orders: bin k covers (edges[k], edges[k+1]]; bin 0 ends at `bin_width`.
    pub fn bin_edges(&self) -> Vec<f64> {
        (0..=self.n_bins())
            .map(|k| k as f64 * self.bin_width_order)
            .collect()
    }
}
