//! Whole recordings -> feature windows: the speed track the rig file asks for, then the
//! pipeline over every full window (window_s long, hop_s apart) of all acceleration channels.

use crate::config::RigConfig;
use crate::dsp::features::{FeaturePipeline, FeatureWindow};
use crate::dsp::speed::SpeedTrack;
use crate::recording::Recording;
use anyhow::{bail, Context, Result};

/// Features of every full window of a recording, with the speed source from the rig file.
pub fn extract_recording(rec: &Recording, rig: &RigConfig) -> Result<Vec<FeatureWindow>> {
    let speed = SpeedTrack::for_recording(rec, rig)
        .with_context(|| format!("speed for {}", rec.provenance.source_path))?;
    extract_with_speed(rec, rig, &speed)
}

/// Features of every full window of a recording along a given speed track.
pub fn extract_with_speed(
    rec: &Recording,
    rig: &RigConfig,
    speed: &SpeedTrack,
) -> Result<Vec<FeatureWindow>> {
    let what = &rec.provenance.source_path;
    if rec.channels.is_empty() {
        bail!("{what}: the recording has no acceleration channel");
    }
    let mut pipe = FeaturePipeline::new(rig, rec.sample_rate)?;
    let n = pipe.window_len();
    let hop = ((rig.features.hop_s * rec.sample_rate).round() as usize).max(1);
    if rec.len() < n {
        bail!(
            "{what}: {:.3} s of signal is shorter than one feature window ({} s); use a longer recording or a shorter features.window_s",
            rec.duration_s(),
            rig.features.window_s
        );
    }
    let mut out = Vec::with_capacity((rec.len() - n) / hop + 1);
    let mut views: Vec<(&str, &[f32])> = Vec::with_capacity(rec.channels.len());
    let mut start = 0;
    while start + n <= rec.len() {
        views.clear();
        views.extend(
            rec.channels
                .iter()
                .map(|c| (c.name.as_str(), &c.samples[start..start + n])),
        );
        let t = start as f64 / rec.sample_rate;
        out.push(
            pipe.process_window(t, &views, speed)
                .with_context(|| format!("{what}: window at t = {t:.3} s"))?,
        );
        start += hop;
    }
    Ok(out)
}
