//! The sound-card source (feature `audio`, cpal -> ALSA): input channels mapped to rig
//! channels by name, the tacho on one of them; samples scaled by the rig's sensitivity.

use super::Source;
use crate::config::RigConfig;
use anyhow::Result;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

fn default_block_ms() -> f64 {
    100.0
}

/// `[source] type = "audio"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AudioSourceConfig {
    /// Input device name as ALSA lists it (`arecord -L`); the default input device if unset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// Sample rate to open the device at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Rig channel name -> input channel index (0-based), e.g.
    /// `map = { vertical = 0, horizontal = 1, axial = 2, tacho = 3 }`.
    pub map: BTreeMap<String, u16>,
    /// Channels to open on the device; defaults to the highest mapped index + 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_channels: Option<u16>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
}

impl AudioSourceConfig {
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        let _ = rig;
        anyhow::bail!("audio source: not available in this build yet")
    }
}
