//! One window -> one health message: the shared analysis stage (speed, data-quality checks,
//! envelope order spectrum features, velocity RMS), then the classifier and its fault-family
//! evidence, the one window verdict and the health state machine
//! ([`HealthStateMachine::observe`], what every offline score calls too), fault-band
//! amplitudes and the ISO 20816-3 velocity advisory.

use crate::analysis::{AnalysisStage, SpeedSource, WindowAnalysis, WindowError, WindowView};
use crate::bearing::FaultOrders;
use crate::config::RigConfig;
use crate::dsp::features::FeatureWindow;
use crate::dsp::quality::Quality;
use crate::health::verdict::{novelty_threshold, quality_problem, speed_only};
use crate::health::{HealthPolicy, HealthStateMachine, Smoothed, UnknownReason, WindowInput};
use crate::model::evidence::{BaselineSpread, FamilyBins, FamilyEvidence};
use crate::model::impulsiveness::{Impulse, ImpulseBaseline};
use crate::model::indicators::{IndicatorMeter, Indicators};
use crate::model::onnx::OnnxClassifier;
use crate::model::rule::{EnvelopeRule, RuleReading, RuleSettings};
use crate::vocabulary::{QualityFlag, SpeedSourceKind};
use crate::wire::health::{
    FaultBands, HealthIndicators, HealthMessage, ModelInfo, QualityReport, WindowTimes, SCHEMA,
    SCHEMA_VERSION,
};
use anyhow::{Context, Result};
use std::collections::BTreeMap;

/// A window's results.
pub struct WindowOutput {
    /// The features (None when the window could not be computed: no speed, failure).
    pub features: Option<FeatureWindow>,
    pub health: HealthMessage,
}

/// Everything that turns a window into a health message.
pub struct Analyzer {
    rig: RigConfig,
    stage: AnalysisStage,
    model: OnnxClassifier,
    model_id: String,
    /// How the model differs from this rig (a foreign model allowed on purpose), else empty.
    foreign: Vec<String>,
    health: HealthStateMachine,
    /// Rig acceleration channel names, in source order.
    names: Vec<String>,
    classifier: usize,
    fault_orders: FaultOrders,
    /// The fault-family bins of the rig's bearing, and the aligned model's baseline spread
    /// (None: the model gives no evidence).
    family_bins: FamilyBins,
    spread: Option<BaselineSpread>,
    /// The aligned model's healthy kurtosis (None: the model gives no impulsiveness).
    impulse_baseline: Option<ImpulseBaseline>,
    /// Measures each window's speed-free health indicators (classifier channel).
    meter: IndicatorMeter,
    /// The rule baseline at the rig's bearing (its reading is one input of the verdict).
    rule: EnvelopeRule,
    sample_rate: f64,
    start_time_ns: u64,
    seq: u64,
    /// Windows that failed in features or inference.
    pub errors: u64,
}

impl Analyzer {
    /// `absent` lists rig channels the source cannot deliver; `nominal_rpm` is the speed the
    /// source knows up front (for `speed.source = "recording"`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        rig: &RigConfig,
        sample_rate: f64,
        model: OnnxClassifier,
        model_id: &str,
        policy: HealthPolicy,
        absent: &[String],
        nominal_rpm: Option<f64>,
        start_time_ns: u64,
    ) -> Result<Self> {
        model
            .check_layout(rig)
            .with_context(|| format!("model {model_id}"))?;
        let mut health = HealthStateMachine::new(policy, &model.meta().labels)?;
        health.set_hop_fraction(rig.features.hop_s / rig.features.window_s);
        health.set_indicator_baseline(model.meta().alignment.as_ref().and_then(|a| a.indicators()));
        let chans: Vec<(String, String)> = rig
            .acceleration_channels()
            .map(|c| (c.name.clone(), c.unit.to_string()))
            .collect();
        let names: Vec<String> = chans.iter().map(|(n, _)| n.clone()).collect();
        let cls = rig
            .classifier_channel()
            .context("the rig file names no classifier channel")?;
        let classifier = names
            .iter()
            .position(|n| n == &cls.name)
            .context("classifier channel missing")?;
        if absent.iter().any(|a| a == &cls.name) {
            anyhow::bail!(
                "the source cannot deliver channel {:?}, which features.classifier_axis selects for the classifier; pick another channel or source",
                cls.name
            );
        }
        let speed = SpeedSource::new(&rig.speed, sample_rate, nominal_rpm)?;
        Ok(Analyzer {
            spread: model.meta().alignment.as_ref().and_then(|a| a.spread()),
            impulse_baseline: model.meta().alignment.as_ref().and_then(|a| a.impulse()),
            meter: IndicatorMeter::new(sample_rate, rig.features.lowpass_hz),
            stage: AnalysisStage::new(rig, sample_rate, &chans, absent, speed)?,
            foreign: foreign_to(&model, rig),
            model,
            model_id: model_id.to_string(),
            health,
            names,
            classifier,
            fault_orders: rig.bearing.fault_orders(),
            family_bins: FamilyBins::for_rig(rig),
            rule: EnvelopeRule::for_rig(rig, RuleSettings::default()),
            sample_rate,
            start_time_ns,
            seq: 0,
            errors: 0,
            rig: rig.clone(),
        })
    }

    pub fn model(&self) -> &OnnxClassifier {
        &self.model
    }

    pub fn model_id(&self) -> &str {
        &self.model_id
    }

    pub fn policy(&self) -> &HealthPolicy {
        self.health.policy()
    }

    pub fn state(&self) -> &str {
        self.health.state()
    }

    /// Swap the model and health policy (SIGHUP). The caller has already checked the model.
    pub fn swap(
        &mut self,
        model: OnnxClassifier,
        model_id: &str,
        policy: HealthPolicy,
    ) -> Result<()> {
        model.check_layout(&self.rig)?;
        self.health.reconfigure(policy, &model.meta().labels)?;
        self.foreign = foreign_to(&model, &self.rig);
        self.spread = model.meta().alignment.as_ref().and_then(|a| a.spread());
        self.impulse_baseline = model.meta().alignment.as_ref().and_then(|a| a.impulse());
        self.health
            .set_indicator_baseline(model.meta().alignment.as_ref().and_then(|a| a.indicators()));
        self.model = model;
        self.model_id = model_id.to_string();
        Ok(())
    }

    /// Analyse one window.
    pub fn analyze(&mut self, view: &WindowView) -> WindowOutput {
        self.seq += 1;
        let analysis = self.stage.analyze(view);
        let labels = self.model.meta().labels.clone();
        let mut c = self.classify(view, analysis);
        let features = c.features.take();
        let model_threshold = self.model.meta().novelty_threshold;
        let threshold = novelty_threshold(self.health.policy(), model_threshold);
        let indicators = self.meter.measure(view.channels[self.classifier]);
        let smoothed = self.health.observe_indicators(
            view.t_end,
            &WindowInput {
                labels: &labels,
                probs: &c.probs,
                novelty: c.novelty,
                model_novelty_threshold: model_threshold,
                quality: c.problem,
                beyond_baseline: c.beyond_baseline,
                evidence: c.evidence,
                impulse: c.impulse,
                rule: c.rule,
            },
            indicators.as_ref(),
        );
        let health = self.message(
            view,
            c,
            features.as_ref(),
            (labels, indicators),
            smoothed,
            threshold,
        );
        WindowOutput { features, health }
    }

    /// Quality checks, features and the classifier's probabilities for one window.
    fn classify(&mut self, view: &WindowView, analysis: WindowAnalysis) -> Classified {
        let mut c = Classified {
            features: None,
            quality: stream_quality(&analysis),
            problem: quality_problem(&analysis, &self.names[self.classifier]),
            probs: Vec::new(),
            novelty: f32::NAN,
            baseline_distance: None,
            beyond_baseline: None,
            evidence: None,
            impulse: self
                .impulse_baseline
                .zip(analysis.classifier_kurtosis)
                .map(|(b, (k, n))| b.impulse(k, n)),
            rule: analysis.fault_bands.as_ref().map(|b| self.rule.reading(b)),
            rpm: None,
            speed_source: analysis.speed_source,
            speed_confidence: analysis.speed_confidence,
            speed_rival_rpm: analysis.speed_rival_rpm,
            velocity: analysis.velocity_mm_s,
        };
        match analysis.features {
            Err(WindowError::NoSpeed(e)) => {
                c.quality.flag(QualityFlag::NoSpeed);
                tracing::debug!(
                    "window {:.1}-{:.1} s: no speed: {e:#}",
                    view.t_start,
                    view.t_end
                );
            }
            Err(WindowError::Features(e)) => {
                if analysis.tacho_lost {
                    c.quality.flag(QualityFlag::TachoLost);
                }
                self.errors += 1;
                c.quality.flag(QualityFlag::FeaturesFailed);
                tracing::warn!(
                    "window {:.1}-{:.1} s: features failed: {e:#}",
                    view.t_start,
                    view.t_end
                );
            }
            Ok(fw) => {
                if analysis.tacho_lost {
                    c.quality.flag(QualityFlag::TachoLost);
                }
                c.rpm = Some(fw.rpm).filter(|r| r.is_finite());
                c.speed_source = fw.speed_source;
                Self::dsp_quality(&fw.quality, &mut c.quality);
                // a window whose speed alone is in doubt is classified at the speed it was
                // analysed at: the verdict names a speed-free alarm by it, nothing more
                let finite = || {
                    fw.classifier_features(&self.rig)
                        .iter()
                        .all(|v| v.is_finite())
                };
                if c.problem.is_none() || c.problem.is_some_and(speed_only) && finite() {
                    self.infer(view, &fw, &mut c);
                }
                c.features = Some(fw);
            }
        }
        c
    }

    /// Flag the feature pipeline's quality findings (whether they forbid a verdict is
    /// [`quality_problem`]'s to say).
    fn dsp_quality(q: &Quality, quality: &mut QualityReport) {
        for (flag, list) in [
            (QualityFlag::Clipping, &q.clipped),
            (QualityFlag::Flat, &q.flat),
            (QualityFlag::Dropout, &q.dropout),
            (QualityFlag::Nan, &q.non_finite),
        ] {
            if !list.is_empty() {
                quality.flag(flag);
            }
        }
        if !q.dc_offset.is_empty() {
            // Advisory: the envelope features ignore DC.
            quality.flag(QualityFlag::DcOffset);
        }
        quality.flat_channels = q.flat.clone();
        quality.clipped_samples = q.clipped.len() as u32;
        quality.missing_tacho_pulses = q.missing_pulses;
        if q.missing_pulses > 0 {
            quality.flag(QualityFlag::MissingTachoPulses);
        }
        if q.speed_out_of_range {
            quality.flag(QualityFlag::SpeedOutOfRange);
        }
        if q.speed_uncertain {
            quality.flag(QualityFlag::SpeedUncertain);
        }
        if q.speed_ambiguous {
            // advisory: classified, the rival speed is in the message
            quality.flag(QualityFlag::SpeedAmbiguous);
        }
        quality.dsp = serde_json::to_value(q).unwrap_or_default();
    }

    /// Run the classifier on the window's features.
    fn infer(&mut self, view: &WindowView, fw: &FeatureWindow, c: &mut Classified) {
        match self.model.predict(fw.classifier_features(&self.rig)) {
            Ok(p) => {
                c.evidence = self
                    .spread
                    .zip(p.baseline_deviation.as_deref())
                    .map(|(spread, dev)| self.family_bins.evidence(dev, spread, fw.rpm));
                c.probs = p.probs;
                c.novelty = p.novelty;
                c.baseline_distance = p.baseline_distance;
                c.beyond_baseline = p.beyond_baseline;
            }
            Err(e) => {
                self.errors += 1;
                tracing::warn!(
                    "window {:.1}-{:.1} s: inference failed: {e:#}",
                    view.t_start,
                    view.t_end
                );
                c.problem = Some(QualityFlag::InferenceFailed);
            }
        }
    }

    /// The health message for one window: the classification, the smoothed state, the fault
    /// bands and the ISO 20816-3 velocity advisory.
    fn message(
        &self,
        view: &WindowView,
        c: Classified,
        features: Option<&FeatureWindow>,
        (labels, indicators): (Vec<String>, Option<Indicators>),
        smoothed: Smoothed,
        threshold: f32,
    ) -> HealthMessage {
        let fault_bands = features.map(|fw| self.fault_bands(fw)).unwrap_or_default();
        // None when the window has non-finite samples or the unit is not an acceleration.
        let velocity = c.velocity;
        let zone = velocity.and_then(|v| self.health.policy().iso20816.zone(v));
        let ns = |t: f64| self.start_time_ns.saturating_add((t * 1e9).round() as u64);
        HealthMessage {
            schema: SCHEMA.into(),
            schema_version: SCHEMA_VERSION,
            rig: self.rig.machine.id.clone(),
            asset: self.rig.machine.asset.clone(),
            point: self.rig.machine.point.clone(),
            site: self.rig.machine.site.clone(),
            seq: self.seq,
            window: WindowTimes {
                start_s: view.t_start,
                end_s: view.t_end,
                start_ns: ns(view.t_start),
                end_ns: ns(view.t_end),
            },
            publish_time_ns: now_ns(),
            rpm: c.rpm,
            speed_source: c.speed_source,
            speed_confidence: c.speed_confidence,
            speed_rival_rpm: c.speed_rival_rpm,
            quality: c.quality,
            probabilities: labels
                .iter()
                .cloned()
                .zip(c.probs.iter().copied())
                .collect::<BTreeMap<_, _>>(),
            window_state: smoothed.window_state,
            // a speed-free alarm has a class without probabilities (no speed, no classifier)
            unknown_reason: smoothed
                .window
                .unknown_reason
                .or((c.probs.is_empty() && smoothed.window.class.is_none())
                    .then_some(UnknownReason::BadQuality)),
            alarm_despite: smoothed.window.alarm_despite,
            decision: smoothed.window.basis,
            overruled: smoothed.window.overruled,
            evidence: smoothed.evidence,
            impulse: smoothed.impulse,
            indicators: indicators.map(|values| HealthIndicators {
                values,
                departure: smoothed.departure,
            }),
            state: smoothed.state,
            state_since_s: smoothed.since_s,
            state_changed: smoothed.changed,
            confidence: smoothed.confidence,
            novelty: if c.novelty.is_finite() {
                c.novelty
            } else {
                0.0
            },
            novelty_threshold: threshold,
            baseline_distance: c.baseline_distance,
            beyond_baseline: c.beyond_baseline,
            fault_bands,
            velocity_rms_mm_s: velocity,
            iso_zone: zone,
            model: ModelInfo {
                id: self.model_id.clone(),
                sha256: self.model.meta().sha256.clone(),
                labels,
                foreign: self.foreign.clone(),
            },
            calibration_id: self.calibration_id(),
            software_version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }

    /// The rig's calibration, else the model's (unless it has none).
    fn calibration_id(&self) -> Option<String> {
        let meta = self.model.meta();
        self.rig
            .calibration
            .as_ref()
            .map(|c| c.id.clone())
            .or_else(|| Some(meta.calibration_id.clone()).filter(|c| !c.is_empty() && c != "none"))
    }

    /// Bin RMS at harmonics 1..3 of BPFO, BPFI and 2xBSF in the classifier channel.
    fn fault_bands(&self, fw: &FeatureWindow) -> FaultBands {
        let name = &self.names[self.classifier];
        let Some(bins) = fw.features.get(name) else {
            return FaultBands::default();
        };
        let w = self.rig.features.bin_width_order;
        let at = |order: f64| -> f32 {
            let k = (order / w).ceil() as usize;
            if k == 0 {
                return f32::NAN;
            }
            bins.get(k - 1).copied().unwrap_or(f32::NAN)
        };
        let harmonics = |o: f64| -> Vec<f32> {
            (1..=3)
                .map(|h| at(o * h as f64))
                .filter(|x| x.is_finite())
                .collect()
        };
        let mut sorted: Vec<f32> = bins.iter().copied().filter(|x| x.is_finite()).collect();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let floor = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
        let fo = &self.fault_orders;
        FaultBands {
            channel: name.clone(),
            orders: [
                ("bpfo", fo.bpfo),
                ("bpfi", fo.bpfi),
                ("two_bsf", fo.two_bsf),
                ("ftf", fo.ftf),
            ]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
            bpfo: harmonics(fo.bpfo),
            bpfi: harmonics(fo.bpfi),
            two_bsf: harmonics(fo.two_bsf),
            floor,
        }
    }

    pub fn sample_rate(&self) -> f64 {
        self.sample_rate
    }
}

/// What the classifier made of one window.
struct Classified {
    features: Option<FeatureWindow>,
    quality: QualityReport,
    /// Why the classifier channel's data cannot be trusted (None: it can).
    problem: Option<QualityFlag>,
    probs: Vec<f32>,
    /// NaN when the classifier did not run.
    novelty: f32,
    /// Distance from the machine's healthy baseline and whether it is beyond it (aligned
    /// models only).
    baseline_distance: Option<f32>,
    beyond_baseline: Option<bool>,
    /// Fault-family evidence against the machine's healthy baseline (aligned models).
    evidence: Option<FamilyEvidence>,
    /// Impulsiveness against the machine's healthy baseline (aligned models; needs no speed).
    impulse: Option<Impulse>,
    /// The rule's band ratios (None without band ratios).
    rule: Option<RuleReading>,
    rpm: Option<f64>,
    speed_source: SpeedSourceKind,
    speed_confidence: Option<f64>,
    speed_rival_rpm: Option<f64>,
    /// Broadband velocity RMS of the classifier channel, mm/s.
    velocity: Option<f64>,
}

/// The stream's own quality findings: samples lost on the sample clock, non-finite samples.
fn stream_quality(analysis: &WindowAnalysis) -> QualityReport {
    let mut quality = QualityReport {
        ok: true,
        ..Default::default()
    };
    if analysis.lost_samples > 0 {
        quality.dropout_samples = analysis.lost_samples;
        quality.flag(QualityFlag::Dropout);
    }
    if analysis.nan_samples > 0 {
        quality.nan_samples += analysis.nan_samples;
        quality.flag(QualityFlag::Nan);
    }
    quality
}

/// How `model` differs from `rig` (empty when trained for it). Its identity was checked when
/// it was loaded: a difference here is a foreign model allowed on purpose.
fn foreign_to(model: &OnnxClassifier, rig: &RigConfig) -> Vec<String> {
    model
        .foreign_to(rig)
        .iter()
        .map(ToString::to_string)
        .collect()
}

/// Wall clock, ns since the Unix epoch.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}
