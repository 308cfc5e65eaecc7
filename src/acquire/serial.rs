//! The serial DAQ adapter: reads frames of the rigmon serial protocol
//! ([`super::serial_protocol`]) from a serial port, reconnects with backoff when the device
//! goes away, and counts bad frames, sequence gaps and lost samples instead of failing.

use super::Source;
use crate::config::RigConfig;
use anyhow::Result;
use serde::{Deserialize, Serialize};

fn default_baud() -> u32 {
    921_600
}
fn default_block_ms() -> f64 {
    100.0
}
fn default_reconnect_max_ms() -> u64 {
    2000
}

/// `[source] type = "serial"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSourceConfig {
    /// The serial device (`/dev/ttyUSB0`, `/dev/serial/by-id/...`, or the path
    /// `rigmon emulate serial --pty` prints).
    pub port: String,
    /// Baud rate (ignored by pseudo-terminals and USB CDC devices).
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Sample rate the DAQ runs at; defaults to the rig's `acquisition.sample_rate_hz`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// Longest wait between reconnection attempts, ms (the wait doubles from 50 ms).
    #[serde(default = "default_reconnect_max_ms")]
    pub reconnect_max_ms: u64,
}

impl SerialSourceConfig {
    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        let _ = rig;
        anyhow::bail!(
            "serial source {}: not available in this build yet",
            self.port
        )
    }
}
