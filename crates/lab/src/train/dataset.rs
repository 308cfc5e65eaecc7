//! Labelled recordings reduced for training and evaluation: a recording as its classifier
//! feature windows ([`RecordingFeatures`], made by [`super::featurise`] from a
//! [`crate::manifest`] row), and the training-data hash.

use ndarray::Array2;
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// A recording reduced to its classifier feature windows.
#[derive(Debug, Clone)]
pub struct RecordingFeatures {
    pub path: PathBuf,
    pub path_text: String,
    pub label: String,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    /// Made by the simulator (as opposed to measured).
    pub simulated: bool,
    /// Mean shaft speed over the windows, rpm.
    pub rpm: f64,
    /// `[windows, bins]` raw classifier features.
    pub windows: Array2<f32>,
    /// The classifier channel's excess kurtosis per window (row order of `windows`; NaN where
    /// the window had none).
    pub kurtosis: Vec<f32>,
}

/// SHA-256 over `label <TAB> file-sha256` lines in manifest order: identifies training data.
pub fn data_hash(recs: &[RecordingFeatures]) -> String {
    let mut h = Sha256::new();
    for r in recs {
        h.update(format!("{}\t{}\n", r.label, r.sha256).as_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}
