//! Splits BY RECORDING: every window of a recording lands on the same side, so overlapping
//! windows can never leak between training and validation (or fine-tuning and test).
//! Stratified by label and seeded.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use std::collections::BTreeMap;

/// Indices of recordings on each side.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    pub train: Vec<usize>,
    pub held_out: Vec<usize>,
}

/// Hold out about `fraction` of each label's recordings (at least one when the label has two
/// or more recordings, none when it has only one).
pub fn stratified(labels: &[String], fraction: f64, seed: u64) -> Split {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut by_label: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, l) in labels.iter().enumerate() {
        by_label.entry(l.as_str()).or_default().push(i);
    }
    let (mut train, mut held) = (Vec::new(), Vec::new());
    for (_, mut idx) in by_label {
        idx.shuffle(&mut rng);
        let n = idx.len();
        let k = if n < 2 {
            0
        } else {
            ((fraction * n as f64).round() as usize).clamp(1, n - 1)
        };
        held.extend_from_slice(&idx[..k]);
        train.extend_from_slice(&idx[k..]);
    }
    train.sort_unstable();
    held.sort_unstable();
    Split {
        train,
        held_out: held,
    }
}

/// Pick about `fraction` of all recordings (at least one, never all) at random, regardless of
/// label: the fine-tuning protocol (a small labelled sample of what the plant happens to have).
pub fn sample(n: usize, fraction: f64, seed: u64) -> Split {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut idx: Vec<usize> = (0..n).collect();
    idx.shuffle(&mut rng);
    let k = if n < 2 {
        n
    } else {
        ((fraction * n as f64).round() as usize).clamp(1, n - 1)
    };
    let mut picked = idx[..k].to_vec();
    let mut rest = idx[k..].to_vec();
    picked.sort_unstable();
    rest.sort_unstable();
    Split {
        train: picked,
        held_out: rest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels() -> Vec<String> {
        let mut v = Vec::new();
        for (l, n) in [("healthy", 10), ("outer_race", 20), ("inner_race", 1)] {
            v.extend(std::iter::repeat_n(l.to_string(), n));
        }
        v
    }

    #[test]
    fn stratified_is_disjoint_complete_and_seeded() {
        let l = labels();
        let s = stratified(&l, 0.1, 3);
        let mut all: Vec<usize> = s.train.iter().chain(&s.held_out).copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..l.len()).collect::<Vec<_>>());
        let count = |lab: &str| s.held_out.iter().filter(|&&i| l[i] == lab).count();
        assert_eq!(
            (count("healthy"), count("outer_race"), count("inner_race")),
            (1, 2, 0)
        );
        assert_eq!(s, stratified(&l, 0.1, 3));
        assert_ne!(s, stratified(&l, 0.1, 4));
    }

    #[test]
    fn sample_takes_at_least_one_never_all() {
        assert_eq!(sample(5, 0.1, 1).train.len(), 1);
        assert_eq!(sample(5, 0.99, 1).held_out.len(), 1);
        assert_eq!(sample(20, 0.2, 1).train.len(), 4);
    }
}
