//! Per-window processing latency as a fixed-size histogram: log-spaced buckets from 10 us to
//! 100 s (40 per decade, 2.9 % wide), so a daemon running for months keeps percentiles
//! without growing or allocating. The pipeline records one value per window; `rigmon replay`
//! and `rigmon bench load` report p50/p99.

/// Buckets per decade of milliseconds.
const PER_DECADE: f64 = 40.0;
/// Lower edge of the first bucket, ms.
const MIN_MS: f64 = 0.01;
/// Decades covered (0.01 ms .. 100 000 ms).
const DECADES: usize = 7;
const N: usize = DECADES * PER_DECADE as usize;

/// Counts of latencies per log-spaced bucket.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    counts: Box<[u64; N]>,
    n: u64,
    max_ms: f64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        LatencyHistogram {
            counts: Box::new([0; N]),
            n: 0,
            max_ms: 0.0,
        }
    }
}

impl LatencyHistogram {
    /// Add one latency in milliseconds (values outside the range land in the end buckets).
    pub fn record(&mut self, ms: f64) {
        if !ms.is_finite() {
            return;
        }
        let i = ((ms.max(MIN_MS) / MIN_MS).log10() * PER_DECADE).floor() as usize;
        self.counts[i.min(N - 1)] += 1;
        self.n += 1;
        self.max_ms = self.max_ms.max(ms);
    }

    /// Number of values recorded.
    pub fn len(&self) -> u64 {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Largest value recorded, ms.
    pub fn max(&self) -> f64 {
        self.max_ms
    }

    /// The `p`-quantile (0..=1), ms: the geometric centre of the bucket holding it (NaN when
    /// empty). Accurate to half a bucket, 1.5 %.
    pub fn quantile(&self, p: f64) -> f64 {
        if self.n == 0 {
            return f64::NAN;
        }
        let rank = ((p.clamp(0.0, 1.0) * self.n as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let centre = MIN_MS * 10f64.powf((i as f64 + 0.5) / PER_DECADE);
                return centre.min(self.max_ms);
            }
        }
        self.max_ms
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_the_sorted_values_within_a_bucket() {
        let mut h = LatencyHistogram::default();
        // 1..=1000 ms, uniformly.
        for k in 1..=1000 {
            h.record(k as f64);
        }
        assert_eq!(h.len(), 1000);
        for (p, want) in [(0.5, 500.0), (0.99, 990.0), (0.01, 10.0)] {
            let got = h.quantile(p);
            assert!((got / want - 1.0).abs() < 0.03, "p{p}: {got} vs {want}");
        }
        assert_eq!(h.max(), 1000.0);
    }

    #[test]
    fn empty_is_nan_and_extremes_are_kept_in_range() {
        let mut h = LatencyHistogram::default();
        assert!(h.quantile(0.5).is_nan());
        h.record(1e-9);
        h.record(1e9);
        h.record(f64::NAN);
        assert_eq!(h.len(), 2);
        assert!(h.quantile(0.0) < 0.0105, "{}", h.quantile(0.0));
        // The top bucket ends at 100 s.
        let top = h.quantile(1.0);
        assert!(top > 9.0e4 && top < 1.0e5, "{top}");
    }
}
