//! A recording's health indicators window by window ([`super::indicators`]), streamed: the
//! windows the daemon would cut (a folder of captures: one or more per capture, never
//! straddling two), each with its classifier-channel indicators and plain RMS. `rigmon
//! trend` draws them; `rigmon align` / `adapt` fit the healthy indicator baseline on the
//! healthy recordings' windows.

use super::indicators::{IndicatorMeter, Indicators};
use crate::analysis::windows::Windower;
use crate::config::RigConfig;
use crate::importers::{self, ImportOptions};
use crate::recording::captures;
use anyhow::{Context, Result};
use std::path::Path;

/// One window of a recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndicatorWindow {
    /// Start and end, s since the recording's first sample.
    pub t_start: f64,
    pub t_end: f64,
    /// RMS of the classifier channel around zero (the RMS rule's value).
    pub rms: f64,
    /// The indicators (None: the window had non-finite samples or was flat).
    pub indicators: Option<Indicators>,
}

/// The windows of the recording at `path` whose span `keep(t_start, t_end)` accepts.
pub fn indicator_series(
    path: &Path,
    rig: &RigConfig,
    opts: &ImportOptions,
    keep: impl Fn(f64, f64) -> bool,
) -> Result<Vec<IndicatorWindow>> {
    let channel = rig
        .classifier_channel()
        .context("the rig file names no classifier channel (features.classifier_axis)")?
        .name
        .clone();
    let ch = rig
        .acceleration_channels()
        .position(|c| c.name == channel)
        .context("the classifier channel is not an acceleration channel")?;
    let mut stream = importers::open(path, rig, opts)?;
    let info = stream.info().clone();
    let mut w = Windower::for_rig(
        &rig.speed,
        &rig.features,
        info.sample_rate,
        info.channels.len(),
    )?;
    if captures::is_capture_series(&info.metadata) {
        w = w.capture_series();
    }
    let mut meter = IndicatorMeter::new(info.sample_rate, rig.features.lowpass_hz);
    let mut out = Vec::new();
    while let Some(b) = stream.next_block()? {
        w.push(&b);
        while let Some(v) = w.window() {
            if keep(v.t_start, v.t_end) {
                let x = v.channels[ch];
                let ms =
                    x.iter().map(|&s| f64::from(s) * f64::from(s)).sum::<f64>() / x.len() as f64;
                out.push(IndicatorWindow {
                    t_start: v.t_start,
                    t_end: v.t_end,
                    rms: ms.sqrt(),
                    indicators: meter.measure(x),
                });
            }
            drop(v);
            w.advance();
        }
    }
    Ok(out)
}
