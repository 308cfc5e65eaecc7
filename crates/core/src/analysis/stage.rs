//! One window in, everything the model and health stages need out: the window's samples
//! checked (dropouts, NaN), its shaft speed from the [`SpeedSource`], the envelope order
//! spectrum features with their quality flags, the classifier channel's band ratios at the
//! bearing's fault orders (what the rule baseline judges), and the ISO 20816-3 velocity RMS of
//! the classifier channel. The daemon and whole recordings (`rigmon features`, training,
//! evaluation) both go through [`AnalysisStage::analyze`], so a model is served the features
//! it was trained on. Buffers are made once and reused.

use super::speed_source::SpeedSource;
use super::velocity::VelocityRms;
use super::windows::WindowView;
use crate::config::RigConfig;
use crate::dsp::fault_band_ratios::{FaultBandMeter, FaultBandRatios};
use crate::dsp::features::{FeaturePipeline, FeatureWindow};
use crate::vocabulary::{AccelUnit, SpeedSourceKind};
use anyhow::Result;

/// Why a window has no features.
#[derive(Debug)]
pub enum WindowError {
    /// No speed could be found for the window.
    NoSpeed(anyhow::Error),
    /// The feature pipeline refused the window.
    Features(anyhow::Error),
}

impl WindowError {
    /// The error with what went wrong at the front.
    pub fn into_error(self) -> anyhow::Error {
        match self {
            WindowError::NoSpeed(e) => e.context("no speed for the window"),
            WindowError::Features(e) => e,
        }
    }
}

impl std::fmt::Display for WindowError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WindowError::NoSpeed(e) => write!(f, "no speed: {e:#}"),
            WindowError::Features(e) => write!(f, "features failed: {e:#}"),
        }
    }
}

/// The analysis of one window.
#[derive(Debug)]
pub struct WindowAnalysis {
    pub t_start: f64,
    pub t_end: f64,
    /// Samples of the window lost on the sample clock (NaN-filled by the windower).
    pub lost_samples: u32,
    /// Other non-finite samples, over all delivered channels (set to 0 before analysis).
    pub nan_samples: u32,
    /// The classifier channel had lost or non-finite samples.
    pub classifier_nan: bool,
    /// Tacho pulses stopped (or had not started) inside the window: the speed is a guess.
    pub tacho_lost: bool,
    /// The speed source (known before a window has been computed).
    pub speed_source: SpeedSourceKind,
    /// How sure the vibration tracker is of the window's speed (0-1; None for speeds not
    /// read from the vibration).
    pub speed_confidence: Option<f64>,
    /// Half or twice the speed, when the vibration supports it nearly as well, rpm.
    pub speed_rival_rpm: Option<f64>,
    pub features: Result<FeatureWindow, WindowError>,
    /// The classifier channel's band ratios at the bearing's fault orders, from the envelope
    /// order spectrum its features were summed from (None without features).
    pub fault_bands: Option<FaultBandRatios>,
    /// Broadband velocity RMS of the classifier channel, mm/s (None for a unit that is not
    /// an acceleration or a window with non-finite samples).
    pub velocity_mm_s: Option<f64>,
    /// The classifier channel's excess kurtosis and the samples it was measured over: needs
    /// no speed, so a window without one has it too (None: lost, non-finite, flat, clipped or
    /// dropped-out samples).
    pub classifier_kurtosis: Option<(f32, usize)>,
}

/// Windows -> features, speed, quality and velocity, for one set of channels.
pub struct AnalysisStage {
    pipeline: FeaturePipeline,
    speed: SpeedSource,
    velocity: VelocityRms,
    names: Vec<String>,
    /// Each channel's acceleration unit (None: not an acceleration, no velocity).
    units: Vec<Option<AccelUnit>>,
    /// Channels the source cannot deliver (NaN in every block): skipped.
    absent: Vec<bool>,
    /// Index of the classifier channel in `names` (None when the source lacks it).
    classifier: Option<usize>,
    /// Sanitised copies of the window (NaN -> 0), one per channel.
    scratch: Vec<Vec<f32>>,
    /// Band ratios at the bearing's fault orders, measured on the classifier channel.
    fault_bands: FaultBandMeter,
    /// Pass non-finite samples to the pipeline, which then refuses the window (whole
    /// recordings: a NaN in a training file is an error to fix, not a flag).
    strict: bool,
    sample_rate: f64,
}

impl AnalysisStage {
    /// `channels` = (name, unit) of the channels in window order; `absent` lists those the
    /// source cannot deliver.
    pub fn new(
        rig: &RigConfig,
        sample_rate: f64,
        channels: &[(String, String)],
        absent: &[String],
        speed: SpeedSource,
    ) -> Result<Self> {
        let pipeline = FeaturePipeline::new(rig, sample_rate)?;
        let len = pipeline.window_len();
        let names: Vec<String> = channels.iter().map(|(n, _)| n.clone()).collect();
        let classifier = rig
            .classifier_channel()
            .and_then(|c| names.iter().position(|n| n == &c.name))
            .filter(|&k| !absent.contains(&names[k]));
        let o = rig.bearing.fault_orders();
        Ok(AnalysisStage {
            fault_bands: FaultBandMeter::new(o.bpfo, o.bpfi, o.two_bsf, rig.features.max_order),
            pipeline,
            speed: speed.with_fault_families(rig, sample_rate)?,
            velocity: VelocityRms::new(len, sample_rate),
            absent: names.iter().map(|n| absent.contains(n)).collect(),
            scratch: names.iter().map(|_| vec![0.0; len]).collect(),
            units: channels.iter().map(|(_, u)| AccelUnit::parse(u)).collect(),
            names,
            classifier,
            strict: false,
            sample_rate,
        })
    }

    /// Whole-recording mode: a window with non-finite samples is an error naming the sample.
    pub fn strict(mut self) -> Self {
        self.strict = true;
        self
    }

    /// Samples per window.
    pub fn window_len(&self) -> usize {
        self.pipeline.window_len()
    }

    /// The classifier channel's index in window order.
    pub fn classifier(&self) -> Option<usize> {
        self.classifier
    }

    /// Analyse one window.
    pub fn analyze(&mut self, view: &WindowView) -> WindowAnalysis {
        let mut nan_samples = 0;
        // Copy, count and zero non-finite samples (the feature pipeline refuses them).
        let mut classifier_nan = view.lost_samples > 0;
        for (k, (src, dst)) in view
            .channels
            .iter()
            .zip(self.scratch.iter_mut())
            .enumerate()
        {
            if self.absent[k] {
                continue;
            }
            let mut nan = 0u32;
            for (d, &s) in dst.iter_mut().zip(src.iter()) {
                *d = if s.is_finite() {
                    s
                } else {
                    nan += 1;
                    0.0
                };
            }
            // Lost samples are NaN-filled by the windower; count only the other ones.
            nan_samples += nan.saturating_sub(view.lost_samples);
            if nan > 0 && Some(k) == self.classifier {
                classifier_nan = true;
            }
        }
        // Speed from the classifier channel (the first delivered one without it).
        let signal = self
            .classifier
            .or_else(|| self.absent.iter().position(|a| !a))
            .map_or(&[][..], |k| self.scratch[k].as_slice());
        let mut tacho_lost = false;
        let (mut speed_confidence, mut speed_rival_rpm) = (None, None);
        let mut fault_bands = None;
        let features = match self.speed.track(view, signal) {
            Err(e) => Err(WindowError::NoSpeed(e)),
            Ok(speed) => {
                let track = &speed.track;
                (speed_confidence, speed_rival_rpm) = (speed.confidence, speed.rival_rpm);
                tacho_lost = self.speed.lost_pulses(track, view.t_start, view.t_end);
                let (names, absent, scratch) = (&self.names, &self.absent, &self.scratch);
                let chans: Vec<(&str, &[f32])> = (0..names.len())
                    .filter(|&k| !absent[k])
                    .map(|k| {
                        let x = if self.strict {
                            view.channels[k]
                        } else {
                            scratch[k].as_slice()
                        };
                        (names[k].as_str(), x)
                    })
                    .collect();
                let meter = &mut self.fault_bands;
                let mut measure =
                    |step: f64, lines: &[f32]| fault_bands = Some(meter.measure(step, lines));
                let probe = self.classifier.map(|k| {
                    (
                        names[k].as_str(),
                        &mut measure as &mut dyn FnMut(f64, &[f32]),
                    )
                });
                self.pipeline
                    .process_window_probed(view.t_start, &chans, track, probe)
                    .map(|mut fw| {
                        fw.quality.speed_uncertain = speed.uncertain;
                        fw.quality.speed_ambiguous = speed.rival_rpm.is_some();
                        fw.speed_confidence = speed.confidence.map(|c| c as f32);
                        fw
                    })
                    .map_err(WindowError::Features)
            }
        };
        WindowAnalysis {
            t_start: view.t_start,
            t_end: view.t_end,
            lost_samples: view.lost_samples,
            nan_samples,
            classifier_nan,
            tacho_lost,
            speed_source: self.speed.kind(),
            speed_confidence,
            speed_rival_rpm,
            fault_bands,
            velocity_mm_s: self
                .classifier
                .and_then(|k| self.velocity.mm_per_s(view.channels[k], self.units[k]?)),
            classifier_kurtosis: self.classifier_kurtosis(&features, classifier_nan),
            features,
        }
    }

    /// The classifier channel's excess kurtosis: the feature pipeline's when the window has
    /// features, else a scan of the sanitised samples (a window without a speed); None for
    /// lost, non-finite, flat, clipped or dropped-out samples.
    fn classifier_kurtosis(
        &self,
        features: &Result<FeatureWindow, WindowError>,
        classifier_nan: bool,
    ) -> Option<(f32, usize)> {
        let k = self.classifier?;
        let name = &self.names[k];
        match features {
            Ok(fw) => {
                let q = &fw.quality;
                let spoilt = [&q.clipped, &q.dropout].iter().any(|l| l.contains(name));
                let kurtosis = *fw.excess_kurtosis.get(name)?;
                (!spoilt).then_some((kurtosis, fw.samples))
            }
            Err(_) if classifier_nan => None,
            Err(_) => {
                let x = &self.scratch[k];
                let s = crate::dsp::quality::scan(x, self.sample_rate);
                let sound = s.non_finite.is_none() && !(s.flat || s.clipped || s.dropout);
                sound.then_some((s.excess_kurtosis, x.len()))
            }
        }
    }
}
