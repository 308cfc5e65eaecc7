//! Whole-record scoring of a classifier on labelled recordings: per-window accuracy,
//! whole-record accuracy (majority vote of the windows), balanced accuracy (mean recall over
//! the classes present), confusion matrices, the unknown (novelty) rate and the alarm counts
//! (missed alarms: a faulty record called healthy; false alarms: a healthy record called
//! faulty). Pure arithmetic on
//! per-window predictions, so training, fine-tuning and `rigmon evaluate` share it.

use serde::Serialize;

/// Per-window outcomes of one labelled recording.
#[derive(Debug, Clone)]
pub struct RecordOutcome {
    pub path: String,
    /// True class index (into the label list).
    pub label: usize,
    /// Predicted class index per window.
    pub predicted: Vec<usize>,
    /// Novelty flag per window.
    pub unknown: Vec<bool>,
    /// Mean rpm of the recording (reported only).
    pub rpm: f64,
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
    /// Majority vote of the windows (see [`majority`]).
    pub predicted: String,
    pub correct: bool,
    pub windows: usize,
    pub window_accuracy: f64,
    /// Fraction of windows whose novelty score exceeded the threshold.
    pub unknown_rate: f64,
    /// Windows per predicted class (in label order).
    pub votes: Vec<usize>,
    pub rpm: f64,
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
    /// Fraction of windows flagged unknown by the novelty score.
    pub unknown_rate: f64,
    /// Faulty records (any label but `healthy`) called healthy. Calling a fault another
    /// fault is wrong but still an alarm, so it is not counted here.
    pub missed_alarms: usize,
    /// Healthy records called anything but healthy.
    pub false_alarms: usize,
    /// The same per window.
    pub window_missed_alarms: usize,
    pub window_false_alarms: usize,
    /// Whole-record confusion matrix.
    pub confusion: Confusion,
    /// Per-window confusion matrix.
    pub window_confusion: Confusion,
    pub records: Vec<RecordResult>,
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
    let Some(h) = cm.labels.iter().position(|l| l == "healthy") else {
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

/// Score per-window outcomes of labelled recordings.
pub fn score(labels: &[String], outcomes: &[RecordOutcome]) -> Evaluation {
    let k = labels.len();
    let mut rec_cm = Confusion::new(labels);
    let mut win_cm = Confusion::new(labels);
    let (mut n_unknown, mut n_windows) = (0usize, 0usize);
    let mut records = Vec::new();
    for o in outcomes {
        for &p in &o.predicted {
            win_cm.matrix[o.label][p] += 1;
        }
        let (pred, votes) = majority(&o.predicted, k);
        rec_cm.matrix[o.label][pred] += 1;
        let unk = o.unknown.iter().filter(|&&u| u).count();
        n_unknown += unk;
        n_windows += o.predicted.len();
        let n = o.predicted.len().max(1) as f64;
        records.push(RecordResult {
            path: o.path.clone(),
            label: labels[o.label].clone(),
            predicted: labels[pred].clone(),
            correct: pred == o.label,
            windows: o.predicted.len(),
            window_accuracy: votes[o.label] as f64 / n,
            unknown_rate: unk as f64 / n,
            votes,
            rpm: o.rpm,
        });
    }
    let (missed_alarms, false_alarms) = alarms(&rec_cm);
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
        missed_alarms,
        false_alarms,
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
        };
        let e = score(&labels(), &[o]);
        assert_eq!(e.balanced_accuracy, 1.0);
        assert_eq!(e.unknown_rate, 0.5);
    }
}
