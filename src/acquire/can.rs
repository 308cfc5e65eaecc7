//! The CAN adapter: reads frames of the rigmon CAN layout from a SocketCAN interface
//! (feature `can`), reconnects when the interface goes down, and counts bad frames, sequence
//! gaps and lost samples instead of failing.

use super::Source;
use crate::config::RigConfig;
use anyhow::Result;
use serde::{Deserialize, Serialize};

fn default_base_id() -> u32 {
    0x100
}
fn default_block_ms() -> f64 {
    100.0
}
fn default_reconnect_max_ms() -> u64 {
    2000
}

/// `[source] type = "can"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanSourceConfig {
    /// SocketCAN interface (`can0`, `vcan0`).
    pub interface: String,
    /// The adapter sends CAN FD (64-byte) frames; otherwise classic 8-byte frames.
    #[serde(default)]
    pub fd: bool,
    /// First CAN ID of the adapter's block of IDs (see the CAN layout in the README).
    #[serde(default = "default_base_id")]
    pub base_id: u32,
    /// Sample rate the adapter runs at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// Longest wait between reconnection attempts, ms.
    #[serde(default = "default_reconnect_max_ms")]
    pub reconnect_max_ms: u64,
}

impl CanSourceConfig {
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        let _ = rig;
        anyhow::bail!(
            "can source {}: not available in this build yet",
            self.interface
        )
    }
}
