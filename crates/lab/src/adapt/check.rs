//! Adapt checks itself: every labelled recording it was given (measured and held out) has
//! been scored by the zero-shot model, the adapted model and the rule through the scoring
//! code `rigmon evaluate` uses ([`crate::train::score`], [`crate::evaluate::score`]). A
//! labelled fault the adapted model misses (the daemon's final state for it is healthy or
//! unknown, or its majority vote is healthy: [`crate::evaluate::RecordResult::missed_alarm`])
//! is a regression, worse still when the zero-shot model caught it. `adapt` then keeps the
//! model out of `model.onnx` (it is written as [`REJECTED_MODEL`]) and exits non-zero, unless
//! `--accept-regression` is given; either way the report and stderr say so.

use super::SetScores;
use crate::vocabulary::Condition;
use serde::Serialize;

/// Where a model that failed the self-check is written instead of `model.onnx`.
pub const REJECTED_MODEL: &str = "model.rejected.onnx";

/// One labelled fault the adapted model misses.
#[derive(Debug, Clone, Serialize)]
pub struct Regression {
    /// `measured` or `held out`.
    pub set: String,
    pub recording: String,
    pub label: String,
    /// The adapted model's whole-record call and the daemon's final state.
    pub after: String,
    /// The zero-shot model's.
    pub before: String,
    /// The zero-shot model raised an alarm on it (the adapted model lost what it had).
    pub zero_shot_caught_it: bool,
    /// The rule's call.
    pub rule: String,
}

impl Regression {
    /// One line for stderr and the report.
    pub fn line(&self) -> String {
        format!(
            "{} recording {} (labelled {}): the adapted model misses it ({}){}; rule: {}",
            self.set,
            self.recording,
            self.label,
            self.after,
            if self.zero_shot_caught_it {
                format!(", the zero-shot model caught it ({})", self.before)
            } else {
                format!(", the zero-shot model missed it too ({})", self.before)
            },
            self.rule
        )
    }
}

/// The outcome of the self-check.
#[derive(Debug, Clone, Serialize)]
pub struct SelfCheck {
    pub regressions: Vec<Regression>,
    /// Labelled recordings checked (faulty ones among them).
    pub checked: usize,
    pub faulty: usize,
    /// `--accept-regression` was given.
    pub accepted_by_flag: bool,
    /// The file the adapted model was written to.
    pub model_file: String,
}

impl SelfCheck {
    /// The model may be used as `model.onnx`.
    pub fn passed(&self) -> bool {
        self.regressions.is_empty()
    }
}

fn call(r: &crate::evaluate::RecordResult) -> String {
    match &r.state {
        Some(s) => format!("called {}, final state {s}", r.predicted),
        None => format!("called {}", r.predicted),
    }
}

/// The labelled faults of one scored set that the adapted model misses.
pub fn regressions(set: &str, s: &SetScores) -> (Vec<Regression>, usize, usize) {
    let find = |e: &crate::evaluate::Evaluation, path: &str| {
        e.records
            .iter()
            .find(|r| r.path == path)
            .map(|r| (call(r), r.missed_alarm))
    };
    let mut out = Vec::new();
    let mut faulty = 0;
    for a in &s.after.records {
        if Condition::is_healthy(&a.label) {
            continue;
        }
        faulty += 1;
        if !a.missed_alarm {
            continue;
        }
        let (before, before_missed) =
            find(&s.before, &a.path).unwrap_or(("not scored".into(), true));
        out.push(Regression {
            set: set.to_string(),
            recording: a.path.clone(),
            label: a.label.clone(),
            after: call(a),
            before,
            zero_shot_caught_it: !before_missed,
            rule: find(&s.rule, &a.path).map_or_else(|| "not scored".into(), |r| r.0),
        });
    }
    (out, s.after.records.len(), faulty)
}
