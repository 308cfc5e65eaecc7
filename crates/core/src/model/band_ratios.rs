//! Band selection measured with the rule's statistic (issue 18). For every feature window of
//! a recording channel (`window_s` long, `hop_s` apart from the first sample: the analysis
//! stage's windows of a recording without gaps) the envelope order spectrum is taken with the
//! envelope band chosen one of three ways ([`BandChoice`]): the recipe's fixed low-pass
//! (`[features] lowpass_hz`, what the features and the rule use), one band for the whole
//! recording (the best band of its fast kurtogram), or the best band of each window's own
//! kurtogram. Per fault family the window gets the rule's ratio
//! ([`crate::dsp::fault_band_ratios::FaultBandMeter::ratios_at`], what the analysis stage
//! measures): the larger of the bands at the family's order and at twice it, over the median
//! band. Families: BPFO, BPFI and 2xBSF (a ball defect strikes both races once per ball spin).
//! A recording is summarised per family by the mean ratio over its windows and the share of
//! windows at or above the rule's threshold. `rigmon inspect --json` prints it; the features
//! and the classifier do not use it.

use crate::config::RigConfig;
use crate::dsp::kurtogram::{Kurtogram, KurtogramBand, KurtogramSettings};
use crate::dsp::{FeaturePipeline, SpeedTrack};
use crate::model::rule::EnvelopeRule;
use anyhow::{bail, Context, Result};
use serde::Serialize;

/// How the envelope band of a window is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BandChoice {
    /// The recipe's low-pass, `[features] lowpass_hz`.
    LowPass,
    /// One band for every window (the whole recording's best kurtogram band).
    Fixed(KurtogramBand),
    /// The best band of each window's own kurtogram.
    PerWindow(KurtogramSettings),
}

impl BandChoice {
    /// Name in reports: `lowpass`, `kurtogram_record`, `kurtogram_window`.
    pub fn name(&self) -> &'static str {
        match self {
            BandChoice::LowPass => "lowpass",
            BandChoice::Fixed(_) => "kurtogram_record",
            BandChoice::PerWindow(_) => "kurtogram_window",
        }
    }
}

/// The rule's ratio per fault family: max(band at the order, band at twice it) / median band.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FamilyRatios {
    pub bpfo: f64,
    pub bpfi: f64,
    pub two_bsf: f64,
}

/// One window: its envelope band and its ratios.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WindowRatios {
    /// Window start, s since the first sample.
    pub t_start: f64,
    /// Mean shaft speed over the window, rpm.
    pub rpm: f64,
    /// Envelope band, Hz.
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// The band's kurtogram level and kurtosis (none for the low-pass).
    pub level: Option<f64>,
    pub kurtosis: Option<f64>,
    pub ratios: FamilyRatios,
}

/// One family over a recording's windows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FamilySummary {
    /// Mean ratio over the windows.
    pub mean: f64,
    /// Share of windows whose ratio is at or above the rule's threshold.
    pub share_at_threshold: f64,
}

/// A recording channel under one band choice.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BandRatios {
    /// [`BandChoice::name`].
    pub choice: &'static str,
    pub bpfo: FamilySummary,
    pub bpfi: FamilySummary,
    pub two_bsf: FamilySummary,
    pub windows: Vec<WindowRatios>,
}

/// The rule's ratios on every full feature window of `samples` (one channel at
/// `sample_rate`), the envelope band chosen by `choice`.
pub fn band_ratios(
    samples: &[f32],
    sample_rate: f64,
    rig: &RigConfig,
    speed: &SpeedTrack,
    choice: BandChoice,
    rule: &EnvelopeRule,
) -> Result<BandRatios> {
    let mut pipe = FeaturePipeline::new(rig, sample_rate)?;
    let n = pipe.window_len();
    let hop = ((rig.features.hop_s * sample_rate).round() as usize).max(1);
    if samples.len() < n {
        bail!(
            "{:.3} s of signal is shorter than one window ({} s)",
            samples.len() as f64 / sample_rate,
            rig.features.window_s
        );
    }
    let mut per_window = match choice {
        BandChoice::PerWindow(settings) => Some(
            Kurtogram::new(n, sample_rate, settings)
                .context("the kurtogram of each feature window")?,
        ),
        _ => None,
    };
    let o = rig.bearing.fault_orders();
    let centres = [
        o.bpfo,
        2.0 * o.bpfo,
        o.bpfi,
        2.0 * o.bpfi,
        o.two_bsf,
        2.0 * o.two_bsf,
    ];
    let mut r = [0.0; 6];
    let mut meter = rule.meter();
    let mut windows = Vec::with_capacity((samples.len() - n) / hop + 1);
    let mut start = 0;
    while start + n <= samples.len() {
        let t = start as f64 / sample_rate;
        let x = &samples[start..start + n];
        let at = || format!("window at t = {t:.3} s");
        let (band, (step, _, lines)) = match (&choice, per_window.as_mut()) {
            (BandChoice::LowPass, _) => (
                None,
                pipe.envelope_order_power(t, x, speed).with_context(at)?,
            ),
            (BandChoice::Fixed(b), _) => (
                Some(*b),
                pipe.envelope_order_power_band(t, x, speed, b.lo_hz, b.hi_hz)
                    .with_context(at)?,
            ),
            (BandChoice::PerWindow(_), Some(k)) => {
                k.compute(x).with_context(at)?;
                let b = k.best();
                (
                    Some(b),
                    pipe.envelope_order_power_band(t, x, speed, b.lo_hz, b.hi_hz)
                        .with_context(at)?,
                )
            }
            (BandChoice::PerWindow(_), None) => unreachable!("planned above"),
        };
        meter.ratios_at(step, lines, &centres, &mut r);
        windows.push(WindowRatios {
            t_start: t,
            rpm: speed.mean_rpm(t, t + n as f64 / sample_rate),
            lo_hz: band.map_or(0.0, |b| b.lo_hz),
            hi_hz: band.map_or(rig.features.lowpass_hz.min(sample_rate / 2.0), |b| b.hi_hz),
            level: band.map(|b| b.level),
            kurtosis: band.map(|b| b.kurtosis),
            ratios: FamilyRatios {
                bpfo: r[0].max(r[1]),
                bpfi: r[2].max(r[3]),
                two_bsf: r[4].max(r[5]),
            },
        });
        start += hop;
    }
    let summary = |f: fn(&FamilyRatios) -> f64| {
        let k = windows.len() as f64;
        FamilySummary {
            mean: windows.iter().map(|w| f(&w.ratios)).sum::<f64>() / k,
            share_at_threshold: windows
                .iter()
                .filter(|w| f(&w.ratios) >= rule.threshold())
                .count() as f64
                / k,
        }
    };
    Ok(BandRatios {
        choice: choice.name(),
        bpfo: summary(|r| r.bpfo),
        bpfi: summary(|r| r.bpfi),
        two_bsf: summary(|r| r.two_bsf),
        windows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::kurtogram;
    use crate::dsp::synthetic::Synthetic;
    use crate::model::rule::RuleSettings;
    use crate::recording::{Channel, Provenance, Recording};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const FS: f64 = 12_000.0;

    fn rig() -> RigConfig {
        let text = std::fs::read_to_string(
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("config/cwru-de.toml"),
        )
        .unwrap();
        RigConfig::parse(&text).unwrap()
    }

    /// 6 s at 1800 rpm: impacts at BPFO ringing 3 kHz (peak 1), masked by Gaussian noise
    /// band-limited to 0-1400 Hz (sd `mask`; its envelope spreads over orders 0-47) and white
    /// noise (sd 0.05).
    fn masked_bpfo(mask: f64) -> Vec<f32> {
        let bpfo = rig().bearing.fault_orders().bpfo;
        let imp = Synthetic {
            sample_rate: FS,
            seconds: 6.0,
            f_start: 30.0,
            f_end: 30.0,
            fault_order: bpfo,
            resonance_hz: 3000.0,
            damping: 0.05,
            noise: 0.0,
            seed: 1,
            ..Synthetic::default()
        }
        .generate()
        .vibration;
        let n = imp.len();
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let d = Normal::new(0.0, 1.0).unwrap();
        let mut planner = realfft::RealFftPlanner::<f64>::new();
        let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
        let mut raw: Vec<f64> = (0..n).map(|_| d.sample(&mut rng)).collect();
        let mut spec = fwd.make_output_vec();
        fwd.process(&mut raw, &mut spec).unwrap();
        let top = (1400.0 / FS * n as f64) as usize;
        spec.iter_mut()
            .skip(top + 1)
            .for_each(|c| *c = Default::default());
        spec[0] = Default::default();
        inv.process(&mut spec, &mut raw).unwrap();
        let sd = (raw.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        imp.iter()
            .zip(&raw)
            .map(|(&i, &m)| (i as f64 + mask * m / sd + 0.05 * d.sample(&mut rng)) as f32)
            .collect()
    }

    fn recording(x: Vec<f32>) -> Recording {
        let ch = |name: &str, samples: Vec<f32>| Channel {
            name: name.into(),
            axis: "radial".into(),
            unit: "g".into(),
            samples,
        };
        let n = x.len();
        Recording {
            sample_rate: FS,
            start_time_ns: 0,
            channels: vec![ch("DE", x), ch("FE", vec![0.0; n]), ch("BA", vec![0.0; n])],
            tacho: None,
            rpm: Some(1800.0),
            nominal_rpm: None,
            provenance: Provenance {
                source_path: "synthetic".into(),
                format: "simulated".into(),
                notes: vec![],
            },
            metadata: Default::default(),
        }
    }

    #[test]
    fn the_low_pass_choice_is_the_rules_own_statistic() {
        let rig = rig();
        let rec = recording(masked_bpfo(0.5));
        let rule = EnvelopeRule::for_rig(&rig, RuleSettings::default());
        let verdicts = rule.judge_recording(&rec, &rig).unwrap();
        let speed = crate::analysis::whole_recording(&rec, &rig).unwrap();
        let x = &rec.channels[0].samples;
        let got = band_ratios(x, FS, &rig, &speed, BandChoice::LowPass, &rule).unwrap();
        assert_eq!(got.windows.len(), verdicts.len());
        for (w, v) in got.windows.iter().zip(&verdicts) {
            assert_eq!(w.t_start, v.t_start);
            assert_eq!(w.ratios.bpfo, v.ratios[0].max(v.ratios[1]));
            assert_eq!(w.ratios.bpfi, v.ratios[2].max(v.ratios[3]));
            assert_eq!((w.lo_hz, w.hi_hz, w.level), (0.0, 4000.0, None));
        }
        let k = got.windows.len() as f64;
        let mean = got.windows.iter().map(|w| w.ratios.bpfo).sum::<f64>() / k;
        assert!((got.bpfo.mean - mean).abs() < 1e-12);
    }

    #[test]
    fn a_kurtogram_band_lifts_impacts_a_low_frequency_mask_hides() {
        let rig = rig();
        let x = masked_bpfo(3.0);
        let speed = SpeedTrack::fixed(1800.0).unwrap();
        let rule = EnvelopeRule::for_rig(&rig, RuleSettings::default());
        let lp = band_ratios(&x, FS, &rig, &speed, BandChoice::LowPass, &rule).unwrap();
        let settings = KurtogramSettings {
            levels: 2,
            max_hz: None,
        };
        let win =
            band_ratios(&x, FS, &rig, &speed, BandChoice::PerWindow(settings), &rule).unwrap();
        let best = kurtogram::of_recording(&x, FS, settings).unwrap().best();
        let rec = band_ratios(&x, FS, &rig, &speed, BandChoice::Fixed(best), &rule).unwrap();
        assert!(lp.bpfo.share_at_threshold < 0.5, "{:?}", lp.bpfo);
        for got in [&win, &rec] {
            assert_eq!(
                got.bpfo.share_at_threshold, 1.0,
                "{}: {:?}",
                got.choice, got.bpfo
            );
            assert!(
                got.bpfo.mean > 2.0 * lp.bpfo.mean,
                "{}: {:?}",
                got.choice,
                got.bpfo
            );
            for w in &got.windows {
                // the band leaves the mask out (the impacts ring from 3 kHz up)
                assert!(w.lo_hz >= 1400.0, "{w:?}");
                assert!(w.level.is_some() && w.kurtosis.is_some(), "{w:?}");
            }
        }
        assert_eq!(win.choice, "kurtogram_window");
        assert_eq!(rec.choice, "kurtogram_record");
    }
}
