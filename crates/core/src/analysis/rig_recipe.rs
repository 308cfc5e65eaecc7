//! What a rig file asks of the DSP layer: the feature pipeline for its `[features]` and
//! `[speed]` sections, and its classifier channel's features. Defined here, above both
//! `config` and `dsp`, so that `dsp` never imports the rig file (and `config`, which embeds
//! the DSP sections, is not imported back).

use crate::config::RigConfig;
use crate::dsp::features::{FeaturePipeline, FeatureWindow};
use anyhow::Result;

impl FeaturePipeline {
    /// Plan the pipeline for the rig's feature settings at `sample_rate`.
    pub fn new(rig: &RigConfig, sample_rate: f64) -> Result<Self> {
        Self::with_settings(&rig.features, &rig.speed, sample_rate)
    }
}

impl FeatureWindow {
    /// The classifier channel's features (empty if this window lacks that channel).
    pub fn classifier_features(&self, rig: &RigConfig) -> &[f32] {
        rig.classifier_channel()
            .map_or(&[][..], |c| self.channel_features(&c.name))
    }

    /// The classifier channel's excess kurtosis and the samples it was measured over (None
    /// if this window lacks that channel, or it was flat, clipped or dropped out: a kurtosis
    /// that measures the sensor, not the machine).
    pub fn classifier_kurtosis(&self, rig: &RigConfig) -> Option<(f32, usize)> {
        let c = rig.classifier_channel()?;
        let q = &self.quality;
        let spoilt = [&q.clipped, &q.dropout].iter().any(|l| l.contains(&c.name));
        let k = *self.excess_kurtosis.get(&c.name)?;
        (!spoilt).then_some((k, self.samples))
    }
}
