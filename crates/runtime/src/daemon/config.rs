//! The daemon's own configuration file (`config/rigmon.toml`): rig file, source, model,
//! health policy, pipeline queues, Zenoh and recording. Unknown keys are rejected with their
//! name and line; relative paths are relative to the folder of the file they appear in
//! (recordings: relative to `$STATE_DIRECTORY` when systemd sets it).

use crate::acquire::SourceConfig;
use crate::config::{resolve_relative, RigConfig};
use crate::health::HealthPolicy;
use crate::publish::zenoh::ZenohSettings;
use crate::recorder::RecordConfig;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole `rigmon.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaemonConfig {
    /// The rig file (machine, bearing, channels, speed, feature recipe).
    pub rig: PathBuf,
    pub source: SourceConfig,
    pub model: ModelConfig,
    #[serde(default)]
    pub health: HealthPolicy,
    #[serde(default)]
    pub pipeline: PipelineConfig,
    #[serde(default)]
    pub zenoh: ZenohSettings,
    #[serde(default)]
    pub recording: RecordConfig,
}

/// `[model]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    /// The ONNX classifier (trained by `rigmon train`, metadata inside).
    pub path: PathBuf,
    /// Serve a model trained for another rig (its rig id, classifier axis, bearing orders,
    /// low-pass or window differ from the rig file's) on purpose; refused otherwise. Every
    /// health message then lists the differences (`model.foreign`).
    #[serde(default)]
    pub allow_foreign: bool,
}

impl ModelConfig {
    /// The model at `path`, refusing one trained for another rig.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        ModelConfig {
            path: path.into(),
            allow_foreign: false,
        }
    }
}

/// `[pipeline]`: queue sizes and what to publish besides health.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineConfig {
    /// Blocks the source may queue ahead of the pipeline before it has to drop (live
    /// sources) or wait (file replay).
    #[serde(default = "default_queue_blocks")]
    pub queue_blocks: usize,
    /// Messages each sink (Zenoh, recording, stdout) may queue before messages are dropped
    /// and counted.
    #[serde(default = "default_sink_queue")]
    pub sink_queue: usize,
    /// Publish the classifier channel's envelope order spectrum on `.../spectrum`.
    #[serde(default = "yes")]
    pub spectrum: bool,
    /// Seconds between status messages on `.../status`.
    #[serde(default = "default_status_every")]
    pub status_every_s: f64,
}

fn default_queue_blocks() -> usize {
    64
}
fn default_sink_queue() -> usize {
    256
}
fn yes() -> bool {
    true
}
fn default_status_every() -> f64 {
    2.0
}

impl Default for PipelineConfig {
    fn default() -> Self {
        PipelineConfig {
            queue_blocks: default_queue_blocks(),
            sink_queue: default_sink_queue(),
            spectrum: true,
            status_every_s: default_status_every(),
        }
    }
}

impl DaemonConfig {
    /// Read, parse, resolve relative paths and validate. Errors name the file and the key.
    pub fn load(path: &Path) -> Result<DaemonConfig> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read daemon config {}", path.display()))?;
        Self::parse(&text, path).with_context(|| format!("in daemon config {}", path.display()))
    }

    /// Parse text that was read from `path` (used to resolve relative paths).
    pub fn parse(text: &str, path: &Path) -> Result<DaemonConfig> {
        let mut c: DaemonConfig = toml::from_str(text).map_err(|e| anyhow::anyhow!("{e}"))?;
        c.resolve_paths(path);
        c.validate()?;
        Ok(c)
    }

    /// Make every relative path absolute-or-relative-to-cwd as the rules above say.
    pub fn resolve_paths(&mut self, base_file: &Path) {
        self.rig = resolve_relative(base_file, &self.rig);
        self.model.path = resolve_relative(base_file, &self.model.path);
        self.source.resolve_paths(base_file);
        if let Some(p) = &self.zenoh.config_file {
            self.zenoh.config_file = Some(resolve_relative(base_file, p));
        }
        let z = &mut self.zenoh;
        for p in [
            &mut z.auth.users_file,
            &mut z.auth.password_file,
            &mut z.tls.root_ca,
            &mut z.tls.cert,
            &mut z.tls.key,
        ]
        .into_iter()
        .flatten()
        {
            *p = resolve_relative(base_file, p);
        }
        if self.recording.dir.is_relative() {
            self.recording.dir = match std::env::var_os("STATE_DIRECTORY") {
                // systemd may pass several colon-separated directories; the first is ours.
                Some(s) => Path::new(s.to_string_lossy().split(':').next().unwrap_or("."))
                    .join(&self.recording.dir),
                None => resolve_relative(base_file, &self.recording.dir),
            };
        }
    }

    pub fn validate(&self) -> Result<()> {
        self.health.validate()?;
        self.zenoh.validate()?;
        self.recording.validate()?;
        if self.pipeline.queue_blocks == 0 || self.pipeline.sink_queue == 0 {
            bail!("pipeline.queue_blocks and pipeline.sink_queue must be at least 1");
        }
        if !(self.pipeline.status_every_s > 0.0 && self.pipeline.status_every_s.is_finite()) {
            bail!(
                "pipeline.status_every_s = {}: must be a positive number",
                self.pipeline.status_every_s
            );
        }
        Ok(())
    }

    /// Load the rig file this config points to.
    pub fn load_rig(&self) -> Result<RigConfig> {
        RigConfig::load(&self.rig)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> (String, PathBuf) {
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/rigmon.toml");
        (std::fs::read_to_string(&p).unwrap(), p)
    }

    #[test]
    fn shipped_config_parses_and_is_loopback_only() {
        let (text, p) = shipped();
        let c = DaemonConfig::parse(&text, &p).unwrap();
        assert!(c.rig.ends_with("lut-rig.toml"));
        c.load_rig().unwrap();
        assert!(c.model.path.ends_with("models/lut-rig.onnx"));
        assert_eq!(c.zenoh.mode, crate::vocabulary::ZenohMode::Peer);
        assert!(!c.zenoh.multicast_scouting);
        assert!(!c.zenoh.listen.is_empty());
        for e in c.zenoh.listen.iter().chain(&c.zenoh.connect) {
            assert!(
                e.starts_with("tcp/127.0.0.1:"),
                "shipped config must bind to loopback only: {e}"
            );
        }
    }

    #[test]
    fn unknown_keys_are_named() {
        let (text, p) = shipped();
        let bad = text.replacen("[health]", "[health]\nvote_m = 3", 1);
        let e = format!("{:#}", DaemonConfig::parse(&bad, &p).unwrap_err());
        assert!(e.contains("vote_m") && e.contains("line"), "{e}");
        let bad = text.replacen("vote_k = 3", "vote_k = 1", 1);
        let e = format!("{:#}", DaemonConfig::parse(&bad, &p).unwrap_err());
        assert!(e.contains("health.vote_k"), "{e}");
    }
}
