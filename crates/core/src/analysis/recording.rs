//! Whole recordings -> feature windows, exactly as the daemon would compute them: the
//! recording is fed as sample blocks through the same [`Windower`] and [`AnalysisStage`]
//! (window by window speed included), so `rigmon features`, training and evaluation see the
//! features a served model is given. A window that cannot be computed (NaN samples, no
//! speed) is an error naming the window; [`analyze_recording`] instead keeps every window as
//! the daemon would see it (quality flags, no-speed and failed windows included), for scores
//! that must say what the daemon says. A recording made of periodic captures is fed capture by
//! capture at each one's time ([`crate::recording::captures`]): no window straddles two.

use super::speed_source::SpeedSource;
use super::stage::{AnalysisStage, WindowAnalysis};
use super::windows::Windower;
use crate::config::RigConfig;
use crate::dsp::features::FeatureWindow;
use crate::dsp::speed::SpeedTrack;
use crate::recording::stream::block_of;
use crate::recording::{captures, Recording};
use anyhow::{bail, Context, Result};

/// Samples per block fed to the windower (the result does not depend on it).
const BLOCK: usize = 4096;

/// Features of every full window of a recording, with the speed source from the rig file.
pub fn extract_recording(rec: &Recording, rig: &RigConfig) -> Result<Vec<FeatureWindow>> {
    extract(rec, rig, SpeedSource::for_recording(rec, rig)?)
}

/// Features of every full window of a recording along a given speed track.
pub fn extract_with_speed(
    rec: &Recording,
    rig: &RigConfig,
    speed: &SpeedTrack,
) -> Result<Vec<FeatureWindow>> {
    extract(rec, rig, SpeedSource::given(speed.clone(), rec.sample_rate))
}

/// Every full window of a recording as the daemon analyses it (non-finite samples zeroed and
/// flagged, windows without speed or features kept with their error), with the speed source
/// from the rig file.
pub fn analyze_recording(rec: &Recording, rig: &RigConfig) -> Result<Vec<WindowAnalysis>> {
    let speed = SpeedSource::for_recording(rec, rig)?;
    let mut out = Vec::new();
    each_window(rec, rig, speed, false, |a| {
        out.push(a);
        Ok(())
    })?;
    Ok(out)
}

fn extract(rec: &Recording, rig: &RigConfig, speed: SpeedSource) -> Result<Vec<FeatureWindow>> {
    let what = &rec.provenance.source_path;
    let mut out = Vec::new();
    each_window(rec, rig, speed, true, |a| {
        let t = a.t_start;
        out.push(
            a.features
                .map_err(|e| e.into_error())
                .with_context(|| format!("{what}: window at t = {t:.3} s"))?,
        );
        Ok(())
    })?;
    Ok(out)
}

/// Feed the recording through the windower and the analysis stage (`strict`: non-finite
/// samples reach the pipeline, which refuses the window) and hand each window to `each`.
fn each_window(
    rec: &Recording,
    rig: &RigConfig,
    speed: SpeedSource,
    strict: bool,
    mut each: impl FnMut(WindowAnalysis) -> Result<()>,
) -> Result<()> {
    let what = &rec.provenance.source_path;
    if rec.channels.is_empty() {
        bail!("{what}: the recording has no acceleration channel");
    }
    if let Some(bad) = rec.channels.iter().find(|c| c.samples.len() != rec.len()) {
        bail!(
            "{what}: channel {:?} has {} samples but {:?} has {}; channels must be the same length",
            bad.name,
            bad.samples.len(),
            rec.channels[0].name,
            rec.len()
        );
    }
    let fs = rec.sample_rate;
    let channels: Vec<(String, String)> = rec
        .channels
        .iter()
        .map(|c| (c.name.clone(), c.unit.clone()))
        .collect();
    let mut stage = AnalysisStage::new(rig, fs, &channels, &[], speed)?;
    if strict {
        stage = stage.strict();
    }
    let n = stage.window_len();
    if rec.len() < n {
        bail!(
            "{what}: {:.3} s of signal is shorter than one feature window ({} s); use a longer recording or a shorter features.window_s",
            rec.duration_s(),
            rig.features.window_s
        );
    }
    let mut windower = Windower::for_rig(&rig.speed, &rig.features, fs, channels.len())?;
    let spans = captures::spans(rec).map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
    if captures::is_capture_series(&rec.metadata) {
        windower = windower.capture_series();
    }
    let longest = spans.iter().map(|s| s.end - s.start).max().unwrap_or(0);
    if longest < n {
        bail!(
            "{what}: its {} captures last at most {:.4} s each, shorter than one feature window ({} s); \
             set features.window_s (and hop_s) to at most the capture's length in the rig file",
            spans.len(),
            longest as f64 / fs,
            rig.features.window_s
        );
    }
    for span in spans {
        let mut start = span.start;
        while start < span.end {
            let end = (start + BLOCK).min(span.end);
            let mut block = block_of(rec, start, end);
            // Each capture at its own time: the time between captures is not signal.
            let shift = span.clock as f64 / fs - span.start as f64 / fs;
            block.first_sample = span.clock + (start - span.start) as u64;
            block.tacho_edges.iter_mut().for_each(|t| *t += shift);
            windower.push(&block);
            // Every window is complete once its last sample is in: none waits for a later
            // block.
            while let Some(view) = windower.window() {
                let a = stage.analyze(&view);
                drop(view);
                windower.advance();
                each(a)?;
            }
            start = end;
        }
    }
    Ok(())
}
