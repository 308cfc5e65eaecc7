//! The rule baseline (issue 18): a ten-line envelope-order rule with no training, scored next
//! to every classifier. It judges the analysis stage's windows (the windows, speed and
//! envelope order spectrum the model is given: [`WindowAnalysis::fault_bands`], measured on
//! the lines the classifier channel's feature bins are summed from) and compares the RMS of
//! the band centred at BPFO, 2xBPFO, BPFI and 2xBPFI with the median RMS of all bands of the
//! same width (0.5 order, the thesis' bin width) from 0 to `features.max_order`
//! ([`FaultBandMeter`]). A window is faulty when
//! one of those bands stands [`RuleSettings::threshold`] (3x) or more above that median; it
//! is `outer_race` or `inner_race` by whichever race's band stands highest relative to the
//! median (an exact tie goes to `outer_race`). The rule has no ball class: a ball fault it
//! sees is called a race fault (an alarm, not a miss; unseen, it is a miss). A recording
//! takes the majority of its windows through the same scoring code as the ONNX classifier.
//! The rule is scored as an independent baseline; the daemon's verdict reads it in one place
//! only ([`RuleReading`], `crate::health::verdict` step 2): where the rule names one race, sees
//! nothing of the race (or health) the network named, and the fault-family evidence against
//! the machine's healthy baseline supports the rule's race at least as strongly, the rule's
//! race wins (issue 34: the model never below the rule).

use crate::analysis::WindowAnalysis;
use crate::bearing::FaultOrders;
use crate::config::RigConfig;
use crate::dsp::fault_band_ratios::{FaultBandMeter, FaultBandRatios, BAND_WIDTH_ORDER};
use crate::recording::Recording;
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use serde::Serialize;

/// Classes the rule can name, in this order.
pub const RULE_LABELS: [&str; 3] = [
    Condition::Healthy.as_str(),
    Condition::OuterRace.as_str(),
    Condition::InnerRace.as_str(),
];

/// The rule's two numbers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RuleSettings {
    /// A fault band counts when its RMS is at least this many times the median band RMS of
    /// the envelope order spectrum.
    pub threshold: f64,
    /// Width of every band, orders: the analysis stage's [`BAND_WIDTH_ORDER`] (0.5), reported
    /// with the rule's figures. A fault band is centred on its kinematic order, so +-0.25
    /// order covers slip and speed error (+-7 % at BPFO 3.58, +-2.3 % at 2xBPFI 10.8); the
    /// median is over the bands (k w, (k+1) w] tiling 0..max_order.
    pub band_width_order: f64,
}

impl Default for RuleSettings {
    fn default() -> Self {
        RuleSettings {
            threshold: 3.0,
            band_width_order: BAND_WIDTH_ORDER,
        }
    }
}

/// The rule's verdict on one window.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RuleVerdict {
    /// Index into [`RULE_LABELS`].
    pub class: usize,
    /// Band RMS / median band RMS at BPFO, 2xBPFO, BPFI, 2xBPFI.
    pub ratios: [f64; 4],
    /// Mean shaft speed of the window, rpm.
    pub rpm: f64,
    /// Window start, s since the first sample (0 for a lone spectrum).
    pub t_start: f64,
}

impl RuleVerdict {
    pub fn label(&self) -> &'static str {
        RULE_LABELS[self.class]
    }
}

/// What the rule reads in one window, for the verdict: the race families' band ratios (the
/// larger of the fundamental's and the second harmonic's: what the rule calls by), the
/// fundamentals' alone (what it sees a race by) and the threshold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RuleReading {
    pub outer_race: f64,
    pub inner_race: f64,
    pub bpfo: f64,
    pub bpfi: f64,
    pub threshold: f64,
}

impl RuleReading {
    /// The race the rule calls (None: healthy, or no finite ratio); an exact tie goes to the
    /// outer race, as [`EnvelopeRule::judge_bands`] decides.
    pub fn calls(&self) -> Option<&'static str> {
        let (o, i) = (self.outer_race, self.inner_race);
        if !(o.max(i) >= self.threshold) {
            return None;
        }
        Some(if o >= i {
            Condition::OuterRace.as_str()
        } else {
            Condition::InnerRace.as_str()
        })
    }

    /// Whether the rule sees any sign of the class `label`: a race whose *fundamental* band
    /// stands at the threshold (a second harmonic is no sign of its race: on the common
    /// geometries, d/D near 0.2, BPFI is about 1.5 BPFO, so 3xBPFO falls in the 2xBPFI band and
    /// an inner race's BPFI - 2x sideband in the BPFO band's neighbour), `healthy` when it
    /// calls no race. Classes the rule cannot see (ball, a dataset's own labels) count as
    /// seen: the rule says nothing against them.
    pub fn sees(&self, label: &str) -> bool {
        match Condition::parse(label) {
            Some(Condition::OuterRace) => self.bpfo >= self.threshold,
            Some(Condition::InnerRace) => self.bpfi >= self.threshold,
            Some(Condition::Healthy) => self.calls().is_none(),
            Some(Condition::Ball) | None => true,
        }
    }
}

/// The rule for one bearing.
#[derive(Debug, Clone)]
pub struct EnvelopeRule {
    orders: FaultOrders,
    settings: RuleSettings,
    /// Highest order of the spectrum the median is taken over.
    max_order: f64,
}

impl EnvelopeRule {
    /// The rule at the rig file's bearing geometry.
    pub fn for_rig(rig: &RigConfig, settings: RuleSettings) -> Self {
        EnvelopeRule {
            orders: rig.bearing.fault_orders(),
            settings,
            max_order: rig.features.max_order,
        }
    }

    /// The rule at given fault orders, the median taken up to `max_order`.
    pub fn new(orders: FaultOrders, settings: RuleSettings, max_order: f64) -> Self {
        EnvelopeRule {
            orders,
            settings,
            max_order,
        }
    }

    /// A meter for this rule's bearing (what the analysis stage measures every window with).
    pub fn meter(&self) -> FaultBandMeter {
        let o = &self.orders;
        FaultBandMeter::new(o.bpfo, o.bpfi, o.two_bsf, self.max_order)
    }

    /// Judge one envelope order spectrum given as power lines `order_step` apart (line 0 at
    /// order 0).
    pub fn judge(&self, order_step: f64, power: &[f32]) -> RuleVerdict {
        self.judge_bands(&self.meter().measure(order_step, power))
    }

    /// Judge one window's band ratios at the fault orders (the analysis stage's
    /// [`WindowAnalysis::fault_bands`]).
    pub fn judge_bands(&self, bands: &FaultBandRatios) -> RuleVerdict {
        let ratios = [bands.0[0], bands.0[1], bands.0[2], bands.0[3]];
        let outer = bands.outer_race();
        let inner = bands.inner_race();
        let class = if outer.max(inner) < self.settings.threshold {
            0
        } else if outer >= inner {
            1
        } else {
            2
        };
        RuleVerdict {
            class,
            ratios,
            rpm: 0.0,
            t_start: 0.0,
        }
    }

    /// What the rule reads in one window's band ratios ([`RuleReading`]).
    pub fn reading(&self, bands: &FaultBandRatios) -> RuleReading {
        RuleReading {
            outer_race: bands.outer_race(),
            inner_race: bands.inner_race(),
            bpfo: bands.0[0],
            bpfi: bands.0[2],
            threshold: self.settings.threshold,
        }
    }

    /// The rule's threshold (a band this many times the median is a fault).
    pub fn threshold(&self) -> f64 {
        self.settings.threshold
    }

    /// The rule on the analysis stage's windows of a recording (as the daemon and the
    /// scores cut them); windows without band ratios (no speed, failed features) are left
    /// out. `t_start` and `rpm` are the window's.
    pub fn judge_recording(&self, rec: &Recording, rig: &RigConfig) -> Result<Vec<RuleVerdict>> {
        let what = &rec.provenance.source_path;
        let ch = rig
            .classifier_channel()
            .context("the rig file has no classifier channel (features.classifier_axis)")?;
        if rec.channel(&ch.name).is_none() {
            bail!(
                "{what}: no channel {:?} (the rig's classifier channel) in the recording",
                ch.name
            );
        }
        let windows = crate::analysis::analyze_recording(rec, rig)?;
        Ok(windows
            .iter()
            .filter_map(|w| self.judge_window(w))
            .collect())
    }

    /// The rule on one analysed window (None without band ratios).
    pub fn judge_window(&self, w: &WindowAnalysis) -> Option<RuleVerdict> {
        let bands = w.fault_bands.as_ref()?;
        let mut v = self.judge_bands(bands);
        v.t_start = w.t_start;
        v.rpm = w.features.as_ref().map_or(f64::NAN, |f| f.rpm);
        Some(v)
    }
}

/// Map the rule's classes onto a classifier's label list (so both are scored alike).
pub fn class_map(labels: &[String]) -> Result<[usize; 3]> {
    let mut map = [0; 3];
    for (m, name) in map.iter_mut().zip(RULE_LABELS) {
        *m = labels.iter().position(|l| l == name).with_context(|| {
            format!("the rule names {name:?}, which is not among the scored classes {labels:?}")
        })?;
    }
    Ok(map)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::synthetic::Synthetic;
    use crate::dsp::FeaturePipeline;

    fn orders() -> FaultOrders {
        crate::bearing::BearingGeometry {
            balls: 9,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 39.04,
            contact_angle_deg: 0.0,
        }
        .fault_orders()
    }

    fn rig() -> RigConfig {
        let text = std::fs::read_to_string(
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
                .join("config/cwru-de.toml"),
        )
        .unwrap();
        RigConfig::parse(&text).unwrap()
    }

    /// Windows of a synthetic impact train at `order` (none when 0), `scale` times the
    /// generator's impacts, under white noise of standard deviation `noise`; 1800 rpm, 12 kHz.
    fn verdicts(order: f64, scale: f32, noise: f64) -> Vec<RuleVerdict> {
        let syn = |fault_order: f64, noise: f64| {
            Synthetic {
                sample_rate: 12_000.0,
                seconds: 4.0,
                f_start: 30.0,
                f_end: 30.0,
                fault_order,
                resonance_hz: 3000.0,
                damping: 0.05,
                noise,
                seed: 3,
                ..Synthetic::default()
            }
            .generate()
            .vibration
        };
        // an order of 1e-3 puts the first impact beyond the 120 revolutions: noise only
        let floor = syn(1e-3, noise);
        let x: Vec<f32> = if order > 0.0 {
            syn(order, 0.0)
                .iter()
                .zip(&floor)
                .map(|(i, n)| scale * i + n)
                .collect()
        } else {
            floor
        };
        let rig = rig();
        let mut pipe = FeaturePipeline::new(&rig, 12_000.0).unwrap();
        let speed = crate::dsp::SpeedTrack::fixed(1800.0).unwrap();
        let rule = EnvelopeRule::new(orders(), RuleSettings::default(), 50.0);
        let n = pipe.window_len();
        (0..7)
            .map(|k| {
                let s = k * n / 2;
                let (step, _, p) = pipe
                    .envelope_order_power(s as f64 / 12_000.0, &x[s..s + n], &speed)
                    .unwrap();
                rule.judge(step, p)
            })
            .collect()
    }

    #[test]
    fn noise_alone_is_healthy() {
        for v in verdicts(0.0, 1.0, 0.5) {
            assert_eq!(v.label(), "healthy", "{v:?}");
            assert!(v.ratios.iter().all(|&r| r < 3.0), "{v:?}");
        }
    }

    #[test]
    fn impacts_at_bpfo_are_outer_race_and_at_bpfi_inner_race() {
        let o = orders();
        for v in verdicts(o.bpfo, 1.0, 0.05) {
            assert_eq!(v.label(), "outer_race", "{v:?}");
        }
        for v in verdicts(o.bpfi, 1.0, 0.05) {
            assert_eq!(v.label(), "inner_race", "{v:?}");
        }
    }

    #[test]
    fn impacts_off_the_fault_orders_do_not_fire() {
        // a strong train at order 4.4 (between BPFO 3.58 and BPFI 5.42; 2x = 8.8, off both
        // 7.17 and 10.83) is no race fault by the rule
        for v in verdicts(4.4, 1.0, 0.05) {
            assert_eq!(v.label(), "healthy", "{v:?}");
        }
    }

    #[test]
    fn impacts_buried_in_noise_are_missed() {
        // the same BPFO train 200x weaker under the same noise: below 3x the median
        let o = orders();
        let n_healthy = verdicts(o.bpfo, 0.005, 0.5)
            .iter()
            .filter(|v| v.class == 0)
            .count();
        assert_eq!(n_healthy, 7);
    }

    #[test]
    fn the_threshold_decides_between_two_lines() {
        let rule = EnvelopeRule::new(orders(), RuleSettings::default(), 50.0);
        // flat floor: power 1 per line, 50 lines per 0.5-order band -> band RMS sqrt(50)
        let step = 0.01;
        let mut p = vec![1.0f32; 5001];
        let at = |o: f64| (o / step).round() as usize;
        p[at(orders().bpfo)] = 380.0; // band RMS sqrt(429 / 50) = 2.93x: not enough
        let v = rule.judge(step, &p);
        assert_eq!(v.class, 0, "{v:?}");
        p[at(2.0 * orders().bpfi)] = 420.0; // sqrt(469 / 50) = 3.06x at 2xBPFI: inner race
        let v = rule.judge(step, &p);
        assert_eq!(v.label(), "inner_race");
        assert!(
            (v.ratios[3] - (469.0f64 / 50.0).sqrt()).abs() < 1e-3,
            "{v:?}"
        );
        p[at(orders().bpfo)] = 420.0; // the same at BPFO: a tie goes to the outer race
        assert_eq!(rule.judge(step, &p).label(), "outer_race");
    }

    #[test]
    fn a_reading_names_one_race_and_says_what_it_sees() {
        // (fundamental, family) ratios of each race
        let r = |(bpfo, o): (f64, f64), (bpfi, i): (f64, f64)| RuleReading {
            outer_race: o,
            inner_race: i,
            bpfo,
            bpfi,
            threshold: 3.0,
        };
        // an outer race: BPFO at 6x the median, BPFI at 1.2x
        let or = r((6.0, 6.0), (1.2, 1.2));
        assert_eq!(or.calls(), Some("outer_race"));
        assert!(or.sees("outer_race") && !or.sees("inner_race") && !or.sees("healthy"));
        assert!(
            or.sees("ball"),
            "the rule says nothing against a ball fault"
        );
        // its third harmonic lifts the 2xBPFI band: still no sign of an inner race
        let or3 = r((6.0, 6.0), (1.2, 3.5));
        assert_eq!(or3.calls(), Some("outer_race"));
        assert!(!or3.sees("inner_race"));
        // both fundamentals above: the rule calls the higher family and sees both
        let both = r((4.0, 4.0), (5.0, 5.0));
        assert_eq!(both.calls(), Some("inner_race"));
        assert!(both.sees("outer_race") && both.sees("inner_race"));
        // nothing above: healthy
        let h = r((2.9, 2.9), (1.0, 1.0));
        assert_eq!(h.calls(), None);
        assert!(h.sees("healthy") && !h.sees("outer_race"));
        assert_eq!(r((f64::NAN, f64::NAN), (f64::NAN, f64::NAN)).calls(), None);
    }

    #[test]
    fn rule_classes_map_onto_a_model_label_list() {
        let l: Vec<String> = ["healthy", "outer_race", "inner_race", "ball"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(class_map(&l).unwrap(), [0, 1, 2]);
        assert!(class_map(&l[..2]).is_err());
    }
}
