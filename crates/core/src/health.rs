//! Health state machine: per-window verdicts -> a smoothed machine state with hysteresis.
//!
//! Each window gets a *window verdict* from the one mapping in [`verdict`] (data quality,
//! the classifier's probabilities and novelty, the machine's healthy baseline, the
//! fault-family evidence and the impulsiveness, under this policy): its class, or `unknown`
//! when the data quality is bad, or when the window is novel or doubtful and nothing shows it
//! is clearly a fault. Faults on a real machine are often stronger than anything simulated,
//! so a distance-to-training-set test calls them novel; answering `unknown` there would hide
//! the alarm, so a window beyond the machine's healthy baseline, a confident fault, an
//! impulsive one, or a fault the spectrum's fault-family bins support keeps its class,
//! flagged `alarm_despite`. The *smoothed state* changes only when one state wins at least `k` of the last `n` window
//! states (k-of-n voting) and has kept winning for `dwell_s` seconds of signal (dwell time).
//! Going to `unknown` uses `unknown_dwell_s` (default 0: stop claiming a state as soon as the
//! votes say the data cannot be trusted). Before the first vote is won the smoothed state is
//! `unknown`.
//!
//! Where the model carries the machine's healthy indicator baseline
//! ([`crate::model::indicators`]), each window's speed-free indicators also feed the
//! departure test ([`crate::model::departure`]): once the indicators have left the healthy
//! baseline for good, the smoothed state is a fault and stays one (named by the fault the
//! vote holds or the window's class when either is a fault, else [`UNNAMED_FAULT`]); it may
//! move to another fault by the vote, never back to `healthy` or `unknown`, until a new
//! baseline is loaded.
//!
//! The published message is [`crate::wire::health`]; the ISO 20816-3 velocity zones in
//! [`iso20816`].

pub mod iso20816;
pub mod verdict;

use crate::model::departure::{Departure, DepartureReading, DepartureSettings};
use crate::model::evidence::{EvidenceHistory, FamilyEvidence};
use crate::model::impulsiveness::{window_cap, Impulse, ImpulseHistory};
use crate::model::indicators::{IndicatorBaseline, Indicators};
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
pub use verdict::{judge, Basis, WindowInput, WindowVerdict, UNNAMED_FAULT};

/// The state name used when no class can be trusted.
pub const UNKNOWN: &str = "unknown";

/// How window verdicts are smoothed (the `[health]` section of the daemon config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HealthPolicy {
    /// Votes kept (the last `vote_n` windows).
    #[serde(default = "default_n")]
    pub vote_n: usize,
    /// Votes a state needs among the last `vote_n` windows to become the smoothed state.
    #[serde(default = "default_k")]
    pub vote_k: usize,
    /// Seconds (of signal) a new known state must keep winning the vote before it is adopted.
    #[serde(default = "default_dwell")]
    pub dwell_s: f64,
    /// Seconds the `unknown` vote must keep winning before the smoothed state becomes unknown.
    #[serde(default)]
    pub unknown_dwell_s: f64,
    /// A window whose top class probability is below this is `unknown`.
    #[serde(default = "default_min_conf")]
    pub min_confidence: f32,
    /// A novel window whose top class is a fault with at least this probability keeps its
    /// fault class (an alarm flagged `alarm_despite = novelty`) instead of becoming `unknown`.
    #[serde(default = "default_novel_alarm_conf")]
    pub novel_alarm_confidence: f32,
    /// Override the model's novelty threshold (None = use the model's own).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub novelty_threshold: Option<f32>,
    /// Standard deviations above the machine's healthy level at which a fault family's bins
    /// confirm or overrule the classifier (aligned models; [`verdict`]). `inf` switches the
    /// evidence off.
    #[serde(default = "default_evidence_z")]
    pub evidence_z: f32,
    /// Standard deviations by which the classifier channel's excess kurtosis, averaged over
    /// the last `vote_n` windows, must stand above both the machine's healthy windows and
    /// Gaussian noise for a window the classifier calls healthy to be an alarm (aligned
    /// models; [`crate::model::impulsiveness`]). `inf` switches it off.
    #[serde(default = "default_impulse_z")]
    pub impulse_z: f32,
    /// ISO 20816-3 zone limits for the velocity RMS advisory.
    #[serde(default)]
    pub iso20816: iso20816::ZoneConfig,
    /// When the health indicators have left the healthy baseline for good (models carrying
    /// the indicator baseline; [`crate::model::departure`]).
    #[serde(default)]
    pub departure: DepartureSettings,
}

fn default_n() -> usize {
    5
}
fn default_k() -> usize {
    3
}
fn default_dwell() -> f64 {
    1.0
}
fn default_min_conf() -> f32 {
    0.5
}
fn default_novel_alarm_conf() -> f32 {
    0.9
}
fn default_evidence_z() -> f32 {
    DEFAULT_EVIDENCE_Z
}
fn default_impulse_z() -> f32 {
    DEFAULT_IMPULSE_Z
}

/// Default `evidence_z` (see [`HealthPolicy::evidence_z`]): three standard deviations, a
/// one-sided 0.13 % per family and window on healthy data; chosen on the study's own generator
/// and simulator draws (docs/diagnosis.md), where the machines' held-out healthy windows
/// reached at most 2.5 and weak inner-race faults 3.1-5.4.
pub const DEFAULT_EVIDENCE_Z: f32 = 3.0;

/// Default `impulse_z` (see [`HealthPolicy::impulse_z`]): five standard deviations, stricter
/// than `evidence_z` because the sample kurtosis has a heavy upper tail and one machine's
/// kurtosis drifts with load (its windows are no independent draws). Chosen after reading the
/// shared records' kurtosis (97, the CWRU fan end, HIT-SM Normal) and not tried at other
/// values (docs/diagnosis.md).
pub const DEFAULT_IMPULSE_Z: f32 = 5.0;

impl Default for HealthPolicy {
    fn default() -> Self {
        HealthPolicy {
            vote_n: default_n(),
            vote_k: default_k(),
            dwell_s: default_dwell(),
            unknown_dwell_s: 0.0,
            min_confidence: default_min_conf(),
            novel_alarm_confidence: default_novel_alarm_conf(),
            novelty_threshold: None,
            evidence_z: default_evidence_z(),
            impulse_z: default_impulse_z(),
            iso20816: iso20816::ZoneConfig::default(),
            departure: DepartureSettings::default(),
        }
    }
}

impl HealthPolicy {
    /// Check the numbers; errors name the key and the rule.
    pub fn validate(&self) -> Result<()> {
        if self.vote_n == 0 || self.vote_n > 1000 {
            bail!(
                "health.vote_n = {}: must be between 1 and 1000",
                self.vote_n
            );
        }
        if self.vote_k * 2 <= self.vote_n || self.vote_k > self.vote_n {
            bail!(
                "health.vote_k = {} with vote_n = {}: need vote_n/2 < vote_k <= vote_n so that at most one state can win",
                self.vote_k,
                self.vote_n
            );
        }
        if !(self.dwell_s >= 0.0 && self.dwell_s.is_finite())
            || !(self.unknown_dwell_s >= 0.0 && self.unknown_dwell_s.is_finite())
        {
            bail!("health.dwell_s and health.unknown_dwell_s must be finite and >= 0");
        }
        if !(0.0..=1.0).contains(&self.min_confidence) {
            bail!(
                "health.min_confidence = {}: must be in 0..=1",
                self.min_confidence
            );
        }
        if !(0.0..=1.0).contains(&self.novel_alarm_confidence) {
            bail!(
                "health.novel_alarm_confidence = {}: must be in 0..=1",
                self.novel_alarm_confidence
            );
        }
        if self.evidence_z.is_nan() || self.evidence_z <= 0.0 {
            bail!(
                "health.evidence_z = {}: must be > 0 (inf switches the fault-family evidence off)",
                self.evidence_z
            );
        }
        if self.impulse_z.is_nan() || self.impulse_z <= 0.0 {
            bail!(
                "health.impulse_z = {}: must be > 0 (inf switches the impulsiveness off)",
                self.impulse_z
            );
        }
        self.departure.validate()?;
        self.iso20816.validate()
    }
}

/// Why a window is `unknown` (None when it has a class).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnknownReason {
    BadQuality,
    Novelty,
    LowConfidence,
}

impl UnknownReason {
    /// The name used in JSON (`bad_quality`, `novelty`, `low_confidence`).
    pub fn as_str(self) -> &'static str {
        match self {
            UnknownReason::BadQuality => "bad_quality",
            UnknownReason::Novelty => "novelty",
            UnknownReason::LowConfidence => "low_confidence",
        }
    }
}

/// The state machine's answer for one window.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed {
    /// This window's verdict ([`verdict::judge`]).
    pub window: WindowVerdict,
    /// This window's own state (its class or `unknown`).
    pub window_state: String,
    /// The fault-family evidence the verdict used: accumulated over the last `vote_n`
    /// windows that had one (None: the model gives none).
    pub evidence: Option<FamilyEvidence>,
    /// The impulsiveness the verdict used: the capped mean over the last `vote_n` places
    /// ([`ImpulseHistory`]; None: the model carries no kurtosis baseline).
    pub impulse: Option<Impulse>,
    /// The window's health indicators and the departure test's reading (None: no indicator
    /// baseline, or the window had no indicators).
    pub departure: Option<DepartureReading>,
    /// The smoothed state after this window.
    pub state: String,
    /// Mean probability of the smoothed state over the vote history (for `unknown`: the
    /// share of `unknown` votes).
    pub confidence: f32,
    /// True when this window changed the smoothed state.
    pub changed: bool,
    /// Window-end time at which the smoothed state was entered, s.
    pub since_s: f64,
}

/// k-of-n voting with dwell time. Allocation-free per window once the history is full
/// (state names are interned in `names`).
#[derive(Debug, Clone)]
pub struct HealthStateMachine {
    policy: HealthPolicy,
    /// Interned state names: index 0 is `unknown`, then the model's labels.
    names: Vec<String>,
    /// Last n votes: (state index, probability vector index in `probs`).
    votes: VecDeque<usize>,
    /// Probabilities of the last n windows, flattened (n x labels), in vote order.
    probs: VecDeque<Vec<f32>>,
    state: usize,
    since_s: f64,
    /// The state currently winning the vote but not yet adopted, and since when.
    candidate: Option<(usize, f64)>,
    /// False until the first state has been adopted (leaving start-up needs no dwell).
    started: bool,
    /// The last `vote_n` windows' fault-family evidence, and how far apart windows are.
    evidence: EvidenceHistory,
    /// The last `vote_n` windows' impulsiveness.
    impulse: ImpulseHistory,
    hop_fraction: f64,
    /// The departure test (None: no indicator baseline) and the fault it holds once departed.
    departure: Option<Departure>,
    held: Option<usize>,
}

impl HealthStateMachine {
    pub fn new(policy: HealthPolicy, labels: &[String]) -> Result<Self> {
        policy.validate()?;
        let mut names = vec![UNKNOWN.to_string()];
        for l in labels {
            if l == UNKNOWN {
                bail!("the model has a class named {UNKNOWN:?}; that name is reserved for the health state machine");
            }
            names.push(l.clone());
        }
        let n = policy.vote_n;
        Ok(HealthStateMachine {
            policy,
            names,
            votes: VecDeque::with_capacity(n + 1),
            probs: VecDeque::with_capacity(n + 1),
            state: 0,
            since_s: 0.0,
            candidate: None,
            started: false,
            evidence: EvidenceHistory::new(n),
            impulse: ImpulseHistory::new(n),
            hop_fraction: 0.5,
            departure: None,
            held: None,
        })
    }

    /// Windows are `hop_fraction` x their length apart (`hop_s / window_s`; 0.5 unless told):
    /// how correlated consecutive windows' evidence is.
    pub fn set_hop_fraction(&mut self, hop_fraction: f64) {
        self.hop_fraction = hop_fraction;
        self.evidence.set_hop_fraction(hop_fraction);
    }

    pub fn policy(&self) -> &HealthPolicy {
        &self.policy
    }

    /// The current smoothed state.
    pub fn state(&self) -> &str {
        &self.names[self.state]
    }

    /// Swap in a new policy and/or label set (SIGHUP reload). The vote history is kept when
    /// the labels are the same, cleared (state -> unknown) when they differ.
    pub fn reconfigure(&mut self, policy: HealthPolicy, labels: &[String]) -> Result<()> {
        let mut fresh = HealthStateMachine::new(policy, labels)?;
        fresh.set_hop_fraction(self.hop_fraction);
        if fresh.names == self.names {
            self.policy = fresh.policy;
            while self.votes.len() > self.policy.vote_n {
                self.votes.pop_front();
                self.probs.pop_front();
            }
            // another model or policy: its evidence starts afresh
            self.evidence = fresh.evidence;
            self.impulse = fresh.impulse;
            // the departure keeps its history; its settings are the new policy's
            if let Some(d) = self.departure.as_mut() {
                if d.settings() != self.policy.departure {
                    *d = Departure::new(*d.baseline(), self.policy.departure);
                    self.held = None;
                }
            }
        } else {
            *self = fresh;
        }
        Ok(())
    }

    /// Load the machine's healthy indicator baseline (None: the model carries none). The
    /// departure test starts afresh, and a held fault is released, only when the baseline
    /// differs from the one in force.
    pub fn set_indicator_baseline(&mut self, baseline: Option<IndicatorBaseline>) {
        let current = self.departure.as_ref().map(|d| *d.baseline());
        if current != baseline {
            self.departure = baseline.map(|b| Departure::new(b, self.policy.departure));
            self.held = None;
        }
    }

    /// [`Self::observe`] with the window's health indicators (None: the window had none),
    /// fed to the departure test first; once the machine has departed, the state is held at a
    /// fault (module doc).
    pub fn observe_indicators(
        &mut self,
        t_end: f64,
        w: &WindowInput,
        indicators: Option<&Indicators>,
    ) -> Smoothed {
        let reading = self
            .departure
            .as_mut()
            .zip(indicators)
            .map(|(d, i)| d.push(t_end, i));
        let before = (self.state, self.since_s);
        let mut s = self.observe(t_end, w);
        s.departure = reading;
        self.hold_departure(t_end, before, &mut s, w.labels);
        s
    }

    /// Once departed, keep the smoothed state at a fault.
    fn hold_departure(
        &mut self,
        t_end: f64,
        before: (usize, f64),
        s: &mut Smoothed,
        labels: &[String],
    ) {
        if self
            .departure
            .as_ref()
            .and_then(Departure::departed_since)
            .is_none()
        {
            return;
        }
        let is_fault = |name: &str| name != UNKNOWN && !Condition::is_healthy(name);
        let held = if is_fault(&self.names[self.state]) {
            self.state
        } else if let Some(h) = self.held {
            h
        } else {
            let name = match s.window.class.as_deref() {
                Some(c) if is_fault(c) => c.to_string(),
                _ => UNNAMED_FAULT.to_string(),
            };
            self.intern(&name)
        };
        self.held = Some(held);
        if self.state != held {
            self.state = held;
            // back to the state held before this window: since then, unchanged
            self.since_s = if held == before.0 { before.1 } else { t_end };
            self.started = true;
            self.candidate = None;
        }
        s.changed = self.state != before.0;
        s.state = self.names[self.state].clone();
        s.since_s = self.since_s;
        s.confidence = self.confidence(labels);
    }

    /// Judge one window ending at `t_end` ([`verdict::judge`] under this machine's policy)
    /// and feed its verdict; the daemon and every offline score go through here.
    ///
    /// The window's fault-family evidence and impulsiveness are first accumulated with the
    /// last windows' ([`EvidenceHistory`], [`ImpulseHistory`]) and the verdict judges the
    /// accumulated values. A window whose quality forbids a verdict adds no evidence; one
    /// whose speed alone is in doubt ([`verdict::speed_only`]) adds its impulsiveness (the
    /// kurtosis needs no speed) and is named, if it is an alarm, by its own evidence at the
    /// speed it was analysed at (not accumulated: another speed's bins).
    pub fn observe(&mut self, t_end: f64, w: &WindowInput) -> Smoothed {
        let evidence = match (w.evidence, w.quality) {
            (Some(e), None) => Some(self.evidence.push(e)),
            (own, Some(q)) if verdict::speed_only(q) => own,
            _ => None,
        };
        let sound = w.quality.is_none_or(verdict::speed_only);
        let impulse = match w.impulse {
            Some(i) if sound => {
                let p = &self.policy;
                Some(
                    self.impulse
                        .push(i, window_cap(p.impulse_z, p.vote_n, self.hop_fraction)),
                )
            }
            _ => None,
        };
        let verdict = judge(
            &WindowInput {
                evidence,
                impulse,
                ..*w
            },
            &self.policy,
        );
        let mut s = self.update(t_end, verdict, w.probs, w.labels);
        s.evidence = evidence;
        s.impulse = impulse;
        s
    }

    /// Feed one window's verdict (and the probabilities behind it, for the confidence);
    /// returns the smoothed state.
    pub fn update(
        &mut self,
        t_end: f64,
        verdict: WindowVerdict,
        probs: &[f32],
        labels: &[String],
    ) -> Smoothed {
        let vote = match (&verdict.class, verdict.unknown_reason) {
            (Some(c), None) => self.intern(c),
            _ => 0,
        };

        // Record the vote and the probabilities (recycling the oldest buffer).
        let mut buf = if self.votes.len() >= self.policy.vote_n {
            self.votes.pop_front();
            self.probs.pop_front().unwrap_or_default()
        } else {
            Vec::with_capacity(probs.len())
        };
        buf.clear();
        buf.extend_from_slice(probs);
        self.votes.push_back(vote);
        self.probs.push_back(buf);

        // k-of-n winner, if any.
        let winner = (0..self.names.len())
            .find(|&s| self.votes.iter().filter(|&&x| x == s).count() >= self.policy.vote_k);
        let mut changed = false;
        match winner {
            Some(w) if w != self.state => {
                let since = match self.candidate {
                    Some((c, t)) if c == w => t,
                    _ => t_end,
                };
                self.candidate = Some((w, since));
                let dwell = if w == 0 {
                    self.policy.unknown_dwell_s
                } else {
                    self.policy.dwell_s
                };
                // Leaving the start-up `unknown` needs no dwell beyond the vote itself.
                if !self.started || t_end - since + 1e-9 >= dwell {
                    self.started = true;
                    self.state = w;
                    self.since_s = t_end;
                    self.candidate = None;
                    changed = true;
                }
            }
            _ => self.candidate = None,
        }

        Smoothed {
            window_state: self.names[vote].clone(),
            evidence: None,
            impulse: None,
            departure: None,
            window: verdict,
            state: self.names[self.state].clone(),
            confidence: self.confidence(labels),
            changed,
            since_s: self.since_s,
        }
    }

    fn intern(&mut self, label: &str) -> usize {
        match self.names.iter().position(|n| n == label) {
            Some(i) => i,
            None => {
                self.names.push(label.to_string());
                self.names.len() - 1
            }
        }
    }

    fn confidence(&self, labels: &[String]) -> f32 {
        let n = self.votes.len().max(1) as f32;
        if self.state == 0 {
            return self.votes.iter().filter(|&&x| x == 0).count() as f32 / n;
        }
        let name = &self.names[self.state];
        match labels.iter().position(|l| l == name) {
            Some(i) => {
                self.probs
                    .iter()
                    .map(|p| p.get(i).copied().unwrap_or(0.0))
                    .sum::<f32>()
                    / n
            }
            None => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vocabulary::QualityFlag;

    fn labels() -> Vec<String> {
        ["healthy", "outer_race", "inner_race", "ball"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn probs_for(label: &str) -> Vec<f32> {
        labels()
            .iter()
            .map(|l| if l == label { 0.9 } else { 0.1 / 3.0 })
            .collect()
    }

    /// Feed window states (a label, "nan" for bad quality, "novel" for novelty) at hop 0.5 s.
    fn run(policy: HealthPolicy, seq: &[&str]) -> Vec<Smoothed> {
        let labels = labels();
        let mut sm = HealthStateMachine::new(policy, &labels).unwrap();
        seq.iter()
            .enumerate()
            .map(|(i, s)| {
                let p = probs_for(if *s == "nan" || *s == "novel" {
                    "healthy"
                } else {
                    s
                });
                sm.observe(
                    1.0 + 0.5 * i as f64,
                    &WindowInput {
                        labels: &labels,
                        probs: &p,
                        novelty: if *s == "novel" { 5.0 } else { 0.1 },
                        model_novelty_threshold: 1.0,
                        quality: (*s == "nan").then_some(QualityFlag::Nan),
                        beyond_baseline: None,
                        evidence: None,
                        impulse: None,
                        rule: None,
                    },
                )
            })
            .collect()
    }

    fn states(out: &[Smoothed]) -> Vec<&str> {
        out.iter().map(|s| s.state.as_str()).collect()
    }

    #[test]
    fn starts_unknown_and_adopts_after_k_votes() {
        let out = run(HealthPolicy::default(), &["healthy"; 4]);
        assert_eq!(states(&out), ["unknown", "unknown", "healthy", "healthy"]);
        assert!(out[2].changed && !out[3].changed);
        assert!(
            (out[3].confidence - 0.9).abs() < 1e-6,
            "{}",
            out[3].confidence
        );
    }

    #[test]
    fn hysteresis_ignores_isolated_flips() {
        // One or two stray fault windows among healthy ones never reach 3 of 5.
        let seq = [
            "healthy",
            "healthy",
            "healthy",
            "outer_race",
            "healthy",
            "outer_race",
            "healthy",
            "healthy",
            "inner_race",
        ];
        let out = run(HealthPolicy::default(), &seq);
        assert!(
            out[2..].iter().all(|s| s.state == "healthy"),
            "{:?}",
            states(&out)
        );
        assert_eq!(out[3].window_state, "outer_race");
    }

    #[test]
    fn dwell_delays_a_change_between_known_states() {
        let mut seq = vec!["healthy"; 5];
        seq.extend(["outer_race"; 6]);
        let policy = HealthPolicy {
            dwell_s: 1.0,
            ..HealthPolicy::default()
        };
        let out = run(policy, &seq);
        // outer_race wins 3 of 5 at index 7 (t = 4.5); dwell 1 s -> adopted at index 9 (t = 5.5).
        let first = out.iter().position(|s| s.state == "outer_race").unwrap();
        assert_eq!(first, 9, "{:?}", states(&out));
        assert!(out[first].changed);
        assert_eq!(out[first].since_s, 5.5);
        // Without dwell it switches as soon as the vote is won.
        let out0 = run(
            HealthPolicy {
                dwell_s: 0.0,
                ..HealthPolicy::default()
            },
            &seq,
        );
        assert_eq!(
            out0.iter().position(|s| s.state == "outer_race").unwrap(),
            7
        );
    }

    #[test]
    fn a_broken_streak_restarts_the_dwell_clock() {
        let seq = [
            "healthy",
            "healthy",
            "healthy",
            "outer_race",
            "outer_race",
            "healthy",
            "healthy",
            "outer_race",
            "outer_race",
            "outer_race",
            "outer_race",
        ];
        let policy = HealthPolicy {
            dwell_s: 1.0,
            vote_n: 3,
            vote_k: 2,
            ..HealthPolicy::default()
        };
        let out = run(policy, &seq);
        // outer_race wins 2 of 3 from index 4 (t = 3.0) to 5, loses at 6 (t = 4.0), wins again
        // from index 8 (t = 5.0): the dwell clock restarts there and runs out at index 10.
        let s = states(&out);
        assert_eq!(s[0], "unknown");
        assert!(s[1..10].iter().all(|&x| x == "healthy"), "{s:?}");
        assert_eq!(s[10], "outer_race", "{s:?}");
        assert_eq!(out[10].since_s, 6.0);
    }

    #[test]
    fn bad_quality_and_novelty_make_unknown() {
        let mut seq = vec!["healthy"; 4];
        seq.extend(["nan"; 3]);
        seq.extend(["novel"; 3]);
        let out = run(HealthPolicy::default(), &seq);
        assert_eq!(out[4].window_state, "unknown");
        assert_eq!(
            out[4].window.unknown_reason,
            Some(UnknownReason::BadQuality)
        );
        assert_eq!(out[8].window.unknown_reason, Some(UnknownReason::Novelty));
        // 3 unknown votes of 5 at index 6 -> unknown at once (unknown_dwell_s = 0).
        assert_eq!(out[5].state, "healthy");
        assert_eq!(out[6].state, "unknown");
        assert!(out[6].changed);
        assert!(out[9].state == "unknown" && out[9].confidence == 1.0);
    }

    #[test]
    fn low_confidence_is_unknown() {
        let labels = labels();
        let mut sm = HealthStateMachine::new(
            HealthPolicy {
                min_confidence: 0.6,
                ..Default::default()
            },
            &labels,
        )
        .unwrap();
        let s = sm.observe(
            1.0,
            &WindowInput {
                labels: &labels,
                probs: &[0.4, 0.3, 0.2, 0.1],
                novelty: 0.0,
                model_novelty_threshold: 1.0,
                quality: None,
                beyond_baseline: None,
                evidence: None,
                impulse: None,
                rule: None,
            },
        );
        assert_eq!(s.window_state, "unknown");
        assert_eq!(s.window.unknown_reason, Some(UnknownReason::LowConfidence));
    }

    /// Feed `n` windows of one verdict; returns the last answer.
    fn feed(probs: &[f32], novelty: f32, beyond: Option<bool>, n: usize) -> Smoothed {
        let labels = labels();
        let mut sm = HealthStateMachine::new(HealthPolicy::default(), &labels).unwrap();
        let mut last = None;
        for i in 0..n {
            last = Some(sm.observe(
                1.0 + 0.5 * i as f64,
                &WindowInput {
                    labels: &labels,
                    probs,
                    novelty,
                    model_novelty_threshold: 10.0,
                    quality: None,
                    beyond_baseline: beyond,
                    evidence: None,
                    impulse: None,
                    rule: None,
                },
            ));
        }
        last.unwrap()
    }

    #[test]
    fn novel_windows_beyond_the_healthy_baseline_raise_their_fault() {
        // The gate closed (healthy = 0) and the network is sure of outer_race, but the window
        // is further from the simulated training set than anything seen: an alarm, not unknown.
        let s = feed(&[0.0, 1.0, 0.0, 0.0], 20.0, Some(true), 6);
        assert_eq!(
            (s.window_state.as_str(), s.state.as_str()),
            ("outer_race", "outer_race")
        );
        assert_eq!(s.window.unknown_reason, None);
        assert_eq!(s.window.alarm_despite, Some(UnknownReason::Novelty));
        // Beyond the baseline, faults split between two classes are still an alarm.
        let s = feed(&[0.0, 0.45, 0.4, 0.15], 5.0, Some(true), 6);
        assert_eq!(s.state, "outer_race");
        assert_eq!(s.window.alarm_despite, Some(UnknownReason::LowConfidence));
        // Without a baseline a confident novel fault is an alarm, a doubtful one is unknown.
        assert_eq!(
            feed(&[0.02, 0.95, 0.02, 0.01], 20.0, None, 6).state,
            "outer_race"
        );
        let s = feed(&[0.2, 0.6, 0.1, 0.1], 20.0, None, 6);
        assert_eq!(s.state, "unknown");
        assert_eq!(s.window.unknown_reason, Some(UnknownReason::Novelty));
    }

    #[test]
    fn novel_windows_near_healthy_stay_unknown() {
        // Inside the healthy baseline a novel window is never called healthy nor a fault.
        let s = feed(&[0.95, 0.03, 0.01, 0.01], 20.0, Some(false), 6);
        assert_eq!(s.state, "unknown");
        assert_eq!(s.window.unknown_reason, Some(UnknownReason::Novelty));
        let s = feed(&[0.05, 0.92, 0.02, 0.01], 20.0, Some(false), 6);
        assert_eq!(
            s.state, "outer_race",
            "a confident fault is an alarm on its own"
        );
        // A healthy, familiar window stays healthy and carries no flag.
        let s = feed(&[0.97, 0.01, 0.01, 0.01], 2.0, Some(false), 6);
        assert_eq!(
            (s.state.as_str(), s.window.alarm_despite),
            ("healthy", None)
        );
    }

    /// Feed `n` windows whose speed is uncertain, each with excess kurtosis `k` over 12 000
    /// samples against a healthy baseline near Gaussian; returns every answer.
    fn uncertain_run(k: f32, n: usize) -> Vec<Smoothed> {
        use crate::model::impulsiveness::ImpulseBaseline;
        let labels = labels();
        let b = ImpulseBaseline::fit(&[0.01, -0.02, 0.03, 0.0, -0.01]).unwrap();
        let mut sm = HealthStateMachine::new(HealthPolicy::default(), &labels).unwrap();
        let p = probs_for("healthy");
        (0..n)
            .map(|i| {
                sm.observe(
                    1.0 + 0.5 * i as f64,
                    &WindowInput {
                        labels: &labels,
                        probs: &p,
                        novelty: 0.1,
                        model_novelty_threshold: 1.0,
                        quality: Some(QualityFlag::SpeedUncertain),
                        beyond_baseline: None,
                        evidence: None,
                        impulse: Some(b.impulse(k, 12_000)),
                        rule: None,
                    },
                )
            })
            .collect()
    }

    #[test]
    fn a_record_of_impulsive_windows_without_a_speed_ends_in_an_alarm() {
        // excess kurtosis 35 (issue 34's inner race at 1000-1400 rpm), every window's speed
        // uncertain: the impulsiveness accumulates and the state reaches a fault
        let out = uncertain_run(35.0, 8);
        let last = out.last().unwrap();
        assert_eq!(last.state, "outer_race", "{:?}", states(&out));
        assert_eq!(last.window.basis, Basis::Impulsive);
        assert_eq!(last.window.alarm_despite, Some(UnknownReason::BadQuality));
        // Gaussian-like windows with an uncertain speed: never an alarm, unknown
        let out = uncertain_run(0.05, 8);
        assert!(out.iter().all(|s| s.state == UNKNOWN), "{:?}", states(&out));
    }

    /// Windows the classifier calls healthy, each with indicators at `level` x the healthy
    /// RMS; returns every answer.
    fn departing_run(levels: &[f32]) -> Vec<Smoothed> {
        use crate::model::departure::MEDIAN_OF;
        let ind = |level: f32, i: usize| Indicators {
            rms: level * (1.0 + 0.01 * (i % 3) as f32),
            crest: 3.0,
            kurtosis: 0.0,
            resonance: 0.5 * level,
            samples: 2560,
        };
        let healthy: Vec<Indicators> = (0..60).map(|i| ind(1.0, i)).collect();
        let labels = labels();
        let mut sm = HealthStateMachine::new(HealthPolicy::default(), &labels).unwrap();
        sm.set_indicator_baseline(crate::model::departure::fit_baseline(&healthy, MEDIAN_OF));
        let p = probs_for("healthy");
        levels
            .iter()
            .enumerate()
            .map(|(i, &level)| {
                let w = WindowInput {
                    labels: &labels,
                    probs: &p,
                    novelty: 0.1,
                    model_novelty_threshold: 1.0,
                    quality: None,
                    beyond_baseline: None,
                    evidence: None,
                    impulse: None,
                    rule: None,
                };
                sm.observe_indicators(10.0 * (i + 1) as f64, &w, Some(&ind(level, i)))
            })
            .collect()
    }

    #[test]
    fn once_the_indicators_have_departed_the_state_is_a_fault_and_stays_one() {
        // healthy, 80 windows at 3x the RMS, then healthy again: the classifier says healthy
        // throughout, the state is held at a fault from the departure on
        let mut levels = vec![1.0f32; 60];
        levels.extend([3.0; 80]);
        levels.extend([1.0; 40]);
        let out = departing_run(&levels);
        let first = out
            .iter()
            .position(|s| s.state == UNNAMED_FAULT)
            .expect("departed");
        assert_eq!(first, 60 + 15 + 29, "{:?}", states(&out));
        assert!(out[first].changed && out[first].since_s == 10.0 * (first + 1) as f64);
        assert!(out[..first].iter().all(|s| s.state != UNNAMED_FAULT));
        assert!(
            out[first..].iter().all(|s| s.state == UNNAMED_FAULT),
            "{:?}",
            states(&out)
        );
        assert!(out[first + 1..].iter().all(|s| !s.changed));
        let d = out.last().unwrap().departure.unwrap();
        assert_eq!(d.departed_since_s, Some(10.0 * (first + 1) as f64));
        // a burst of 15 loud windows never departs
        let mut levels = vec![1.0f32; 60];
        levels.extend([30.0; 15]);
        levels.extend([1.0; 60]);
        let out = departing_run(&levels);
        assert!(out
            .iter()
            .all(|s| s.state == "healthy" || s.state == UNKNOWN));
    }

    #[test]
    fn invalid_policies_are_rejected_with_the_key() {
        let e = HealthStateMachine::new(
            HealthPolicy {
                vote_k: 2,
                vote_n: 4,
                ..Default::default()
            },
            &labels(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("health.vote_k"), "{e}");
        let e =
            HealthStateMachine::new(HealthPolicy::default(), &["unknown".to_string()]).unwrap_err();
        assert!(e.to_string().contains("reserved"), "{e}");
    }

    #[test]
    fn reconfigure_keeps_history_for_same_labels() {
        let labels = labels();
        let mut sm = HealthStateMachine::new(HealthPolicy::default(), &labels).unwrap();
        let p = probs_for("ball");
        for i in 0..3 {
            sm.observe(
                i as f64,
                &WindowInput {
                    labels: &labels,
                    probs: &p,
                    novelty: 0.0,
                    model_novelty_threshold: 1.0,
                    quality: None,
                    beyond_baseline: None,
                    evidence: None,
                    impulse: None,
                    rule: None,
                },
            );
        }
        assert_eq!(sm.state(), "ball");
        sm.reconfigure(
            HealthPolicy {
                dwell_s: 3.0,
                ..Default::default()
            },
            &labels,
        )
        .unwrap();
        assert_eq!(sm.state(), "ball");
        sm.reconfigure(HealthPolicy::default(), &labels[..2])
            .unwrap();
        assert_eq!(sm.state(), "unknown");
    }
}
