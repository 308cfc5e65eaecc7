//! One window's verdict: the single mapping from what a window says -- the classifier's
//! probabilities and novelty, the machine's healthy baseline, the fault-family evidence, the
//! rule's band ratios, the impulsiveness and the data quality -- to the window's state under a
//! `[health]` policy. The daemon (`daemon::analyze`) and every offline score
//! (`train::score`, so `evaluate` and `adapt`) call [`judge`] through
//! [`super::HealthStateMachine::observe`], so a score is what the daemon would say.
//!
//! In order:
//! 1. **Quality.** A window whose classifier channel cannot be trusted ([`quality_problem`]:
//!    lost or non-finite samples, clipping, a flat or dropped-out sensor, failed features or
//!    inference) is `unknown` (`bad_quality`), whatever the classifier says. A window whose
//!    samples are sound but whose *speed* is not (no speed, a lost tacho, a speed the recipe
//!    cannot resolve, a speed the vibration does not settle: [`speed_only`]) is judged on the
//!    speed-free evidence alone: impulsive beyond the machine's healthy windows and Gaussian
//!    noise (step 3's test) it is an alarm (`basis` `impulsive`, `alarm_despite`
//!    `bad_quality`), named by a fault family standing `evidence_z` above healthy at the
//!    speed the window was analysed at, else the classifier's most probable fault class at
//!    that speed, else [`UNNAMED_FAULT`]; otherwise `unknown` (`bad_quality`). Alarms never
//!    wait for a speed, and a healthy window with an uncertain speed stays quiet.
//! 2. **Evidence** (aligned models that output `baseline_deviation`; [`FamilyEvidence`],
//!    accumulated over the last windows by the state machine): first, where the rule
//!    ([`RuleReading`]) names one race and sees its fundamental, sees nothing of the class the
//!    network named (`healthy`, or the other race's fundamental) and that race's family stands at least `evidence_z` above
//!    the machine's healthy level and no lower than the network's family, the rule's race
//!    wins (`evidence`, the network's class `overruled`): the spectrum read two independent
//!    ways against the network. Otherwise the classifier's fault class is *confirmed* when
//!    its family's bins stand at least `evidence_z` standard deviations above the machine's
//!    healthy level; a class the evidence does not support -- `healthy` included -- is
//!    *overruled* by the family whose bins stand highest beyond `evidence_z`, named even when
//!    the model lacks that class. Among supported families the evidence alone does not choose
//!    (they share bins: an inner-race fault's 1x sidebands fall into the outer race's bins),
//!    so a supported class stands, novel or not. A confirmed or evidence-decided window is
//!    an alarm even when it is novel or doubtful (flagged `alarm_despite`): the decision
//!    follows the spectrum, not the network's guess.
//! 3. **Impulsiveness** (aligned models carrying the healthy windows' kurtosis;
//!    [`Impulse`], the mean over the last windows): a window the classifier calls healthy
//!    whose raw signal stands `impulse_z` standard deviations above both the machine's
//!    healthy windows and Gaussian noise is an alarm (`basis` `impulsive`): a defect's
//!    impacts without a clean fault-family line (a small ball defect rolling in and out of
//!    the load zone). It is named by the family whose bins stand highest when one stands
//!    above the machine's healthy level, else the classifier's most probable fault class.
//! 4. **Doubt** (no evidence either way): a novel window (novelty above the model's or the
//!    policy's threshold) or one whose top probability is below `min_confidence` is
//!    `unknown`, unless it is clearly a fault -- a fault class beyond the machine's healthy
//!    baseline, impulsive, or of at least `novel_alarm_confidence` -- which keeps its class
//!    as an alarm flagged `alarm_despite`.

use super::{HealthPolicy, UnknownReason, UNKNOWN};
use crate::analysis::{WindowAnalysis, WindowError};
use crate::model::evidence::FamilyEvidence;
use crate::model::impulsiveness::Impulse;
use crate::model::rule::RuleReading;
use crate::vocabulary::Condition;
use crate::vocabulary::QualityFlag;
use serde::{Deserialize, Serialize};

/// Why the classifier channel's window cannot be trusted, as the quality flag that says so
/// (`nan`, `dropout`, `no_speed`, `features_failed`, `tacho_lost`, `clipping`, `flat`,
/// `speed_out_of_range`); None when it can.
pub fn quality_problem(a: &WindowAnalysis, classifier: &str) -> Option<QualityFlag> {
    if a.classifier_nan {
        return Some(if a.lost_samples > 0 {
            QualityFlag::Dropout
        } else {
            QualityFlag::Nan
        });
    }
    let fw = match &a.features {
        Err(WindowError::NoSpeed(_)) => return Some(QualityFlag::NoSpeed),
        Err(WindowError::Features(_)) => return Some(QualityFlag::FeaturesFailed),
        Ok(fw) => fw,
    };
    // the samples first: a speed problem alone leaves the speed-free evidence standing
    let q = &fw.quality;
    let on_classifier = |list: &[String]| list.iter().any(|c| c == classifier);
    for (flag, list) in [
        (QualityFlag::Clipping, &q.clipped),
        (QualityFlag::Flat, &q.flat),
        (QualityFlag::Dropout, &q.dropout),
        (QualityFlag::Nan, &q.non_finite),
    ] {
        if on_classifier(list) {
            return Some(flag);
        }
    }
    if a.tacho_lost {
        return Some(QualityFlag::TachoLost);
    }
    if q.speed_out_of_range {
        return Some(QualityFlag::SpeedOutOfRange);
    }
    q.speed_uncertain.then_some(QualityFlag::SpeedUncertain)
}

/// Whether a quality problem is about the speed only, the samples themselves sound (no
/// speed, a lost tacho, a speed out of the recipe's range, a speed the vibration does not
/// settle): the speed-free evidence (the impulsiveness) still judges such a window.
pub fn speed_only(flag: QualityFlag) -> bool {
    matches!(
        flag,
        QualityFlag::NoSpeed
            | QualityFlag::TachoLost
            | QualityFlag::SpeedOutOfRange
            | QualityFlag::SpeedUncertain
    )
}

/// The class of an alarm no family, no classifier and no evidence can name (a window without
/// a speed, impulsive far beyond the machine's healthy windows, on a model without fault
/// classes or with no features to classify).
pub const UNNAMED_FAULT: &str = "fault";

/// What one window says, before the verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowInput<'a> {
    /// Class labels (model order) and their probabilities (empty: the classifier did not run).
    pub labels: &'a [String],
    pub probs: &'a [f32],
    /// Novelty score (NaN: none) and the model's threshold (the policy may override it).
    pub novelty: f32,
    pub model_novelty_threshold: f32,
    /// Why the data forbids a verdict ([`quality_problem`], or `inference_failed`).
    pub quality: Option<QualityFlag>,
    /// The window stands beyond the machine's healthy baseline (None: not aligned).
    pub beyond_baseline: Option<bool>,
    /// Fault-family evidence against the machine's healthy baseline (None: not available).
    pub evidence: Option<FamilyEvidence>,
    /// Impulsiveness against the machine's healthy baseline (None: not available).
    pub impulse: Option<Impulse>,
    /// The rule's band ratios in this window (None: no band ratios).
    pub rule: Option<RuleReading>,
}

/// What decided a window's class.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Basis {
    /// The classifier's top class; the evidence neither confirms nor contradicts it (or there
    /// is none).
    #[default]
    Model,
    /// The classifier's fault class, its family's bins beyond the machine's healthy level.
    Confirmed,
    /// The fault family the evidence points at, overruling a class it does not support.
    Evidence,
    /// An impulsive signal overruling a `healthy` class ([`Impulse`]).
    Impulsive,
}

impl Basis {
    /// The name used in JSON (`model`, `confirmed`, `evidence`, `impulsive`).
    pub fn as_str(self) -> &'static str {
        match self {
            Basis::Model => "model",
            Basis::Confirmed => "confirmed",
            Basis::Evidence => "evidence",
            Basis::Impulsive => "impulsive",
        }
    }
}

/// The verdict on one window.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowVerdict {
    /// The decided class (None when the quality forbids one).
    pub class: Option<String>,
    /// Why the window is `unknown` (None when it has a class).
    pub unknown_reason: Option<UnknownReason>,
    /// The window keeps its class although it would be `unknown` for this reason.
    pub alarm_despite: Option<UnknownReason>,
    pub basis: Basis,
    /// The classifier's class when the evidence or the impulsiveness overruled it.
    pub overruled: Option<String>,
}

impl WindowVerdict {
    /// The window's own state: its class, or `unknown`.
    pub fn state(&self) -> &str {
        match (&self.class, self.unknown_reason) {
            (Some(c), None) => c,
            _ => UNKNOWN,
        }
    }
}

/// The novelty threshold in force: the policy's override, else the model's.
pub fn novelty_threshold(policy: &HealthPolicy, model_threshold: f32) -> f32 {
    policy.novelty_threshold.unwrap_or(model_threshold)
}

/// The verdict on one window under `policy` (see the module doc for the order of the rules).
pub fn judge(w: &WindowInput, policy: &HealthPolicy) -> WindowVerdict {
    if let Some(flag) = w.quality {
        return without_speed(w, policy, flag);
    }
    let (top, top_p) =
        w.probs
            .iter()
            .copied()
            .enumerate()
            .fold((0usize, f32::NEG_INFINITY), |best, (i, p)| {
                if p > best.1 {
                    (i, p)
                } else {
                    best
                }
            });
    let (Some(model_class), true) = (w.labels.get(top), top_p.is_finite()) else {
        return bad_quality();
    };
    let threshold = novelty_threshold(policy, w.model_novelty_threshold);
    let novel = w.novelty > threshold; // NaN: no novelty score, not novel
    let doubt = if novel {
        Some(UnknownReason::Novelty)
    } else if top_p < policy.min_confidence {
        Some(UnknownReason::LowConfidence)
    } else {
        None
    };
    let decided = |class: &str, basis, overruled| WindowVerdict {
        class: Some(class.to_string()),
        unknown_reason: None,
        alarm_despite: doubt,
        basis,
        overruled,
    };
    let evidence = w.evidence.as_ref();
    if let Some((class, basis)) =
        evidence.and_then(|e| follow(e, model_class, policy.evidence_z, w.rule))
    {
        let overruled = (basis == Basis::Evidence).then(|| model_class.clone());
        return decided(class, basis, overruled);
    }
    let impulsive = w.impulse.is_some_and(|i| i.z() >= policy.impulse_z);
    if impulsive && Condition::is_healthy(model_class) {
        if let Some(fault) = impulsive_fault(w, f32::MIN_POSITIVE) {
            return decided(fault, Basis::Impulsive, Some(model_class.clone()));
        }
    }
    let Some(doubt) = doubt else {
        return decided(model_class, Basis::Model, None);
    };
    // Beyond the healthy baseline the gate has already zeroed `healthy`: every class left is
    // a fault, so the window is an alarm whatever the network's doubt.
    let clearly_faulty = !Condition::is_healthy(model_class)
        && (w.beyond_baseline == Some(true) || impulsive || top_p >= policy.novel_alarm_confidence);
    if clearly_faulty {
        decided(model_class, Basis::Model, None)
    } else {
        WindowVerdict {
            class: Some(model_class.clone()),
            unknown_reason: Some(doubt),
            alarm_despite: None,
            basis: Basis::Model,
            overruled: None,
        }
    }
}

fn bad_quality() -> WindowVerdict {
    WindowVerdict {
        class: None,
        unknown_reason: Some(UnknownReason::BadQuality),
        alarm_despite: None,
        basis: Basis::Model,
        overruled: None,
    }
}

/// Step 1: a window whose data forbid a classification. When only its speed is in doubt
/// ([`speed_only`]) and it is impulsive beyond the machine's healthy windows and Gaussian
/// noise, it is an alarm all the same, named by what can name it at the speed it was
/// analysed at (a family `evidence_z` above healthy, else the classifier's likeliest fault,
/// else [`UNNAMED_FAULT`]); otherwise `unknown`.
fn without_speed(w: &WindowInput, policy: &HealthPolicy, flag: QualityFlag) -> WindowVerdict {
    let impulsive = w.impulse.is_some_and(|i| i.z() >= policy.impulse_z);
    if !(speed_only(flag) && impulsive) {
        return bad_quality();
    }
    let name = impulsive_fault(w, policy.evidence_z).unwrap_or(UNNAMED_FAULT);
    WindowVerdict {
        class: Some(name.to_string()),
        unknown_reason: None,
        alarm_despite: Some(UnknownReason::BadQuality),
        basis: Basis::Impulsive,
        overruled: None,
    }
}

/// What the fault-family evidence decides (step 2): the rule's race where the rule and the
/// families agree against the network ([`rule_wins`]); else the classifier's class when its
/// family stands at least `z` (`confirmed`), else the family standing highest beyond `z`
/// (`evidence`); None when no family does.
fn follow<'a>(
    ev: &FamilyEvidence,
    model_class: &'a str,
    z: f32,
    rule: Option<RuleReading>,
) -> Option<(&'a str, Basis)> {
    if let Some(race) = rule.and_then(|r| rule_wins(&r, ev, model_class, z)) {
        return Some((race, Basis::Evidence));
    }
    // The evidence refuses a class it does not support; it does not choose among supported
    // families: in 0.5-order bins the families share bins (an inner-race fault's 1x
    // sidebands, BPFI -+ 1x, -+ 2x, fall into the outer race's bins on common geometries),
    // so which family stands highest is no class of its own.
    if ev.of(model_class).is_some_and(|v| v >= z) {
        return Some((model_class, Basis::Confirmed));
    }
    ev.strongest(z).map(|(family, _)| (family, Basis::Evidence))
}

/// The race the rule names where it and the fault families agree against the network: the
/// rule calls a race other than the network's class, sees it by its fundamental, sees no
/// sign of the network's class (`healthy`, or the other race's fundamental below the rule's
/// threshold: [`RuleReading::sees`]), and that race's family stands
/// at least `z` above the machine's healthy level and no lower than the network's family.
/// None otherwise (and never against a class the rule cannot see, such as ball).
fn rule_wins(
    rule: &RuleReading,
    ev: &FamilyEvidence,
    model_class: &str,
    z: f32,
) -> Option<&'static str> {
    let race = rule.calls()?;
    if race == model_class || !rule.sees(race) || rule.sees(model_class) {
        return None;
    }
    let theirs = ev.of(race)?;
    let ours = ev.of(model_class).unwrap_or(f32::NEG_INFINITY);
    (theirs >= z && theirs >= ours).then_some(race)
}

/// The fault an impulsive window is named by: the family whose bins stand highest, when one
/// stands at least `min_z` above the machine's healthy level, else the classifier's most
/// probable fault class (None: the model has no fault class and there is no evidence).
fn impulsive_fault<'a>(w: &WindowInput<'a>, min_z: f32) -> Option<&'a str> {
    if let Some((family, _)) = w.evidence.and_then(|e| e.strongest(min_z)) {
        return Some(family);
    }
    w.labels
        .iter()
        .zip(w.probs)
        .filter(|(l, _)| !Condition::is_healthy(l))
        .fold(None, |best: Option<(&String, f32)>, (l, &p)| match best {
            Some((_, b)) if b >= p => best,
            _ => Some((l, p)),
        })
        .map(|(l, _)| l.as_str())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels() -> Vec<String> {
        ["healthy", "outer_race", "inner_race"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn input<'a>(labels: &'a [String], probs: &'a [f32]) -> WindowInput<'a> {
        WindowInput {
            labels,
            probs,
            novelty: 1.0,
            model_novelty_threshold: 10.0,
            quality: None,
            beyond_baseline: Some(false),
            evidence: None,
            impulse: None,
            rule: None,
        }
    }

    fn ev(outer_race: f32, inner_race: f32, ball: f32) -> Option<FamilyEvidence> {
        Some(FamilyEvidence {
            outer_race,
            inner_race,
            ball,
        })
    }

    #[test]
    fn bad_quality_wins_over_everything() {
        let l = labels();
        let w = WindowInput {
            quality: Some(QualityFlag::Clipping),
            evidence: ev(0.0, 50.0, 0.0),
            ..input(&l, &[0.0, 0.0, 1.0])
        };
        let v = judge(&w, &HealthPolicy::default());
        assert_eq!(v.state(), UNKNOWN);
        assert_eq!(v.class, None);
        assert_eq!(v.unknown_reason, Some(UnknownReason::BadQuality));
        // no probabilities (the classifier did not run) is bad quality too
        let v = judge(&input(&l, &[]), &HealthPolicy::default());
        assert_eq!(v.unknown_reason, Some(UnknownReason::BadQuality));
    }

    #[test]
    fn an_impulsive_signal_overrules_healthy_and_is_named_by_the_highest_family() {
        let l = labels();
        let p = HealthPolicy::default();
        let imp = |beyond_healthy: f32, beyond_gaussian: f32| {
            Some(Impulse {
                beyond_healthy,
                beyond_gaussian,
            })
        };
        // a confident healthy call, impulsive beyond both, no family beyond evidence_z: the
        // family standing highest (ball, which the model lacks) names the alarm
        let w = WindowInput {
            impulse: imp(12.0, 8.0),
            evidence: ev(0.5, -1.0, 2.0),
            ..input(&l, &[0.95, 0.03, 0.02])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("ball", Basis::Impulsive));
        assert_eq!(v.overruled.as_deref(), Some("healthy"));
        // without evidence: the classifier's most probable fault class
        let w = WindowInput {
            evidence: None,
            ..w
        };
        assert_eq!(judge(&w, &p).state(), "outer_race");
        // beyond the healthy windows but not beyond Gaussian noise (a sine-dominated machine
        // turning noisier): not impulsive, the classifier stands
        let w = WindowInput {
            impulse: imp(12.0, 2.0),
            ..w
        };
        assert_eq!(
            (judge(&w, &p).state(), judge(&w, &p).basis),
            ("healthy", Basis::Model)
        );
        // switched off
        let off = HealthPolicy {
            impulse_z: f32::INFINITY,
            ..HealthPolicy::default()
        };
        let w = WindowInput {
            impulse: imp(50.0, 50.0),
            ..w
        };
        assert_eq!(judge(&w, &off).state(), "healthy");
        // a novel window the network calls a fault with little confidence: impulsive makes it
        // clearly a fault (an alarm despite novelty) instead of `unknown`
        let w = WindowInput {
            novelty: 50.0,
            beyond_baseline: Some(false),
            ..input(&l, &[0.3, 0.4, 0.3])
        };
        assert_eq!(judge(&w, &p).state(), UNKNOWN);
        let w = WindowInput {
            impulse: imp(9.0, 9.0),
            ..w
        };
        let v = judge(&w, &p);
        assert_eq!(
            (v.state(), v.alarm_despite),
            ("outer_race", Some(UnknownReason::Novelty))
        );
    }

    fn imp(z: f32) -> Option<Impulse> {
        Some(Impulse {
            beyond_healthy: z,
            beyond_gaussian: z,
        })
    }

    #[test]
    fn a_window_without_a_speed_is_judged_on_the_speed_free_evidence() {
        let l = labels();
        let p = HealthPolicy::default();
        // speed uncertain, impulsive far beyond healthy and Gaussian noise: an alarm, not
        // unknown, flagged as decided despite the quality
        let w = WindowInput {
            quality: Some(QualityFlag::SpeedUncertain),
            impulse: imp(9.0),
            ..input(&l, &[0.6, 0.1, 0.3])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("inner_race", Basis::Impulsive));
        assert_eq!(v.alarm_despite, Some(UnknownReason::BadQuality));
        assert_eq!(v.unknown_reason, None);
        // named by a family standing evidence_z above healthy at the analysed speed ...
        let w2 = WindowInput {
            evidence: ev(p.evidence_z + 1.0, 0.5, 0.0),
            ..w.clone()
        };
        assert_eq!(judge(&w2, &p).state(), "outer_race");
        // ... but not by one merely above the healthy level (the speed may be wrong)
        let w2 = WindowInput {
            evidence: ev(1.0, 0.5, 0.0),
            ..w.clone()
        };
        assert_eq!(judge(&w2, &p).state(), "inner_race");
        // no speed at all, no classifier run, nothing to name it: the generic fault
        let w3 = WindowInput {
            quality: Some(QualityFlag::NoSpeed),
            impulse: imp(9.0),
            ..input(&l, &[])
        };
        assert_eq!(judge(&w3, &p).state(), UNNAMED_FAULT);
        // a healthy window with an uncertain speed stays quiet: unknown, no alarm
        let quiet = WindowInput {
            impulse: imp(1.0),
            ..w.clone()
        };
        let v = judge(&quiet, &p);
        assert_eq!(
            (v.state(), v.unknown_reason),
            (UNKNOWN, Some(UnknownReason::BadQuality))
        );
        // sample problems still forbid any verdict, impulsive or not (clipping makes peaks)
        for q in [
            QualityFlag::Clipping,
            QualityFlag::Dropout,
            QualityFlag::Nan,
        ] {
            let bad = WindowInput {
                quality: Some(q),
                ..w.clone()
            };
            assert_eq!(judge(&bad, &p).state(), UNKNOWN, "{q:?}");
        }
        // switched off with the impulsiveness
        let off = HealthPolicy {
            impulse_z: f32::INFINITY,
            ..HealthPolicy::default()
        };
        assert_eq!(judge(&w, &off).state(), UNKNOWN);
    }

    #[test]
    fn the_rule_and_the_families_agreeing_against_the_network_win() {
        let l = labels();
        let p = HealthPolicy::default();
        // the races' ratios, each the fundamental's and the family's alike
        let rule = |o: f64, i: f64| {
            Some(RuleReading {
                outer_race: o,
                inner_race: i,
                bpfo: o,
                bpfi: i,
                threshold: 3.0,
            })
        };
        // an outer race the network calls inner race: the rule sees BPFO at 6x its median
        // and nothing at BPFI, the outer family stands 7 sd above healthy, the inner 4 (it
        // shares bins): the outer race wins
        let w = WindowInput {
            evidence: ev(7.0, 4.0, 0.0),
            rule: rule(6.0, 1.3),
            ..input(&l, &[0.05, 0.15, 0.8])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("outer_race", Basis::Evidence));
        assert_eq!(v.overruled.as_deref(), Some("inner_race"));
        // the rule calls the outer race by its second harmonic only (BPFO itself below 3x):
        // no agreement, the network stands
        let by_harmonic = WindowInput {
            rule: Some(RuleReading {
                outer_race: 6.0,
                inner_race: 1.3,
                bpfo: 2.0,
                bpfi: 1.3,
                threshold: 3.0,
            }),
            ..w.clone()
        };
        assert_eq!(judge(&by_harmonic, &p).state(), "inner_race");
        // without the rule the supported network class stands (the evidence alone does not
        // choose between supported families)
        let alone = WindowInput {
            rule: None,
            ..w.clone()
        };
        assert_eq!(judge(&alone, &p).state(), "inner_race");
        // the rule also sees the network's race (BPFI at 3.5x): the network stands
        let both = WindowInput {
            rule: rule(6.0, 3.5),
            ..w.clone()
        };
        assert_eq!(judge(&both, &p).state(), "inner_race");
        // the families do not agree with the rule (outer below evidence_z, or below the
        // network's family): the network stands
        for e in [ev(2.0, 4.0, 0.0), ev(5.0, 6.0, 0.0)] {
            let w = WindowInput {
                evidence: e,
                ..w.clone()
            };
            assert_eq!(judge(&w, &p).state(), "inner_race", "{e:?}");
        }
        // a network calling healthy: the rule's race wins where its family is supported,
        // though another family stands higher
        let w = WindowInput {
            evidence: ev(4.0, 0.0, 6.0),
            rule: rule(5.0, 1.0),
            ..input(&l, &[0.9, 0.05, 0.05])
        };
        assert_eq!(judge(&w, &p).state(), "outer_race");
        // never against a class the rule cannot see (ball)
        let l4: Vec<String> = ["healthy", "outer_race", "inner_race", "ball"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let w = WindowInput {
            evidence: ev(7.0, 0.0, 5.0),
            rule: rule(6.0, 1.0),
            ..input(&l4, &[0.0, 0.1, 0.0, 0.9])
        };
        assert_eq!(judge(&w, &p).state(), "ball");
    }

    #[test]
    fn evidence_overrules_a_class_it_does_not_support() {
        let l = labels();
        let p = HealthPolicy::default();
        // a novel window the network calls outer race; the BPFI bins stand far above healthy
        let w = WindowInput {
            novelty: 50.0,
            evidence: ev(0.5, 12.0, 1.0),
            ..input(&l, &[0.1, 0.8, 0.1])
        };
        let v = judge(&w, &p);
        assert_eq!(v.state(), "inner_race");
        assert_eq!(v.basis, Basis::Evidence);
        assert_eq!(v.overruled.as_deref(), Some("outer_race"));
        assert_eq!(v.alarm_despite, Some(UnknownReason::Novelty));
        // the network calls a weak inner-race fault healthy, with confidence: overruled
        let w = WindowInput {
            evidence: ev(0.0, p.evidence_z + 0.1, 0.0),
            ..input(&l, &[0.97, 0.02, 0.01])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("inner_race", Basis::Evidence));
        assert_eq!(v.alarm_despite, None);
        // a family the model lacks is named all the same
        let w = WindowInput {
            evidence: ev(0.0, 1.0, 30.0),
            ..input(&l, &[0.9, 0.05, 0.05])
        };
        assert_eq!(judge(&w, &p).state(), "ball");
    }

    #[test]
    fn evidence_confirms_a_supported_fault_and_decides_for_a_novel_window() {
        let l = labels();
        let p = HealthPolicy::default();
        // familiar window, both races supported: the network's supported pick stands
        let w = WindowInput {
            evidence: ev(9.0, 12.0, 0.0),
            ..input(&l, &[0.1, 0.8, 0.1])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("outer_race", Basis::Confirmed));
        assert_eq!(v.alarm_despite, None);
        // the same window novel: the supported pick still stands (an alarm despite novelty);
        // the evidence does not choose between two supported families
        let w = WindowInput { novelty: 50.0, ..w };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("outer_race", Basis::Confirmed));
        assert_eq!(v.overruled, None);
        assert_eq!(v.alarm_despite, Some(UnknownReason::Novelty));
        // novel and unsupported: the strongest supported family decides
        let w = WindowInput {
            evidence: ev(1.0, 12.0, 0.0),
            ..w
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("inner_race", Basis::Evidence));
        assert_eq!(v.overruled.as_deref(), Some("outer_race"));
        assert_eq!(v.alarm_despite, Some(UnknownReason::Novelty));
        // novel, and the network's pick is the strongest: confirmed, an alarm despite novelty
        let w = WindowInput {
            novelty: 50.0,
            evidence: ev(9.0, 4.0, 0.0),
            ..input(&l, &[0.3, 0.4, 0.3])
        };
        let v = judge(&w, &p);
        assert_eq!((v.state(), v.basis), ("outer_race", Basis::Confirmed));
        assert_eq!(v.alarm_despite, Some(UnknownReason::Novelty));
    }

    #[test]
    fn without_evidence_the_doubt_rules_hold() {
        let l = labels();
        let p = HealthPolicy::default();
        // silent evidence: a healthy familiar window stays healthy
        let w = WindowInput {
            evidence: ev(1.0, -0.5, 2.0),
            ..input(&l, &[0.95, 0.03, 0.02])
        };
        let v = judge(&w, &p);
        assert_eq!(
            (v.state(), v.basis, v.alarm_despite),
            ("healthy", Basis::Model, None)
        );
        // novel, inside the baseline, no evidence: unknown (no guess)
        let w = WindowInput {
            novelty: 50.0,
            evidence: ev(1.0, 1.0, 1.0),
            ..input(&l, &[0.2, 0.6, 0.2])
        };
        let v = judge(&w, &p);
        assert_eq!(v.state(), UNKNOWN);
        assert_eq!(v.unknown_reason, Some(UnknownReason::Novelty));
        // beyond the baseline: an alarm despite novelty
        let w = WindowInput {
            beyond_baseline: Some(true),
            ..w
        };
        let v = judge(&w, &p);
        assert_eq!(
            (v.state(), v.alarm_despite),
            ("outer_race", Some(UnknownReason::Novelty))
        );
        // the policy's threshold overrides the model's
        let w = WindowInput {
            novelty: 50.0,
            ..input(&l, &[0.95, 0.03, 0.02])
        };
        assert_eq!(judge(&w, &p).state(), UNKNOWN);
        let lenient = HealthPolicy {
            novelty_threshold: Some(100.0),
            ..HealthPolicy::default()
        };
        assert_eq!(judge(&w, &lenient).state(), "healthy");
        // an infinite evidence threshold switches the evidence off
        let off = HealthPolicy {
            evidence_z: f32::INFINITY,
            ..HealthPolicy::default()
        };
        let w = WindowInput {
            evidence: ev(0.0, 40.0, 0.0),
            ..input(&l, &[0.97, 0.02, 0.01])
        };
        assert_eq!(judge(&w, &off).state(), "healthy");
    }
}
