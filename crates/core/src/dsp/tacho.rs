//! Analog tacho -> pulse edge times: a Schmitt trigger (threshold with hysteresis) finds
//! rising edges, and each edge time is placed where the signal crosses the threshold, by
//! linear interpolation between the two samples around the crossing (sub-sample accuracy).
//! Works on one block or streamed block by block (state carries over).

/// Streaming rising-edge detector for an analog tacho channel.
#[derive(Debug, Clone)]
pub struct EdgeDetector {
    level: f32,
    hi: f32,
    lo: f32,
    sample_rate: f64,
    /// Above the upper switching level since the last rising edge.
    high: bool,
    started: bool,
    prev: f32,
    /// Index of the next sample to arrive (counts across blocks).
    next_index: u64,
    /// Latest upward crossing of `level` (fractional sample index) not yet confirmed.
    candidate: Option<f64>,
}

impl EdgeDetector {
    /// `threshold` is the switching level (edge times are its crossings); the trigger arms
    /// below `threshold - hysteresis` and fires above `threshold + hysteresis`.
    pub fn new(threshold: f64, hysteresis: f64, sample_rate: f64) -> Self {
        let h = hysteresis.abs() as f32;
        EdgeDetector {
            level: threshold as f32,
            hi: threshold as f32 + h,
            lo: threshold as f32 - h,
            sample_rate,
            high: false,
            started: false,
            prev: 0.0,
            next_index: 0,
            candidate: None,
        }
    }

    /// Feed the next block of samples; rising-edge times (s since the first sample ever fed)
    /// are appended to `edges`. Non-finite samples are skipped (they never switch the trigger).
    pub fn push(&mut self, block: &[f32], edges: &mut Vec<f64>) {
        self.run(block, |t, _| edges.push(t));
    }

    /// [`push`](Self::push), with each edge's time and the index (counted from the first
    /// sample ever fed) of the sample that confirmed it: an edge is known once that sample
    /// has arrived, whatever the block boundaries.
    pub fn push_indexed(&mut self, block: &[f32], edges: &mut Vec<(f64, u64)>) {
        self.run(block, |t, k| edges.push((t, k)));
    }

    fn run(&mut self, block: &[f32], mut emit: impl FnMut(f64, u64)) {
        for &x in block {
            let k = self.next_index;
            self.next_index += 1;
            if !x.is_finite() {
                continue;
            }
            if !self.started {
                self.started = true;
                self.high = x >= self.level;
                self.prev = x;
                continue;
            }
            if !self.high {
                if self.prev < self.level && x >= self.level {
                    let frac = ((self.level - self.prev) / (x - self.prev)) as f64;
                    self.candidate = Some((k - 1) as f64 + frac);
                }
                if x >= self.hi {
                    self.high = true;
                    if let Some(c) = self.candidate.take() {
                        emit(c / self.sample_rate, k);
                    }
                }
            } else if x <= self.lo {
                self.high = false;
                self.candidate = None;
            }
            self.prev = x;
        }
    }
}

/// Rising-edge times (s) of a whole analog tacho record.
pub fn detect_edges(
    samples: &[f32],
    sample_rate: f64,
    threshold: f64,
    hysteresis: f64,
) -> Vec<f64> {
    let mut det = EdgeDetector::new(threshold, hysteresis, sample_rate);
    let mut edges = Vec::new();
    det.push(samples, &mut edges);
    edges
}

/// A threshold half-way between the 1st and 99th percentile levels, with 10 % hysteresis:
/// for tacho channels whose voltage levels are not configured.
pub fn auto_threshold(samples: &[f32]) -> Option<(f64, f64)> {
    let mut v: Vec<f32> = samples.iter().copied().filter(|x| x.is_finite()).collect();
    if v.len() < 4 {
        return None;
    }
    v.sort_unstable_by(|a, b| a.total_cmp(b));
    let lo = v[v.len() / 100] as f64;
    let hi = v[v.len() - 1 - v.len() / 100] as f64;
    (hi > lo).then_some((0.5 * (lo + hi), 0.1 * (hi - lo)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A TTL-like pulse train with finite rise time, edges at known fractional positions.
    fn pulses(fs: f64, edge_times: &[f64], n: usize) -> Vec<f32> {
        let rise = 3.0 / fs; // three samples from 0 to 5 V
        (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                let mut v = 0.0;
                for &e in edge_times {
                    // linear ramp centred on e, pulse 2 ms wide
                    let up = ((t - e) / rise + 0.5).clamp(0.0, 1.0);
                    let down = ((t - e - 0.002) / rise + 0.5).clamp(0.0, 1.0);
                    v += 5.0 * (up - down);
                }
                v as f32
            })
            .collect()
    }

    #[test]
    fn edges_are_interpolated_to_sub_sample_accuracy() {
        let fs = 10_000.0;
        let truth: Vec<f64> = (0..20)
            .map(|k| 0.0123 + k as f64 * 0.0987 + 0.37e-4 * k as f64)
            .collect();
        let x = pulses(fs, &truth, 21_000);
        let got = detect_edges(&x, fs, 2.5, 0.5);
        assert_eq!(got.len(), truth.len());
        for (g, t) in got.iter().zip(&truth) {
            assert!(
                (g - t).abs() * fs < 0.01,
                "edge at {g} vs {t}: {} samples off",
                (g - t) * fs
            );
        }
    }

    #[test]
    fn streaming_in_blocks_matches_one_pass_and_noise_does_not_double_count() {
        let fs = 10_000.0;
        let truth: Vec<f64> = (0..10).map(|k| 0.005 + k as f64 * 0.05).collect();
        let mut x = pulses(fs, &truth, 6000);
        // ripple of +-0.3 V around the threshold region does not create extra edges
        for (i, v) in x.iter_mut().enumerate() {
            *v += 0.3 * ((i as f32) * 2.1).sin();
        }
        let whole = detect_edges(&x, fs, 2.5, 0.5);
        let mut det = EdgeDetector::new(2.5, 0.5, fs);
        let mut blocks = Vec::new();
        for b in x.chunks(333) {
            det.push(b, &mut blocks);
        }
        assert_eq!(whole.len(), truth.len());
        assert_eq!(whole, blocks);
    }

    #[test]
    fn auto_threshold_sits_between_levels() {
        let edges: Vec<f64> = (0..20).map(|k| 0.01 + 0.05 * k as f64).collect();
        let x = pulses(10_000.0, &edges, 10_000);
        let (t, h) = auto_threshold(&x).unwrap();
        assert!((t - 2.5).abs() < 0.01 && (h - 0.5).abs() < 0.01, "{t} {h}");
    }
}
