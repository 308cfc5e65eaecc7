//! Impulsiveness relative to the machine's own healthy baseline: how far a window's excess
//! kurtosis (Dyer & Stewart's bearing-damage indicator; [`crate::dsp::quality::scan`]) stands
//! above what the machine's healthy windows and plain Gaussian noise give. A defect that
//! sends impacts through the structure without a clean fault-family line in the envelope (a
//! small ball defect that rolls in and out of the load zone) still makes the raw signal
//! impulsive; this is the evidence the verdict ([`crate::health::verdict`]) uses when the
//! envelope's families are silent.
//!
//! A window's impulsiveness is the smaller of two z-scores of its excess kurtosis `k`:
//! - **beyond healthy**: `(k - mean) / spread`, the healthy windows' mean and spread, the
//!   spread never below the sampling spread of a Gaussian's kurtosis `sqrt(24 / N)` (`N`
//!   samples per window) and widened by `sqrt(1 + 1/n)` for a mean known from `n` windows;
//! - **beyond Gaussian**: `k / sqrt(24 / N)`: a signal is impulsive only where it is more
//!   peaked than noise (a machine whose healthy kurtosis is below 0, dominated by its shaft
//!   lines, is not called impulsive for rising towards noise).
//!
//! Both scores are linear in `k`, so the state machine accumulates them as means over the
//! last windows ([`ImpulseHistory`]). Unlike the fault-family evidence, the mean earns no
//! credit for averaging: the kurtosis of one machine drifts with load and temperature, so
//! windows are not independent draws, and the sample kurtosis has a heavy upper tail.

use super::meta::ModelMeta;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The healthy windows' excess kurtosis, stored in an aligned model's `alignment`
/// (`healthy_kurtosis`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImpulseBaseline {
    /// Mean excess kurtosis of the healthy windows.
    pub mean: f32,
    /// Their spread, with the Gaussian floor and the `sqrt(1 + 1/n)` widening applied.
    pub spread: f32,
    /// Healthy windows it was fitted on.
    pub windows: usize,
}

impl ImpulseBaseline {
    /// Fit on the healthy windows' excess kurtosis, windows of `window_samples` samples; None
    /// with fewer than two finite values.
    pub fn fit(kurtosis: &[f32], window_samples: usize) -> Option<Self> {
        let k: Vec<f64> = kurtosis
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| f64::from(v))
            .collect();
        let n = k.len();
        if n < 2 || window_samples == 0 {
            return None;
        }
        let mean = k.iter().sum::<f64>() / n as f64;
        let sd = (k.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        let spread = sd.max(gaussian_sd(window_samples)) * (1.0 + 1.0 / n as f64).sqrt();
        Some(ImpulseBaseline {
            mean: mean as f32,
            spread: spread as f32,
            windows: n,
        })
    }

    /// From an aligned model's metadata; None for a model not aligned, or aligned before the
    /// kurtosis baseline was stored.
    pub fn of(meta: &ModelMeta) -> Option<Self> {
        let v: serde_json::Value = serde_json::from_str(&meta.alignment).ok()?;
        let b: ImpulseBaseline = serde_json::from_value(v.get("healthy_kurtosis")?.clone()).ok()?;
        (b.spread > 0.0 && b.mean.is_finite()).then_some(b)
    }

    /// One window's impulsiveness from its excess kurtosis over `window_samples` samples.
    pub fn impulse(&self, excess_kurtosis: f32, window_samples: usize) -> Impulse {
        Impulse {
            beyond_healthy: (excess_kurtosis - self.mean) / self.spread,
            beyond_gaussian: excess_kurtosis / gaussian_sd(window_samples) as f32,
        }
    }
}

/// Sampling spread of a Gaussian's excess kurtosis over `n` samples, `sqrt(24 / n)`
/// (infinite for no samples: nothing is beyond it).
fn gaussian_sd(n: usize) -> f64 {
    if n == 0 {
        return f64::INFINITY;
    }
    (24.0 / n as f64).sqrt()
}

/// How impulsive a window (or the last windows) is, in z-scores (module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Impulse {
    pub beyond_healthy: f32,
    pub beyond_gaussian: f32,
}

impl Impulse {
    /// The impulsiveness: the smaller of the two scores (NaN stays NaN: never impulsive).
    pub fn z(&self) -> f32 {
        if self.beyond_healthy.is_nan() || self.beyond_gaussian.is_nan() {
            return f32::NAN;
        }
        self.beyond_healthy.min(self.beyond_gaussian)
    }
}

/// The last windows' impulsiveness, as means (module doc: no credit for averaging).
#[derive(Debug, Clone, PartialEq)]
pub struct ImpulseHistory {
    windows: VecDeque<Impulse>,
    capacity: usize,
}

impl ImpulseHistory {
    /// Keep the last `capacity` windows (at least 1).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        ImpulseHistory {
            windows: VecDeque::with_capacity(capacity + 1),
            capacity,
        }
    }

    /// Add one window; returns the mean over the kept windows.
    pub fn push(&mut self, i: Impulse) -> Impulse {
        if self.windows.len() >= self.capacity {
            self.windows.pop_front();
        }
        self.windows.push_back(i);
        let m = self.windows.len() as f32;
        Impulse {
            beyond_healthy: self.windows.iter().map(|w| w.beyond_healthy).sum::<f32>() / m,
            beyond_gaussian: self.windows.iter().map(|w| w.beyond_gaussian).sum::<f32>() / m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::quality::scan;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn the_baseline_keeps_the_gaussian_floor_and_the_smaller_score_decides() {
        // a sine-dominated healthy machine: kurtosis near -0.3, scattered less than the floor
        let b = ImpulseBaseline::fit(&[-0.30, -0.28, -0.32, -0.29], 12_000).unwrap();
        let floor = (24.0f32 / 12_000.0).sqrt();
        assert!((b.spread - floor * 1.25f32.sqrt()).abs() < 1e-6, "{b:?}");
        // rising to Gaussian noise (0) is beyond this machine's healthy windows, not impulsive
        let i = b.impulse(0.0, 12_000);
        assert!(i.beyond_healthy > 5.0 && i.beyond_gaussian == 0.0);
        assert_eq!(i.z(), 0.0);
        // a window of sparse impacts is both
        assert!(b.impulse(1.0, 12_000).z() > 10.0);
        // beyond Gaussian is judged on the window's own length: a shorter window scatters more
        let long = b.impulse(0.5, 48_000).beyond_gaussian;
        assert!((long / b.impulse(0.5, 12_000).beyond_gaussian - 2.0).abs() < 1e-5);
        // a machine impulsive when healthy: only beyond its own healthy level counts
        let b = ImpulseBaseline::fit(&[2.0, 2.4, 2.2, 1.8, 2.1], 51_200).unwrap();
        assert!(b.impulse(2.3, 51_200).z() < 2.0);
        assert!(ImpulseBaseline::fit(&[1.0], 100).is_none());
    }

    #[test]
    fn the_baseline_travels_in_the_alignment_json() {
        let b = ImpulseBaseline::fit(&[0.1, 0.2, 0.15], 10_000).unwrap();
        let meta = ModelMeta {
            alignment: serde_json::json!({ "windows": 3, "healthy_kurtosis": b }).to_string(),
            ..ModelMeta::default()
        };
        assert_eq!(ImpulseBaseline::of(&meta), Some(b));
        let old = ModelMeta {
            alignment: serde_json::json!({ "windows": 3 }).to_string(),
            ..ModelMeta::default()
        };
        assert_eq!(ImpulseBaseline::of(&old), None);
    }

    #[test]
    fn gaussian_noise_never_reaches_five() {
        // the footing of the default `impulse_z` = 5: a baseline fitted on 6 windows of
        // Gaussian noise, then 400 more windows of the same noise accumulated five at a
        // time stay far below it
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let normal = Normal::new(0.0f32, 1.0).unwrap();
        let mut window = |n: usize| -> f32 {
            let x: Vec<f32> = (0..n).map(|_| normal.sample(&mut rng)).collect();
            scan(&x, 10_000.0).excess_kurtosis
        };
        let healthy: Vec<f32> = (0..6).map(|_| window(10_000)).collect();
        let b = ImpulseBaseline::fit(&healthy, 10_000).unwrap();
        let mut h = ImpulseHistory::new(5);
        let top = (0..400)
            .map(|_| h.push(b.impulse(window(10_000), 10_000)).z())
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(top < 3.0, "{top}");
    }

    #[test]
    fn the_history_is_a_plain_mean_of_the_last_windows() {
        let mut h = ImpulseHistory::new(2);
        let i = |a: f32| Impulse {
            beyond_healthy: a,
            beyond_gaussian: 2.0 * a,
        };
        assert_eq!(h.push(i(1.0)), i(1.0));
        assert_eq!(h.push(i(3.0)), i(2.0));
        assert_eq!(h.push(i(5.0)), i(4.0));
        assert!(i(f32::NAN).z().is_nan());
    }
}
