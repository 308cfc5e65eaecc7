//! Rig configuration (TOML): machine identity, bearing geometry, acquisition, channels, speed
//! source and feature settings. Unknown keys are rejected with their name and line.
//!
//! The `[simulation]` section is [`simulation`] (the simulator reads it, `config` owns it, so
//! the rig file's types import nothing from the simulator); the daemon's
//! own file (`rigmon.toml`) belongs to the daemon (`daemon/config.rs`).

pub mod simulation;

use crate::bearing::BearingGeometry;
use crate::vocabulary::{AccelUnit, ChannelUnit};
// The `[speed]` and `[features]` sections belong to the DSP layer; re-exported here so the
// rig file reads as one type.
pub use crate::dsp::feature_settings::{
    FeatureSettings, MAX_FEATURE_BINS, MAX_WINDOW_S, MAX_WINDOW_SAMPLES,
};
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
    pub simulation: Option<crate::config::simulation::SimulationConfig>,
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
    /// MAT files: the scalar variable (or struct field, `"meta.fs"`) holding the sample rate
    /// in Hz.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mat_rate_variable: Option<String>,
    /// A folder of periodic captures (snapshots) read as one recording: seconds from the
    /// start of one capture to the start of the next. FEMTO-style CSV captures carry their
    /// own clock and need it only where that clock jumps (else their median step is used);
    /// WAV/MAT/CSV captures without a clock need it (`importers::snapshots`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture_interval_s: Option<f64>,
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
    /// Engineering unit after scaling (m/s^2, g, V): an acceleration channel's must be one
    /// of [`AccelUnit`]'s spellings, parsed when the file is read.
    pub unit: ChannelUnit,
    /// Raw value x sensitivity = value in `unit`.
    #[serde(default = "one")]
    pub sensitivity: f64,
    /// MAT files: the variable (or struct field, `"bearing.gs"`) holding this channel's
    /// samples ([`crate::importers::mat_layout`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mat_variable: Option<String>,
    /// MAT files: the column (from 1) of a samples x channels matrix `mat_variable` that is
    /// this channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mat_column: Option<usize>,
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

    /// Parse and validate rig TOML text. A unit that is not an acceleration unit on an
    /// acceleration channel is refused naming its line.
    pub fn parse(text: &str) -> Result<RigConfig> {
        let rig: RigConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Some((index, problem)) = rig.unit_problem() {
            match unit_line(text, index) {
                Some(line) => bail!("line {line}: {problem}"),
                None => bail!("{problem}"),
            }
        }
        rig.validate()?;
        Ok(rig)
    }

    /// The first acceleration channel whose unit is not an acceleration unit: its index in
    /// `channels` and what is wrong.
    fn unit_problem(&self) -> Option<(usize, String)> {
        let (index, c) = self
            .channels
            .iter()
            .enumerate()
            .find(|(_, c)| c.kind == ChannelKind::Acceleration && c.unit.accel().is_none())?;
        Some((
            index,
            format!(
                "channels {:?}: unit = {:?} is not an acceleration unit; an acceleration channel takes one of {}",
                c.name,
                c.unit.as_str(),
                AccelUnit::accepted()
            ),
        ))
    }

    /// Consistency checks that serde cannot express.
    pub fn validate(&self) -> Result<()> {
        if let Some((_, problem)) = self.unit_problem() {
            bail!("{problem}");
        }
        if let Some(key) = toml::Value::try_from(self)
            .ok()
            .as_ref()
            .and_then(|v| first_non_finite(v, ""))
        {
            bail!("{key} is not a finite number (nan and inf are not allowed in a rig file)");
        }
        self.bearing.validate().map_err(anyhow::Error::msg)?;
        self.features.validate()?;
        if let Some(sim) = &self.simulation {
            sim.validate()?;
        }
        if self.machine.id.is_empty() || self.machine.id.contains(['/', '*', '$', '#', '?', ' ']) {
            bail!("machine.id = {:?}: must be non-empty and free of / * $ # ? and spaces (it becomes a Zenoh key)", self.machine.id);
        }
        self.check_acquisition()?;
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
        if let SpeedConfig::Fixed { rpm, .. } = self.speed {
            if !(rpm.is_finite() && rpm > 0.0) {
                bail!("speed.rpm = {rpm}: must be a positive number");
            }
        }
        self.check_speed_hints()?;
        self.check_recipe_bounds()?;
        if self.classifier_channel().is_none() {
            bail!(
                "features.classifier_axis = {:?} matches no acceleration channel by name or axis; the channels are {:?}",
                self.features.classifier_axis,
                self.channel_names()
            );
        }
        self.validate_mat_keys()?;
        Ok(())
    }

    /// The MAT layout keys (`mat_variable`, `mat_column`, `mat_rate_variable`): well-formed
    /// variable paths, columns from 1, no variable read twice, and once any channel names its
    /// variable, the classifier channel must too.
    /// `[acquisition]`: a positive sample rate and capture interval, when given.
    fn check_acquisition(&self) -> Result<()> {
        if let Some(dt) = self.acquisition.capture_interval_s {
            if !(dt.is_finite() && dt > 0.0) {
                bail!(
                    "acquisition.capture_interval_s = {dt}: must be a positive number of seconds"
                );
            }
        }
        if let Some(fs) = self.acquisition.sample_rate_hz {
            if !(fs.is_finite() && fs > 0.0) {
                bail!("acquisition.sample_rate_hz = {fs}: must be a positive number");
            }
        }
        Ok(())
    }

    fn validate_mat_keys(&self) -> Result<()> {
        if let Some(v) = &self.acquisition.mat_rate_variable {
            check_mat_path("acquisition.mat_rate_variable", v)?;
        }
        let mut seen: Vec<(&str, usize, &str)> = Vec::new();
        for c in &self.channels {
            let key = format!("channels {:?}: mat_variable", c.name);
            match (&c.mat_variable, c.mat_column) {
                (None, Some(_)) => bail!(
                    "channels {:?}: mat_column needs mat_variable (the matrix it is a column of)",
                    c.name
                ),
                (_, Some(0)) => bail!(
                    "channels {:?}: mat_column = 0: columns count from 1 (as in MATLAB)",
                    c.name
                ),
                (Some(v), col) => {
                    check_mat_path(&key, v)?;
                    let col = col.unwrap_or(1);
                    if let Some((_, _, other)) =
                        seen.iter().find(|(w, k, _)| *w == v.as_str() && *k == col)
                    {
                        bail!(
                            "channels {other:?} and {:?} both read mat_variable = {v:?} (column {col}); each channel needs its own variable or mat_column",
                            c.name
                        );
                    }
                    seen.push((v, col, &c.name));
                }
                (None, None) => {}
            }
        }
        if let (false, Some(c)) = (seen.is_empty(), self.classifier_channel()) {
            if c.mat_variable.is_none() {
                bail!(
                    "channels {:?} feeds the classifier but names no mat_variable while other channels do; add mat_variable = \"<variable>\" to it",
                    c.name
                );
            }
        }
        Ok(())
    }

    /// `[speed]` keys that bound a search from the vibration: the band a fixed or nominal
    /// speed is checked in, and an estimate's range.
    fn check_speed_hints(&self) -> Result<()> {
        match self.speed {
            SpeedConfig::Fixed {
                check_within_percent,
                ..
            }
            | SpeedConfig::Estimate {
                check_within_percent,
                ..
            } if !(0.0..=50.0).contains(&check_within_percent) => bail!(
                "speed.check_within_percent = {check_within_percent}: use 0 (do not check the stated speed) to 50 (10 is the default: nominal motor speeds are often a few per cent off)"
            ),
            SpeedConfig::Estimate {
                min_rpm, max_rpm, ..
            } if !(min_rpm > 0.0 && max_rpm > min_rpm) => bail!(
                "speed.min_rpm = {min_rpm}, speed.max_rpm = {max_rpm}: need 0 < min_rpm < max_rpm (the machine's operating range)"
            ),
            _ => Ok(()),
        }
    }

    /// The recipe at the rig's own sample rate (when it sets one) and at the speeds `[speed]`
    /// names (a fixed rpm, the top of an estimate's range): window and hop in samples, the
    /// low-pass below Nyquist, the highest order inside the low-pass band.
    fn check_recipe_bounds(&self) -> Result<()> {
        let fs = self.acquisition.sample_rate_hz;
        if let Some(fs) = fs {
            self.features
                .check_at_rate(fs)
                .with_context(|| format!("at acquisition.sample_rate_hz = {fs}"))?;
        }
        match self.speed {
            // the stated speed (a window whose speed the vibration corrects upwards is
            // checked on its own: speed_out_of_range)
            SpeedConfig::Fixed { rpm, .. } => self.features.check_speed(rpm, "speed.rpm", fs),
            SpeedConfig::Estimate { max_rpm, .. } => {
                self.features.check_speed(max_rpm, "speed.max_rpm", fs)
            }
            _ => Ok(()),
        }
    }

    /// The recipe at a recording's (or source's) sample rate `fs`, and at its stored speed
    /// when `[speed]` uses it; `what` names the recording in errors.
    pub fn check_recipe_at(&self, fs: f64, stored_rpm: Option<f64>, what: &str) -> Result<()> {
        self.features
            .check_at_rate(fs)
            .with_context(|| format!("{what} is sampled at {fs} Hz"))?;
        if let (SpeedConfig::Recording { .. }, Some(rpm)) = (&self.speed, stored_rpm) {
            self.features
                .check_speed(rpm, "the recording's stored speed", Some(fs))
                .with_context(|| what.to_string())?;
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

/// The line (from 1) where channel `index`'s `unit` is written in rig TOML `text`.
fn unit_line(text: &str, index: usize) -> Option<usize> {
    #[derive(Deserialize)]
    struct Units {
        channels: Vec<UnitAt>,
    }
    #[derive(Deserialize)]
    struct UnitAt {
        unit: toml::Spanned<String>,
    }
    let units: Units = toml::from_str(text).ok()?;
    let start = units.channels.get(index)?.unit.span().start;
    Some(text.get(..start)?.matches('\n').count() + 1)
}

/// A MAT variable path: a variable name, or struct fields joined by dots (`bearing.gs`).
fn check_mat_path(key: &str, path: &str) -> Result<()> {
    if path
        .split('.')
        .any(|s| s.is_empty() || s.contains(char::is_whitespace))
    {
        bail!("{key} = {path:?}: expected a MAT variable name, or a struct field path such as \"bearing.gs\" (no spaces, no empty parts)");
    }
    Ok(())
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
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
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

    /// Issue 28: every spelling the daemon's velocity accepted is an acceleration unit of the
    /// rig file, parsed once; the tacho's `V` stays text; a wrong unit on an acceleration
    /// channel is refused when the file is read, naming the channel, the line and the
    /// accepted spellings.
    #[test]
    fn acceleration_units_are_parsed_once_and_a_wrong_one_is_refused_with_its_line() {
        let text = std::fs::read_to_string(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        for (spelling, unit) in [
            ("G", AccelUnit::StandardGravity),
            ("g", AccelUnit::StandardGravity),
            ("gn", AccelUnit::StandardGravity),
            ("m/s2", AccelUnit::MetrePerSecondSquared),
            ("M/S^2", AccelUnit::MetrePerSecondSquared),
            ("m/s²", AccelUnit::MetrePerSecondSquared),
            ("ms^-2", AccelUnit::MetrePerSecondSquared),
            ("mm/s^2", AccelUnit::MillimetrePerSecondSquared),
            ("mm/s2", AccelUnit::MillimetrePerSecondSquared),
        ] {
            let t = text.replacen("unit = \"m/s^2\"", &format!("unit = {spelling:?}"), 2);
            let rig = RigConfig::parse(&t).unwrap_or_else(|e| panic!("{spelling}: {e:#}"));
            assert_eq!(rig.channels[1].unit.accel(), Some(unit), "{spelling}");
            assert_eq!(rig.channels[1].unit.as_str(), spelling);
            assert_eq!(rig.channels[3].unit.as_str(), "V");
            assert_eq!(rig.channels[3].unit.accel(), None);
            // The file keeps its spelling when written back.
            let back = toml::to_string(&rig).unwrap();
            assert!(back.contains(&format!("unit = {spelling:?}")), "{back}");
            assert_eq!(RigConfig::parse(&back).unwrap(), rig);
        }
        // Line 31 holds the vertical channel's unit.
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[30], "unit = \"m/s^2\"");
        let bad = text.replacen("unit = \"m/s^2\"", "unit = \"furlong\"", 2);
        let bad = bad.replacen("unit = \"furlong\"", "unit = \"m/s^2\"", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(
            err.starts_with("line 31: channels \"vertical\": unit = \"furlong\""),
            "{err}"
        );
        assert!(
            err.contains("m/s^2") && err.contains("mm/s^2") && err.contains("gn"),
            "{err}"
        );
        // A rig built in code is checked by validate (no text, so no line).
        let mut rig = RigConfig::parse(&text).unwrap();
        rig.channels[0].unit = "furlong".into();
        let err = format!("{:#}", rig.validate().unwrap_err());
        assert!(
            err.starts_with("channels \"axial\": unit = \"furlong\""),
            "{err}"
        );
    }

    #[test]
    fn unknown_key_is_named_with_line() {
        let text = std::fs::read_to_string(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
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
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
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
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("bin_width_order = 0.5", "bin_width_order = 1e-300", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("at most 10000"), "{err}");
    }

    /// Issue 25, findings 2 and 10: everything that sizes memory is bounded, and settings
    /// past Nyquist are refused, when the rig file is read, naming the key and both numbers.
    /// Before, `window_s = 1e9` aborted every command (a 20 TB allocation) and `lowpass_hz =
    /// 9000` at 10 kHz or `max_order = 4000` passed.
    #[test]
    fn window_nyquist_and_order_bounds_are_refused_by_key() {
        let text = std::fs::read_to_string(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let refused = |from: &str, to: &str| {
            assert!(text.contains(from), "{from}");
            format!(
                "{:#}",
                RigConfig::parse(&text.replacen(from, to, 1)).unwrap_err()
            )
        };
        let e = refused("window_s = 1.0", "window_s = 1e9");
        assert!(e.contains("features.window_s") && e.contains("3600"), "{e}");
        let e = refused("window_s = 1.0", "window_s = 3600.0");
        assert!(
            e.contains("features.window_s = 3600 s at 10000 Hz")
                && e.contains("36000000 samples")
                && e.contains("2097152"),
            "{e}"
        );
        let e = refused("lowpass_hz = 4000.0", "lowpass_hz = 9000.0");
        assert!(
            e.contains("features.lowpass_hz = 9000 Hz") && e.contains("Nyquist frequency 5000 Hz"),
            "{e}"
        );
        let e = refused("max_order = 50.0", "max_order = 4000.0");
        assert!(
            e.contains("features.max_order = 4000")
                && e.contains("8000 Hz")
                && e.contains("features.lowpass_hz = 4000 Hz"),
            "{e}"
        );
        let e = refused("hop_s = 0.5", "hop_s = 0.00001");
        assert!(
            e.contains("features.hop_s") && e.contains("one sample"),
            "{e}"
        );
        // A known speed is checked too: 50 orders at 6000 rpm reach 5000 Hz > 4000 Hz.
        let tacho = "[speed]\nsource = \"tacho\"\nchannel = \"tacho\"\npulses_per_rev = 1\nthreshold = 2.5\nhysteresis = 0.5\n";
        assert!(text.contains(tacho));
        let bad = text.replacen(tacho, "[speed]\nsource = \"fixed\"\nrpm = 6000.0\n", 1);
        let e = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(
            e.contains("speed.rpm = 6000 rpm") && e.contains("5000 Hz") && e.contains("4000"),
            "{e}"
        );
        assert!(RigConfig::parse(&bad.replace("rpm = 6000.0", "rpm = 1200.0")).is_ok());
        // At a recording's rate (a rig file that takes it from the file).
        let rig = RigConfig::parse(&text).unwrap();
        let e = format!(
            "{:#}",
            rig.check_recipe_at(5000.0, None, "recording x.wav")
                .unwrap_err()
        );
        assert!(
            e.contains("recording x.wav") && e.contains("Nyquist frequency 2500 Hz"),
            "{e}"
        );
    }

    #[test]
    fn tacho_must_name_a_tacho_channel() {
        let text = std::fs::read_to_string(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let bad = text.replacen("channel = \"tacho\"", "channel = \"tach\"", 1);
        let err = format!("{:#}", RigConfig::parse(&bad).unwrap_err());
        assert!(err.contains("\"tach\" names no channel"), "{err}");
    }
}
