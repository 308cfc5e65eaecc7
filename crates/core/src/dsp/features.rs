//! The feature pipeline (thesis section 4.2): per window and channel, low-pass + Hilbert
//! envelope, computed order tracking, order power spectrum, RMS per `bin_width_order` bin from
//! 0 to `max_order` (100 values per channel for the default recipe). Plans and buffers are
//! made once in [`FeaturePipeline::with_settings`]; a window allocates only its returned
//! [`FeatureWindow`].

use crate::dsp::envelope::Envelope;
use crate::dsp::feature_settings::FeatureSettings;
use crate::dsp::order_spectrum::OrderFft;
use crate::dsp::order_tracking::{GridInfo, OrderTracker};
use crate::dsp::quality::{scan, Quality};
use crate::dsp::speed::SpeedTrack;
use crate::dsp::speed_config::SpeedConfig;
use crate::vocabulary::SpeedSourceKind;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Features of one window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeatureWindow {
    /// Window start and end, s since the first sample of the recording/stream.
    pub t_start: f64,
    pub t_end: f64,
    /// Mean shaft speed over the window.
    pub rpm: f64,
    /// Where the speed came from.
    pub speed_source: SpeedSourceKind,
    /// How sure the vibration tracker is of the speed (0-1), for speeds read from the
    /// vibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_confidence: Option<f32>,
    pub quality: Quality,
    /// Channel name -> RMS per order bin (bin k covers (k*w, (k+1)*w] orders).
    pub features: BTreeMap<String, Vec<f32>>,
    /// Channel name -> excess kurtosis of the window's samples (0 for Gaussian noise; sparse
    /// impacts raise it): how impulsive the raw signal is, [`crate::dsp::quality::scan`].
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub excess_kurtosis: BTreeMap<String, f32>,
    /// Samples per channel in the window (what the kurtosis was measured over).
    #[serde(default)]
    pub samples: usize,
}

impl FeatureWindow {
    /// One channel's features (empty if this window lacks that channel). The rig's
    /// classifier channel: `classifier_features` (in `analysis::rig_recipe`).
    pub fn channel_features(&self, name: &str) -> &[f32] {
        self.features.get(name).map(Vec::as_slice).unwrap_or(&[])
    }
}

/// A channel's name and a callback handed its envelope order power lines (order step,
/// power per line): see [`FeaturePipeline::process_window_probed`].
pub type LineProbe<'a> = (&'a str, &'a mut dyn FnMut(f64, &[f32]));

/// Envelope-order-spectrum features for fixed-length windows at one sample rate.
pub struct FeaturePipeline {
    sample_rate: f64,
    len: usize,
    bin_width: f64,
    n_bins: usize,
    max_order: f64,
    lowpass_hz: f64,
    rpm_limits: Option<(f64, f64)>,
    envelope: Envelope,
    tracker: OrderTracker,
    fft: OrderFft,
    env: Vec<f32>,
    angle: Vec<f32>,
}

impl FeaturePipeline {
    /// Plan the pipeline for a feature recipe at `sample_rate`; `speed` bounds the speeds
    /// accepted when they are estimated. For a rig file: `FeaturePipeline::new` (in
    /// `analysis::rig_recipe`).
    pub fn with_settings(
        f: &FeatureSettings,
        speed: &SpeedConfig,
        sample_rate: f64,
    ) -> Result<Self> {
        // Bounded before anything is sized by it (window, hop, low-pass below Nyquist).
        f.check_at_rate(sample_rate)?;
        let len = f.window_samples(sample_rate)?;
        let rpm_limits = match *speed {
            SpeedConfig::Estimate {
                min_rpm, max_rpm, ..
            } => Some((min_rpm, max_rpm)),
            _ => None,
        };
        let tracker = OrderTracker::new(len, sample_rate, f.max_order);
        let max_count = 4 * len;
        Ok(FeaturePipeline {
            sample_rate,
            len,
            bin_width: f.bin_width_order,
            n_bins: f.n_bins(),
            max_order: f.max_order,
            lowpass_hz: f.lowpass_hz,
            rpm_limits,
            envelope: Envelope::new(len, sample_rate, f.lowpass_hz),
            tracker,
            fft: OrderFft::new(2),
            env: vec![0.0; len],
            angle: Vec::with_capacity(max_count),
        })
    }

    /// Samples per window (window_s x sample rate).
    pub fn window_len(&self) -> usize {
        self.len
    }

    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }

    /// Features of the window starting at `t_start` (s, same clock as `speed`). Every channel
    /// slice must hold exactly [`window_len`](Self::window_len) samples. NaN/Inf samples are
    /// an error naming the channel and sample; other problems become quality flags.
    pub fn process_window(
        &mut self,
        t_start: f64,
        channels: &[(&str, &[f32])],
        speed: &SpeedTrack,
    ) -> Result<FeatureWindow> {
        self.process_window_probed(t_start, channels, speed, None)
    }

    /// As [`process_window`](Self::process_window), and `probe` (channel name, callback) is
    /// handed that channel's envelope order power lines (order step, power) before they are
    /// summed into bins: a measurement on the very spectrum the features come from, without
    /// computing it twice.
    pub fn process_window_probed(
        &mut self,
        t_start: f64,
        channels: &[(&str, &[f32])],
        speed: &SpeedTrack,
        mut probe: Option<LineProbe>,
    ) -> Result<FeatureWindow> {
        let t_end = t_start + self.len as f64 / self.sample_rate;
        let mut quality = Quality::default();
        let mut excess_kurtosis = BTreeMap::new();
        for (name, x) in channels {
            if x.len() != self.len {
                bail!(
                    "channel {name:?}: the window at t = {t_start:.3} s has {} samples, the pipeline expects {} (features.window_s x {} Hz)",
                    x.len(),
                    self.len,
                    self.sample_rate
                );
            }
            let s = scan(x, self.sample_rate);
            if let Some(i) = s.non_finite {
                bail!(
                    "channel {name:?}: sample {i} of the window at t = {t_start:.3} s (t = {:.4} s) is {}; features cannot be computed from NaN/Inf — repair or drop the input",
                    t_start + i as f64 / self.sample_rate,
                    x[i]
                );
            }
            if s.flat {
                quality.flat.push(name.to_string());
            } else {
                excess_kurtosis.insert(name.to_string(), s.excess_kurtosis);
                if s.clipped {
                    quality.clipped.push(name.to_string());
                }
                if s.dropout {
                    quality.dropout.push(name.to_string());
                }
                if s.dc_offset {
                    quality.dc_offset.push(name.to_string());
                }
            }
        }
        let info = self.tracker.prepare(t_start, speed)?;
        let (ins, rem) = speed.repairs_between(t_start, t_end);
        quality.missing_pulses = ins;
        quality.extra_pulses = rem;
        quality.speed_extrapolated = speed.extrapolates(t_start, t_end);
        let rpm = speed.mean_rpm(t_start, t_end);
        let top_hz = (self.lowpass_hz).min(self.sample_rate / 2.0);
        quality.speed_out_of_range = info.revolutions < 1.0 / self.bin_width
            || self.max_order * info.f_max > top_hz
            || self.rpm_limits.is_some_and(|(lo, hi)| rpm < lo || rpm > hi);
        quality.set_resolution(info.revolutions);
        let count = info.count;
        if self.angle.len() < count {
            self.angle.resize(count + count / 4, 0.0);
        }
        let (n_bins, bin_width) = (self.n_bins, self.bin_width);
        let mut features = BTreeMap::new();
        for (name, x) in channels {
            let mut out = vec![0.0f32; n_bins];
            let (step, lines) = self.channel_power(x, count);
            if let Some((_, f)) = probe.as_mut().filter(|(p, _)| p == name) {
                f(step, lines);
            }
            band_rms(lines, step, bin_width, &mut out);
            features.insert(name.to_string(), out);
        }
        Ok(FeatureWindow {
            t_start,
            t_end,
            rpm,
            speed_source: speed.source(),
            speed_confidence: None,
            quality,
            features,
            excess_kurtosis,
            samples: self.len,
        })
    }

    /// The envelope order power spectrum of one channel over the window starting at
    /// `t_start`: the lines the RMS bins of [`process_window`](Self::process_window) are
    /// summed from (order step between lines, one-sided power per line). Also returns the
    /// revolutions in the window (the spectrum's resolution is 1 / revolutions orders).
    pub fn envelope_order_power(
        &mut self,
        t_start: f64,
        x: &[f32],
        speed: &SpeedTrack,
    ) -> Result<(f64, f64, &[f32])> {
        let info = self.prepare_window(t_start, x, speed)?;
        let (step, lines) = self.channel_power(x, info.count);
        Ok((step, info.revolutions, lines))
    }

    /// As [`envelope_order_power`](Self::envelope_order_power), with the envelope taken over
    /// `lo_hz..hi_hz` (an ideal band-pass, e.g. the band a kurtogram chose) instead of the
    /// recipe's low-pass; the pipeline keeps its low-pass for everything else. Band selection
    /// studies and `inspect --kurtogram`; the features never use it.
    pub fn envelope_order_power_band(
        &mut self,
        t_start: f64,
        x: &[f32],
        speed: &SpeedTrack,
        lo_hz: f64,
        hi_hz: f64,
    ) -> Result<(f64, f64, &[f32])> {
        let nyquist = self.sample_rate / 2.0;
        if !(lo_hz >= 0.0 && lo_hz < hi_hz && hi_hz <= nyquist) {
            bail!(
                "envelope band {lo_hz}-{hi_hz} Hz: must satisfy 0 <= low < high <= {nyquist} Hz (Nyquist at {} Hz)",
                self.sample_rate
            );
        }
        let info = self.prepare_window(t_start, x, speed)?;
        self.envelope.set_band(lo_hz, hi_hz);
        self.envelope.process(x, &mut self.env);
        self.envelope.set_band(0.0, self.lowpass_hz);
        let count = info.count;
        let spr = self.tracker.samples_per_rev();
        self.tracker.resample(&self.env, &mut self.angle[..count]);
        let (step, lines) = self.fft.power(&self.angle[..count], spr);
        Ok((step, info.revolutions, lines))
    }

    /// Check the window's length and prepare order tracking for it (angle buffer grown once,
    /// by a quarter more than needed, so later windows do not allocate).
    fn prepare_window(&mut self, t_start: f64, x: &[f32], speed: &SpeedTrack) -> Result<GridInfo> {
        if x.len() != self.len {
            bail!(
                "the window at t = {t_start:.3} s has {} samples, the pipeline expects {}",
                x.len(),
                self.len
            );
        }
        let info = self.tracker.prepare(t_start, speed)?;
        if self.angle.len() < info.count {
            self.angle.resize(info.count + info.count / 4, 0.0);
        }
        Ok(info)
    }

    /// Envelope, order tracking (prepared for `count` angle samples) and power spectrum.
    fn channel_power(&mut self, x: &[f32], count: usize) -> (f64, &[f32]) {
        let spr = self.tracker.samples_per_rev();
        self.envelope.process(x, &mut self.env);
        self.tracker.resample(&self.env, &mut self.angle[..count]);
        self.fft.power(&self.angle[..count], spr)
    }
}

/// Sum power lines into bins (k*w, (k+1)*w] and take the square root (band RMS).
pub fn band_rms(lines: &[f32], order_step: f64, bin_width: f64, out: &mut [f32]) {
    let per = bin_width / order_step;
    for (k, o) in out.iter_mut().enumerate() {
        let first = ((k as f64 * per + 1e-9).floor() as usize) + 1;
        let last = (((k + 1) as f64 * per + 1e-9).floor() as usize).min(lines.len() - 1);
        let s: f32 = if first <= last {
            lines[first..=last].iter().sum()
        } else {
            0.0
        };
        *o = s.sqrt();
    }
}
