//! Whole-record scoring of a classifier on labelled recordings: per-window accuracy,
//! whole-record accuracy (majority vote of the windows), balanced accuracy (mean recall over
//! the classes present), confusion matrices, the unknown rate and the alarm counts (missed
//! alarms: a faulty record called healthy; false alarms: a healthy record called faulty).
//! Pure arithmetic on per-window outcomes, so training, fine-tuning and `rigmon evaluate`
//! share it. For a model file the windows' classes are the daemon's own window verdicts and
//! the record carries the state the daemon ends in ([`DaemonOutcome`], made by
//! [`crate::train::score`] through the daemon's verdict and health state machine): a faulty
//! record the daemon leaves `healthy` or `unknown` is a missed alarm even when the majority
//! vote names its fault, so `evaluate` and `rigmon run` cannot disagree.

use crate::health::UNKNOWN;
use crate::vocabulary::Condition;
use serde::Serialize;

/// Per-window outcomes of one labelled recording.
#[derive(Debug, Clone)]
pub struct RecordOutcome {
    pub path: String,
    /// True class index (into the label list).
    pub label: usize,
    /// Class index per window that has a class (a window whose quality forbids a verdict has
    /// none and votes for nothing).
    pub predicted: Vec<usize>,
    /// Per such window: its state is `unknown` (novel or doubtful and not clearly a fault).
    pub unknown: Vec<bool>,
    /// Mean rpm of the recording (reported only).
    pub rpm: f64,
    /// What the daemon's verdict and health state machine make of the windows (None when the
    /// outcomes do not come from a model file, e.g. the rule baseline).
    pub daemon: Option<DaemonOutcome>,
}

/// A record's windows as the daemon judges them (its verdict and health state machine).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DaemonOutcome {
    /// The smoothed state after the record's last window.
    pub state: String,
    /// Windows whose state is `unknown` for novelty or low confidence.
    pub unknown_windows: usize,
    /// Windows whose data quality forbids a verdict (`unknown`, `bad_quality`).
    pub bad_quality_windows: usize,
    /// Windows kept as a fault although novel or doubtful (`alarm_despite` in the message).
    pub alarm_despite_windows: usize,
    /// Windows whose class the fault-family evidence decided, overruling the classifier.
    pub evidence_windows: usize,
    /// Windows an impulsive signal made an alarm, overruling a `healthy` classifier.
    pub impulsive_windows: usize,
    /// Every window's state, in order (what `replay --json` prints as `window_state`).
    pub window_states: Vec<String>,
}

/// A confusion matrix: `matrix[true][predicted]`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Confusion {
    pub labels: Vec<String>,
    pub matrix: Vec<Vec<usize>>,
}

impl Confusion {
    pub fn new(labels: &[String]) -> Self {
        Confusion {
            labels: labels.to_vec(),
            matrix: vec![vec![0; labels.len()]; labels.len()],
        }
    }

    /// Fraction on the diagonal.
    pub fn accuracy(&self) -> f64 {
        let total: usize = self.matrix.iter().flatten().sum();
        let diag: usize = (0..self.labels.len()).map(|i| self.matrix[i][i]).sum();
        if total == 0 {
            f64::NAN
        } else {
            diag as f64 / total as f64
        }
    }

    /// Mean recall over the classes that occur (rows with at least one entry).
    pub fn balanced_accuracy(&self) -> f64 {
        let recalls: Vec<f64> = self
            .matrix
            .iter()
            .enumerate()
            .filter_map(|(i, row)| {
                let n: usize = row.iter().sum();
                (n > 0).then(|| row[i] as f64 / n as f64)
            })
            .collect();
        if recalls.is_empty() {
            f64::NAN
        } else {
            recalls.iter().sum::<f64>() / recalls.len() as f64
        }
    }
}

/// One recording in the report.
#[derive(Debug, Clone, Serialize)]
pub struct RecordResult {
    pub path: String,
    pub label: String,
    /// Majority vote of the windows with a class (see [`majority`]); `unknown` when no window
    /// has one.
    pub predicted: String,
    pub correct: bool,
    /// Windows with a class (those voting).
    pub windows: usize,
    pub window_accuracy: f64,
    /// Fraction of windows whose novelty score exceeded the threshold.
    pub unknown_rate: f64,
    /// Windows per predicted class (in label order).
    pub votes: Vec<usize>,
    pub rpm: f64,
    /// The daemon's smoothed state after the record's last window (default `[health]`
    /// policy); null for the rule baseline.
    pub state: Option<String>,
    /// Fraction of windows the daemon calls `unknown` (any reason), and of windows it keeps
    /// as a fault although novel or doubtful; null for the rule baseline.
    pub daemon_unknown_rate: Option<f64>,
    pub alarm_despite_rate: Option<f64>,
    /// Windows the daemon calls `unknown` for their data quality, windows whose class the
    /// fault-family evidence decided, and windows an impulsive signal made an alarm; null for
    /// the rule baseline.
    pub bad_quality_windows: Option<usize>,
    pub evidence_windows: Option<usize>,
    pub impulsive_windows: Option<usize>,
    /// The daemon's state of every window, in order (empty for the rule baseline).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub window_states: Vec<String>,
    /// Counted in `missed_alarms` / `false_alarms` (majority vote or daemon state).
    pub missed_alarm: bool,
    pub false_alarm: bool,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    pub labels: Vec<String>,
    pub n_records: usize,
    pub n_windows: usize,
    /// Whole-record accuracy (majority vote).
    pub record_accuracy: f64,
    /// Mean recall over the classes present, whole-record.
    pub balanced_accuracy: f64,
    /// Per-window accuracy.
    pub window_accuracy: f64,
    /// Mean recall over the classes present, per window.
    pub window_balanced_accuracy: f64,
    /// Fraction of the windows with a class whose state is `unknown` (novel or doubtful).
    pub unknown_rate: f64,
    /// Windows whose data quality forbids a verdict (not in the window figures).
    pub bad_quality_windows: usize,
    /// Faulty records (any label but `healthy`) called healthy by the majority vote, or left
    /// `healthy` or `unknown` by the daemon's state machine (no alarm for the user). Calling a
    /// fault another fault is wrong but still an alarm, so it is not counted here.
    pub missed_alarms: usize,
    /// Healthy records called anything but healthy by the majority vote, or put in a fault
    /// state by the daemon.
    pub false_alarms: usize,
    /// The same from the majority vote alone (what `missed_alarms` / `false_alarms` counted
    /// before the daemon's state was scored).
    pub majority_missed_alarms: usize,
    pub majority_false_alarms: usize,
    /// Records whose daemon state ends `unknown` (faulty ones are also missed alarms).
    pub unknown_states: usize,
    /// The same per window.
    pub window_missed_alarms: usize,
    pub window_false_alarms: usize,
    /// Whole-record confusion matrix.
    pub confusion: Confusion,
    /// Per-window confusion matrix.
    pub window_confusion: Confusion,
    pub records: Vec<RecordResult>,
}

impl Evaluation {
    /// The whole-record picture's title and note: the balanced accuracy, and the missed and
    /// false alarms (by the state the daemon ends in too, which the matrix of majority votes
    /// does not show).
    pub fn record_caption(&self, name: &str) -> (String, String) {
        (
            format!(
                "{name}: whole records (balanced acc. {:.1} %)",
                100.0 * self.balanced_accuracy
            ),
            format!(
                "missed alarms {}, false alarms {}",
                self.missed_alarms, self.false_alarms
            ),
        )
    }

    /// The window picture's title and note.
    pub fn window_caption(&self, name: &str) -> (String, String) {
        (
            format!(
                "{name}: windows (acc. {:.1} %)",
                100.0 * self.window_accuracy
            ),
            format!(
                "missed alarms {}, false alarms {}",
                self.window_missed_alarms, self.window_false_alarms
            ),
        )
    }
}

/// Majority vote: the class with the most windows; among equal counts the lowest class index.
pub fn majority(predicted: &[usize], n_classes: usize) -> (usize, Vec<usize>) {
    let mut votes = vec![0usize; n_classes];
    for &p in predicted {
        votes[p] += 1;
    }
    let best = (0..n_classes).fold(0, |b, c| if votes[c] > votes[b] { c } else { b });
    (best, votes)
}

/// (missed, false) alarms from a confusion matrix: faulty called healthy, healthy called
/// faulty. Both 0 when there is no `healthy` class.
pub fn alarms(cm: &Confusion) -> (usize, usize) {
    let Some(h) = Condition::Healthy.index_in(&cm.labels) else {
        return (0, 0);
    };
    let missed = (0..cm.labels.len())
        .filter(|&t| t != h)
        .map(|t| cm.matrix[t][h])
        .sum();
    let false_ = (0..cm.labels.len())
        .filter(|&p| p != h)
        .map(|p| cm.matrix[h][p])
        .sum();
    (missed, false_)
}

/// (missed, false) alarm of one record: the majority vote `pred` or the daemon's state says
/// healthy (or `unknown`) for a faulty record, or names a fault for a healthy one. Both false
/// when there is no `healthy` class.
fn record_alarms(
    labels: &[String],
    label: usize,
    pred: Option<usize>,
    daemon: Option<&DaemonOutcome>,
) -> (bool, bool) {
    let Some(h) = Condition::Healthy.index_in(labels) else {
        return (false, false);
    };
    let state = daemon.map(|d| d.state.as_str());
    // `pred` None: no window had a class, so no vote raised an alarm
    if label == h {
        let daemon_fault = state.is_some_and(|s| s != UNKNOWN && s != labels[h]);
        (false, pred.is_some_and(|p| p != h) || daemon_fault)
    } else {
        let daemon_silent = state.is_some_and(|s| s == UNKNOWN || s == labels[h]);
        (pred.is_none_or(|p| p == h) || daemon_silent, false)
    }
}

/// Score per-window outcomes of labelled recordings.
pub fn score(labels: &[String], outcomes: &[RecordOutcome]) -> Evaluation {
    let k = labels.len();
    let mut rec_cm = Confusion::new(labels);
    let mut win_cm = Confusion::new(labels);
    let (mut n_unknown, mut n_windows, mut n_bad) = (0usize, 0usize, 0usize);
    let (mut n_missed, mut n_false, mut n_unknown_states) = (0usize, 0usize, 0usize);
    let mut records = Vec::new();
    for o in outcomes {
        for &p in &o.predicted {
            win_cm.matrix[o.label][p] += 1;
        }
        let (pred, votes) = majority(&o.predicted, k);
        let pred = (!o.predicted.is_empty()).then_some(pred);
        if let Some(p) = pred {
            rec_cm.matrix[o.label][p] += 1;
        }
        let unk = o.unknown.iter().filter(|&&u| u).count();
        n_unknown += unk;
        n_windows += o.predicted.len();
        let daemon = o.daemon.as_ref();
        n_bad += daemon.map_or(0, |d| d.bad_quality_windows);
        let n = o.predicted.len().max(1) as f64;
        let (missed_alarm, false_alarm) = record_alarms(labels, o.label, pred, daemon);
        n_missed += usize::from(missed_alarm);
        n_false += usize::from(false_alarm);
        n_unknown_states += usize::from(daemon.is_some_and(|d| d.state == UNKNOWN));
        records.push(RecordResult {
            path: o.path.clone(),
            label: labels[o.label].clone(),
            predicted: pred.map_or(UNKNOWN.to_string(), |p| labels[p].clone()),
            correct: pred == Some(o.label),
            windows: o.predicted.len(),
            window_accuracy: votes[o.label] as f64 / n,
            unknown_rate: unk as f64 / n,
            votes,
            rpm: o.rpm,
            state: daemon.map(|d| d.state.clone()),
            daemon_unknown_rate: daemon.map(|d| d.unknown_windows as f64 / n),
            alarm_despite_rate: daemon.map(|d| d.alarm_despite_windows as f64 / n),
            bad_quality_windows: daemon.map(|d| d.bad_quality_windows),
            evidence_windows: daemon.map(|d| d.evidence_windows),
            impulsive_windows: daemon.map(|d| d.impulsive_windows),
            window_states: daemon.map(|d| d.window_states.clone()).unwrap_or_default(),
            missed_alarm,
            false_alarm,
        });
    }
    let (majority_missed_alarms, majority_false_alarms) = alarms(&rec_cm);
    let (window_missed_alarms, window_false_alarms) = alarms(&win_cm);
    Evaluation {
        labels: labels.to_vec(),
        n_records: outcomes.len(),
        n_windows,
        record_accuracy: rec_cm.accuracy(),
        balanced_accuracy: rec_cm.balanced_accuracy(),
        window_accuracy: win_cm.accuracy(),
        window_balanced_accuracy: win_cm.balanced_accuracy(),
        unknown_rate: if n_windows == 0 {
            f64::NAN
        } else {
            n_unknown as f64 / n_windows as f64
        },
        bad_quality_windows: n_bad,
        missed_alarms: n_missed,
        false_alarms: n_false,
        majority_missed_alarms,
        majority_false_alarms,
        unknown_states: n_unknown_states,
        window_missed_alarms,
        window_false_alarms,
        confusion: rec_cm,
        window_confusion: win_cm,
        records,
    }
}

/// Human-readable summary (several lines).
pub fn summary(e: &Evaluation) -> String {
    let pct = |v: f64| {
        if v.is_nan() {
            "n/a".to_string()
        } else {
            format!("{:.1} %", 100.0 * v)
        }
    };
    let mut s = String::new();
    s += &format!(
        "records: {}  windows: {}\nwhole-record accuracy: {}   balanced (records): {}\nwindow accuracy: {}   balanced (windows): {}   unknown rate: {}\n",
        e.n_records,
        e.n_windows,
        pct(e.record_accuracy),
        pct(e.balanced_accuracy),
        pct(e.window_accuracy),
        pct(e.window_balanced_accuracy),
        pct(e.unknown_rate)
    );
    s += &format!(
        "missed alarms (faulty record called healthy): {}   false alarms (healthy record called faulty): {}   (windows: {} / {})\n",
        e.missed_alarms, e.false_alarms, e.window_missed_alarms, e.window_false_alarms
    );
    if e.bad_quality_windows > 0 {
        s += &format!(
            "windows unknown for their data quality (no vote): {}\n",
            e.bad_quality_windows
        );
    }
    if e.records.iter().any(|r| r.state.is_some()) {
        s += &format!(
            "daemon states (default [health]): {} record(s) end unknown; majority vote alone: {} missed, {} false alarms\n",
            e.unknown_states, e.majority_missed_alarms, e.majority_false_alarms
        );
        for r in e
            .records
            .iter()
            .filter(|r| r.state.as_deref() != Some(&r.predicted))
        {
            s += &format!(
                "  {}: majority {}, daemon state {}\n",
                r.path,
                r.predicted,
                r.state.as_deref().unwrap_or("-")
            );
        }
    }
    for (title, cm) in [
        ("whole-record confusion", &e.confusion),
        ("window confusion", &e.window_confusion),
    ] {
        s += &format!("{title} (rows = true, columns = predicted):\n{:>12}", "");
        for l in &cm.labels {
            s += &format!(" {:>11}", l);
        }
        s += "\n";
        for (l, row) in cm.labels.iter().zip(&cm.matrix) {
            s += &format!("{:>12}", l);
            for v in row {
                s += &format!(" {:>11}", v);
            }
            s += "\n";
        }
    }
    s
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

    #[test]
    fn whole_record_majority_and_balanced_accuracy() {
        let o = |label, predicted: Vec<usize>| RecordOutcome {
            path: "x".into(),
            label,
            unknown: vec![false; predicted.len()],
            predicted,
            rpm: 0.0,
            daemon: None,
        };
        let outcomes = vec![
            o(0, vec![0, 0, 1]), // healthy, right by majority
            o(1, vec![1, 1, 1, 1]),
            o(1, vec![2, 2, 1]), // outer predicted inner: wrong
            o(2, vec![2]),
        ];
        let e = score(&labels(), &outcomes);
        assert_eq!(e.record_accuracy, 0.75);
        // recalls: healthy 1, outer 0.5, inner 1
        assert!((e.balanced_accuracy - (2.5 / 3.0)).abs() < 1e-12);
        assert!((e.window_accuracy - 8.0 / 11.0).abs() < 1e-12);
        assert_eq!(
            e.confusion.matrix,
            vec![vec![1, 0, 0], vec![0, 1, 1], vec![0, 0, 1]]
        );
        assert_eq!(e.records[2].predicted, "inner_race");
        // outer called inner is an alarm, not a miss; one healthy window called outer
        assert_eq!((e.missed_alarms, e.false_alarms), (0, 0));
        assert_eq!((e.window_missed_alarms, e.window_false_alarms), (0, 1));
    }

    #[test]
    fn missed_and_false_alarms_are_counted_per_record() {
        let o = |label, predicted: Vec<usize>| RecordOutcome {
            path: "x".into(),
            label,
            unknown: vec![false; predicted.len()],
            predicted,
            rpm: 0.0,
            daemon: None,
        };
        let outcomes = vec![
            o(0, vec![2, 2, 0]), // healthy called inner: false alarm
            o(1, vec![0, 0, 1]), // outer called healthy: missed
            o(2, vec![0, 0]),    // inner called healthy: missed
            o(2, vec![1, 1]),    // inner called outer: an alarm all the same
        ];
        let e = score(&labels(), &outcomes);
        assert_eq!((e.missed_alarms, e.false_alarms), (2, 1));
        assert_eq!((e.window_missed_alarms, e.window_false_alarms), (4, 2));
        assert!(summary(&e).contains("missed alarms (faulty record called healthy): 2"));
    }

    #[test]
    fn classes_absent_do_not_count_in_balanced_accuracy() {
        let o = RecordOutcome {
            path: "x".into(),
            label: 2,
            predicted: vec![2, 2],
            unknown: vec![true, false],
            rpm: 0.0,
            daemon: None,
        };
        let e = score(&labels(), &[o]);
        assert_eq!(e.balanced_accuracy, 1.0);
        assert_eq!(e.unknown_rate, 0.5);
    }

    #[test]
    fn a_faulty_record_the_daemon_leaves_unknown_is_a_missed_alarm() {
        let labels = labels();
        let daemon = |state: &str, unknown_windows| DaemonOutcome {
            state: state.into(),
            unknown_windows,
            ..DaemonOutcome::default()
        };
        let rec = |label, daemon| RecordOutcome {
            path: "x".into(),
            label,
            predicted: vec![if label == 0 { 0 } else { 1 }; 19],
            unknown: vec![true; 19],
            rpm: 0.0,
            daemon: Some(daemon),
        };
        let e = score(
            &labels,
            &[
                rec(1, daemon("unknown", 19)),
                rec(1, daemon("outer_race", 0)),
                rec(0, daemon("healthy", 0)),
            ],
        );
        // The votes say outer race for both faulty records; the daemon stays silent on one.
        assert_eq!(e.record_accuracy, 1.0);
        assert_eq!((e.majority_missed_alarms, e.majority_false_alarms), (0, 0));
        assert_eq!(
            (e.missed_alarms, e.false_alarms, e.unknown_states),
            (1, 0, 1)
        );
        assert!(e.records[0].missed_alarm && !e.records[1].missed_alarm);
        assert_eq!(e.records[1].state.as_deref(), Some("outer_race"));
        assert_eq!(e.records[2].state.as_deref(), Some("healthy"));
        assert!(summary(&e).contains("daemon state unknown"));
    }

    #[test]
    fn a_record_without_a_verdict_raises_no_alarm() {
        // every window of a faulty record was clipped: no class, the daemon says unknown
        let o = RecordOutcome {
            path: "clipped".into(),
            label: 2,
            predicted: vec![],
            unknown: vec![],
            rpm: 0.0,
            daemon: Some(DaemonOutcome {
                state: "unknown".into(),
                bad_quality_windows: 7,
                ..DaemonOutcome::default()
            }),
        };
        let e = score(&labels(), &[o]);
        assert_eq!(e.records[0].predicted, "unknown");
        assert!(!e.records[0].correct && e.records[0].missed_alarm);
        assert_eq!((e.missed_alarms, e.bad_quality_windows), (1, 7));
        assert_eq!(e.confusion.matrix.iter().flatten().sum::<usize>(), 0);
    }
}
