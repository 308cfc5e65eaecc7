//! Rig configuration (TOML): machine identity, bearing geometry, acquisition, channels, speed
//! source and feature settings. Unknown keys are rejected with their name and line.
//!
//! The simulator's section type is the simulator's own ([`crate::sim::config`]); the daemon's
//! own file (`rigmon.toml`) belongs to the daemon (`daemon/config.rs`).

use crate::bearing::BearingGeometry;
// The `[speed]` and `[features]` sections belong to the DSP layer; re-exported here so the
// rig file reads as one type.
pub use crate::dsp::feature_settings::{FeatureSettings, MAX_FEATURE_BINS};
pub use crate::dsp::speed_config::SpeedConfig;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole rig file (`config/lut-rig.toml`, `config/cwru-de.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    pub machine: Machine,
    pub bearing: BearingGeometry,
    #[serde(default)]
    pub acquisition: Acquisition,
    /// Channels in the order they appear in WAV/CSV input (tacho included).
    pub channels: Vec<ChannelConfig>,
    pub speed: SpeedConfig,
    #[serde(default)]
    pub features: FeatureSettings,
    /// Simulator description of this rig (optional; `rigmon simulate` needs it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<crate::sim::config::SimulationConfig>,
    /// Set by `rigmon calibrate`: which calibration produced this file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationStamp>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// Short id used in topics, file names and model metadata (e.g. "lut-rig").
    pub id: String,
    #[serde(default)]
    pub description: String,
    /// Asset and measurement point names for topics (`rigmon/<rig>/<asset>/<point>/...`).
    #[serde(default = "default_asset")]
    pub asset: String,
    #[serde(default = "default_point")]
    pub point: String,
    /// Site (plant, lab) the machine belongs to: the top of the fleet historian's asset tree.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub site: Option<String>,
}

fn default_asset() -> String {
    "shaft".into()
}
fn default_point() -> String {
    "nde".into()
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Acquisition {
    /// Sample rate in Hz; `None` means "taken from the recording" (e.g. CWRU files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
}

/// What a channel measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelKind {
    Acceleration,
    /// Analog tacho voltage (pulses per revolution from [`SpeedConfig`]).
    Tacho,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelConfig {
    /// Channel name (e.g. "vertical", "DE").
    pub name: String,
    pub kind: ChannelKind,
    /// Measurement axis (axial, vertical, horizontal, radial, ...); free text.
    #[serde(default)]
    pub axis: String,
    /// Engineering unit after scaling (m/s^2, g, V).
    pub unit: String,
    /// Raw value x sensitivity = value in `unit`.
    #[serde(default = "one")]
    pub sensitivity: f64,
}

fn one() -> f64 {
    1.0
}

/// Which calibration produced a rig file; flows into model metadata.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationStamp {
    pub id: String,
    #[serde(default)]
    pub effects: Vec<toml::Table>,
}

impl RigConfig {
    /// Read and validate a rig file. Errors name the file, the line and the key.
    pub fn load(path: &Path) -> Result<RigConfig> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read rig file {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("in rig file {}", path.display()))
    }

    /// Parse and validate rig TOML text.
    pub fn parse(text: &str) -> Result<RigConfig> {
        let rig: RigConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        rig.validate()?;
        Ok(rig)
    }

    /// Consistency checks that serde cannot express.
    pub fn validate(&self) -> Result<()> {
        if let Some(key) = toml::Value::try_from(self)
            .ok()
            .as_ref()
            .and_then(|v| first_non_finite(v, ""))
        {
            bail!("{key} is not a finite number (nan and inf are not allowed in a rig file)");
        }
        self.bearing.validate().map_err(anyhow::Error::msg)?;
        if !(self.features.lowpass_hz > 0.0) {
            bail!(
                "features.lowpass_hz = {}: must be a positive frequency",
                self.features.lowpass_hz
            );
        }
        if let Some(sim) = &self.simulation {
            sim.validate()?;
        }
        if self.machine.id.is_empty() || self.machine.id.contains(['/', '*', '$', '#', '?', ' ']) {
            bail!("machine.id = {:?}: must be non-empty and free of / * $ # ? and spaces (it becomes a Zenoh key)", self.machine.id);
        }
        if let Some(fs) = self.acquisition.sample_rate_hz {
            if !(fs.is_finite() && fs > 0.0) {
                bail!("acquisition.sample_rate_hz = {fs}: must be a positive number");
            }
        }
        if self.acceleration_channels().next().is_none() {
            bail!("channels: no channel of kind \"acceleration\"; add at least one");
        }
        let mut names: Vec<&str> = self.channels.iter().map(|c| c.name.as_str()).collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            bail!(
                "channels: the name {:?} is used twice; channel names must be unique",
                w[0]
            );
        }
        if let SpeedConfig::Tacho {
            channel,
            pulses_per_rev,
            ..
        } = &self.speed
        {
            match self.channels.iter().find(|c| &c.name == channel) {
                Some(c) if c.kind == ChannelKind::Tacho => {}
                Some(_) => bail!("speed.channel = {channel:?} is not of kind \"tacho\""),
                None => bail!(
                    "speed.channel = {channel:?} names no channel; the channels are {:?}",
                    self.channel_names()
                ),
            }
            if *pulses_per_rev == 0 {
                bail!("speed.pulses_per_rev must be at least 1");
            }
        }
        if let SpeedConfig::Recording {
            check_within_percent,
        } = self.speed
        {
            if !(0.0..=20.0).contains(&check_within_percent) {
                bail!("speed.check_within_percent = {check_within_percent}: use 0 (do not check the stored speed) to 20 (5 is typical)");
            }
        }
        if let SpeedConfig::Fixed { rpm } = self.speed {
            if !(rpm.is_finite() && rpm > 0.0) {
                bail!("speed.rpm = {rpm}: must be a positive number");
            }
        }
        let f = &self.features;
        if !(f.window_s > 0.0 && f.hop_s > 0.0 && f.hop_s <= f.window_s) {
            bail!(
                "features: need 0 < hop_s <= window_s (got window_s = {}, hop_s = {})",
                f.window_s,
                f.hop_s
            );
        }
        if !(f.bin_width_order > 0.0 && f.max_order > f.bin_width_order) {
            bail!("features: need 0 < bin_width_order < max_order");
        }
        let fit = f.max_order / f.bin_width_order;
        if !(fit.is_finite() && fit <= MAX_FEATURE_BINS as f64) {
            bail!(
                "features: max_order / bin_width_order = {fit} bins; at most {MAX_FEATURE_BINS} are supported (the default recipe has 100)"
            );
        }
        if (fit - fit.round()).abs() > 1e-9 {
            bail!(
                "features.max_order ({}) must be a whole number of bins of width {}",
                f.max_order,
                f.bin_width_order
            );
        }
        if self.classifier_channel().is_none() {
            bail!(
                "features.classifier_axis = {:?} matches no acceleration channel by name or axis; the channels are {:?}",
                f.classifier_axis,
                self.channel_names()
            );
        }
        Ok(())
    }

    pub fn channel_names(&self) -> Vec<&str> {
        self.channels.iter().map(|c| c.name.as_str()).collect()
    }

    /// Acceleration channels in file order.
    pub fn acceleration_channels(&self) -> impl Iterator<Item = &ChannelConfig> {
        self.channels
            .iter()
            .filter(|c| c.kind == ChannelKind::Acceleration)
    }

    /// The acceleration channel feeding the classifier (matched by name first, then axis).
    pub fn classifier_channel(&self) -> Option<&ChannelConfig> {
        let want = &self.features.classifier_axis;
        self.acceleration_channels()
            .find(|c| &c.name == want)
            .or_else(|| self.acceleration_channels().find(|c| &c.axis == want))
    }

    /// Pulses per revolution of the tacho, whatever form it comes in.
    pub fn pulses_per_rev(&self) -> u32 {
        self.speed.pulses_per_rev()
    }
}

/// The dotted key of the first NaN or infinite float in a TOML tree, if any.
fn first_non_finite(v: &toml::Value, path: &str) -> Option<String> {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match v {
        toml::Value::Float(f) if !f.is_finite() => Some(if path.is_empty() {
            "a value".into()
        } else {
            path.to_string()
        }),
        toml::Value::Table(t) => t.iter().find_map(|(k, x)| first_non_finite(x, &join(k))),
        toml::Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| first_non_finite(x, &format!("{path}[{i}]"))),
        _ => None,
    }
}

/// Resolve a path given in a config file relative to that file's folder.
pub fn resolve_relative(base_file: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base_file.parent().unwrap_or(Path::new(".")).join(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped(name: &str) -> RigConfig {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config")
            .join(name);
        RigConfig::load(&p).unwrap()
    }

    #[test]
    fn shipped_lut_rig_parses() {
        let rig = shipped("lut-rig.toml");
        assert_eq!(rig.machine.id, "lut-rig");
        assert_eq!(rig.bearing.balls, 11);
        assert_eq!(rig.acquisition.sample_rate_hz, Some(10_000.0));
        assert_eq!(
            rig.channel_names(),
            ["axial", "vertical", "horizontal", "tacho"]
        );
        assert_eq!(rig.classifier_channel().unwrap().name, "vertical");
        assert_eq!(rig.features.n_bins(), 100);
        assert_eq!(rig.features.bin_edges()[1], 0.5);
    }

    #[test]
    fn shipped_cwru_parses() {
        let rig = shipped("cwru-de.toml");
        assert_eq!(rig.bearing.balls, 9);
        assert_eq!(rig.acquisition.sample_rate_hz, None);
        assert_eq!(rig.classifier_channel().unwrap().name, "DE");
    }

    #[test]
    fn unknown_key_is_named_with_line() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("[features]", "[features]\nlowpas_hz = 3000", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("lowpas_hz"), "{err}");
        assert!(err.contains("line"), "{err}");
    }

    #[test]
    fn non_finite_numbers_are_refused_by_key() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("lowpass_hz = 4000.0", "lowpass_hz = nan", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("features.lowpass_hz"), "{err}");
        let bad = text.replacen("max_order = 50.0", "max_order = inf", 1);
        assert!(RigConfig::parse(&bad).is_err());
    }

    #[test]
    fn absurd_bin_counts_are_refused() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("bin_width_order = 0.5", "bin_width_order = 1e-300", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("at most 10000"), "{err}");
    }

    #[test]
    fn tacho_must_name_a_tacho_channel() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("channel = \"tacho\"", "channel = \"tach\"", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("\"tach\" names no channel"), "{err}");
    }
}
