//! Importers: read recordings from CWRU/MFPT `.mat`, WAV, CSV and rigmon MCAP into a
//! [`Recording`](crate::recording::Recording).

use crate::config::RigConfig;
use crate::recording::Recording;
use anyhow::{bail, Result};
use std::path::Path;

/// Options a user may give on the command line to override what a file or rig says.
#[derive(Debug, Clone, Default)]
pub struct ImportOptions {
    /// Sample rate override, Hz.
    pub sample_rate: Option<f64>,
    /// Speed override, rpm.
    pub rpm: Option<f64>,
}

/// Read any supported recording, chosen by content and extension.
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let _ = (rig, opts);
    bail!(
        "{}: reading recordings is not implemented yet",
        path.display()
    )
}
