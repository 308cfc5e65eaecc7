//! Publish-to-committed latency: for each live row, the time from the daemon's
//! `publish_time_ns` to the commit of the transaction that wrote it, in a fixed histogram
//! (1 ms bins up to 60 s, then one overflow bin) so percentiles cost nothing per row.

use serde::{Deserialize, Serialize};

const BINS: usize = 60_000;

/// The histogram.
#[derive(Debug, Clone)]
pub struct LatencyHistogram {
    bins: Vec<u32>,
    overflow: u64,
    count: u64,
    max_s: f64,
}

/// Percentiles for the status message.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LatencySummary {
    pub count: u64,
    pub p50_s: f64,
    pub p99_s: f64,
    pub max_s: f64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        LatencyHistogram {
            bins: vec![0; BINS],
            overflow: 0,
            count: 0,
            max_s: 0.0,
        }
    }
}

impl LatencyHistogram {
    /// Record one latency (negative ones, from clocks apart, count as 0).
    pub fn add(&mut self, seconds: f64) {
        let s = seconds.max(0.0);
        let ms = (s * 1000.0) as usize;
        match self.bins.get_mut(ms) {
            Some(b) => *b = b.saturating_add(1),
            None => self.overflow += 1,
        }
        self.count += 1;
        self.max_s = self.max_s.max(s);
    }

    /// The `q` quantile (upper edge of its bin), s.
    pub fn quantile(&self, q: f64) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let target = ((self.count as f64) * q).ceil().max(1.0) as u64;
        let mut seen = 0u64;
        for (i, &b) in self.bins.iter().enumerate() {
            seen += u64::from(b);
            if seen >= target {
                return (i + 1) as f64 / 1000.0;
            }
        }
        self.max_s
    }

    pub fn summary(&self) -> LatencySummary {
        LatencySummary {
            count: self.count,
            p50_s: self.quantile(0.5),
            p99_s: self.quantile(0.99),
            max_s: self.max_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_from_bins() {
        let mut h = LatencyHistogram::default();
        for i in 0..100 {
            h.add(i as f64 / 100.0);
        }
        h.add(120.0);
        let s = h.summary();
        assert_eq!(s.count, 101);
        assert!((s.p50_s - 0.501).abs() < 1e-9, "{s:?}");
        assert!((s.p99_s - 0.991).abs() < 1e-9, "{s:?}");
        assert_eq!(s.max_s, 120.0);
    }
}
