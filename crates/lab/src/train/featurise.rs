//! Turning manifest entries into classifier features: each recording is read with the
//! importers (any supported format) and run through the analysis stage the daemon uses
//! (`analysis::extract_recording`); files are processed in parallel and hashed for the
//! training-data hash.

use super::dataset::RecordingFeatures;
use crate::config::RigConfig;
use crate::importers;
use crate::manifest::ManifestEntry;
use anyhow::{bail, Context, Result};
use ndarray::Array2;
use rayon::prelude::*;

/// Load one recording and compute its classifier features.
pub fn featurise(entry: &ManifestEntry, rig: &RigConfig) -> Result<RecordingFeatures> {
    let sha256 = crate::model::digest::sha256_of_path(&entry.path)
        .with_context(|| format!("manifest line {}", entry.line))?;
    let rec = importers::load(&entry.path, rig, &entry.import_options()).with_context(|| {
        format!(
            "manifest line {}: loading {}",
            entry.line,
            entry.path.display()
        )
    })?;
    let wins = crate::analysis::extract_recording(&rec, rig)
        .with_context(|| format!("features of {}", entry.path.display()))?;
    let n = rig.features.n_bins();
    let mut data = Vec::with_capacity(wins.len() * n);
    let mut kurtosis = Vec::with_capacity(wins.len());
    let mut rpm = 0.0;
    let mut kept = 0usize;
    for w in wins
        .iter()
        .filter(|w| entry.keeps_window(w.t_start, w.t_end))
    {
        let f = w.classifier_features(rig);
        if f.len() != n || f.iter().any(|v| !v.is_finite()) {
            continue;
        }
        data.extend_from_slice(f);
        kurtosis.push(w.classifier_kurtosis(rig).map_or(f32::NAN, |(k, _)| k));
        rpm += w.rpm;
        kept += 1;
    }
    if kept == 0 {
        if let Some((a, b)) = entry.span {
            bail!("{}: no whole feature window between start_s {a} and end_s {b} (manifest line {}; {} windows in the recording, {} s each): widen the span", entry.path.display(), entry.line, wins.len(), rig.features.window_s);
        }
        bail!("{}: no usable feature window ({} windows computed; the recording may be shorter than one window or carry NaN)", entry.path.display(), wins.len());
    }
    Ok(RecordingFeatures {
        path: entry.path.clone(),
        path_text: entry.display_name(),
        label: entry.label.clone(),
        sha256,
        simulated: rec.is_simulated(),
        rpm: rpm / kept as f64,
        windows: Array2::from_shape_vec((kept, n), data)?,
        kurtosis,
    })
}

/// Featurise every entry, in parallel, keeping manifest order. `progress` is ticked per file.
pub fn featurise_all(
    entries: &[ManifestEntry],
    rig: &RigConfig,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<RecordingFeatures>> {
    entries
        .par_iter()
        .map(|e| {
            let r = featurise(e, rig);
            progress.inc(1);
            r
        })
        .collect()
}
