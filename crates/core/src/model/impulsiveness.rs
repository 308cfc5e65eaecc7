//! Impulsiveness relative to the machine's own healthy baseline: how far a window's excess
//! kurtosis (Dyer & Stewart's bearing-damage indicator; [`crate::dsp::quality::scan`]) stands
//! above what the machine's healthy windows and plain Gaussian noise give. A defect that
//! sends impacts through the structure without a clean fault-family line in the envelope (a
//! small ball defect that rolls in and out of the load zone) still makes the raw signal
//! impulsive; this is the evidence the verdict ([`crate::health::verdict`]) uses when the
//! envelope's families are silent.
//!
//! A window's impulsiveness is the smaller of two z-scores of its excess kurtosis `k` over
//! its `N` samples:
//! - **beyond healthy**: `(k - mean) / spread`, the healthy windows' mean, and their spread
//!   never below the sampling spread of a Gaussian's kurtosis over this window, `sqrt(24 /
//!   N)` (a window at a lower sample rate scatters more than the healthy ones did), widened
//!   by `sqrt(1 + 1/n)` for a mean known from `n` windows;
//! - **beyond Gaussian**: `k / sqrt(24 / N)`: a signal is impulsive only where it is more
//!   peaked than noise (a machine whose healthy kurtosis is below 0, dominated by its shaft
//!   lines, is not called impulsive for rising towards noise).
//!
//! The state machine accumulates both over the last `vote_n` windows ([`ImpulseHistory`]):
//! their mean over all `vote_n` places (a place not yet filled counts 0), each window capped
//! at [`window_cap`] so that one transient -- a knock or an electrical spike, huge in the one
//! or two windows holding it -- cannot reach the threshold alone. Unlike the fault-family
//! evidence the mean earns no credit for averaging: the kurtosis of one machine drifts with
//! load and temperature, so windows are not independent draws, and the sample kurtosis has a
//! heavy upper tail.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// The healthy windows' excess kurtosis, stored in an aligned model's `alignment`
/// (`healthy_kurtosis`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImpulseBaseline {
    /// Mean excess kurtosis of the healthy windows.
    pub mean: f32,
    /// Their standard deviation (between windows, as measured; the Gaussian floor is applied
    /// per window in [`Self::impulse`]).
    pub sd: f32,
    /// Healthy windows it was fitted on.
    pub windows: usize,
}

impl ImpulseBaseline {
    /// Fit on the healthy windows' excess kurtosis (NaN: a window without one); None with
    /// fewer than two finite values.
    pub fn fit(kurtosis: &[f32]) -> Option<Self> {
        let k: Vec<f64> = kurtosis
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| f64::from(v))
            .collect();
        let n = k.len();
        if n < 2 {
            return None;
        }
        let mean = k.iter().sum::<f64>() / n as f64;
        let sd = (k.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        Some(ImpulseBaseline {
            mean: mean as f32,
            sd: sd as f32,
            windows: n,
        })
    }

    /// One window's impulsiveness from its excess kurtosis over `window_samples` samples.
    pub fn impulse(&self, excess_kurtosis: f32, window_samples: usize) -> Impulse {
        let floor = gaussian_sd(window_samples);
        let spread = f64::from(self.sd).max(floor) * (1.0 + 1.0 / self.windows as f64).sqrt();
        Impulse {
            beyond_healthy: (excess_kurtosis - self.mean) / spread as f32,
            beyond_gaussian: excess_kurtosis / floor as f32,
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

/// The most one window may add to [`ImpulseHistory`]'s scores: a transient shorter than a
/// window lies in `w = ceil(1 / hop_fraction)` windows, and with each capped at
/// `impulse_z x n / (w + 1/2)` it lifts the mean over `n` places to `w / (w + 1/2)` of
/// `impulse_z` (0.8 for 1 s windows every 0.5 s), never to the threshold.
pub fn window_cap(impulse_z: f32, n: usize, hop_fraction: f64) -> f32 {
    let w = if hop_fraction > 0.0 && hop_fraction.is_finite() {
        (1.0 / hop_fraction).ceil()
    } else {
        1.0
    };
    (f64::from(impulse_z) * n.max(1) as f64 / (w + 0.5)) as f32
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

/// The last windows' impulsiveness: the mean over `capacity` places of each score, every
/// window capped (module doc; no credit for averaging).
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

    /// Add one window, each score capped at +-`cap` ([`window_cap`]); returns the mean over
    /// the `capacity` places (the empty ones count 0).
    pub fn push(&mut self, i: Impulse, cap: f32) -> Impulse {
        if self.windows.len() >= self.capacity {
            self.windows.pop_front();
        }
        let capped = |v: f32| v.max(-cap).min(cap);
        self.windows.push_back(Impulse {
            beyond_healthy: capped(i.beyond_healthy),
            beyond_gaussian: capped(i.beyond_gaussian),
        });
        let n = self.capacity as f32;
        Impulse {
            beyond_healthy: self.windows.iter().map(|w| w.beyond_healthy).sum::<f32>() / n,
            beyond_gaussian: self.windows.iter().map(|w| w.beyond_gaussian).sum::<f32>() / n,
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
    fn the_baseline_keeps_the_gaussian_floor_of_each_window_and_the_smaller_score_decides() {
        // a sine-dominated healthy machine: kurtosis near -0.3, scattered less than the floor
        let b = ImpulseBaseline::fit(&[-0.30, -0.28, -0.32, -0.29, f32::NAN]).unwrap();
        assert_eq!(b.windows, 4);
        let floor = (24.0f32 / 12_000.0).sqrt();
        let i = b.impulse(-0.2975 + floor * 1.25f32.sqrt(), 12_000);
        assert!((i.beyond_healthy - 1.0).abs() < 1e-3, "{i:?}");
        // rising to Gaussian noise (0) is beyond this machine's healthy windows, not impulsive
        let i = b.impulse(0.0, 12_000);
        assert!(i.beyond_healthy > 5.0 && i.beyond_gaussian == 0.0);
        assert_eq!(i.z(), 0.0);
        // a window of sparse impacts is both
        assert!(b.impulse(1.0, 12_000).z() > 10.0);
        // both scores are judged on the window's own length: a shorter window scatters more
        let (long, short) = (b.impulse(0.5, 48_000), b.impulse(0.5, 12_000));
        assert!((long.beyond_gaussian / short.beyond_gaussian - 2.0).abs() < 1e-5);
        assert!(
            long.beyond_healthy > 1.9 * short.beyond_healthy,
            "{long:?} {short:?}"
        );
        // a machine impulsive when healthy: only beyond its own healthy level counts
        let b = ImpulseBaseline::fit(&[2.0, 2.4, 2.2, 1.8, 2.1]).unwrap();
        assert!(b.impulse(2.3, 51_200).z() < 2.0);
        assert!(ImpulseBaseline::fit(&[1.0, f32::NAN]).is_none());
    }

    #[test]
    fn gaussian_noise_never_reaches_five() {
        // the footing of the default `impulse_z` = 5: a baseline fitted on 6 windows of
        // Gaussian noise, then 400 more windows of the same noise accumulated five at a time
        // stay far below it
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let normal = Normal::new(0.0f32, 1.0).unwrap();
        let mut window = |n: usize| -> f32 {
            let x: Vec<f32> = (0..n).map(|_| normal.sample(&mut rng)).collect();
            scan(&x, 10_000.0).excess_kurtosis
        };
        let healthy: Vec<f32> = (0..6).map(|_| window(10_000)).collect();
        let b = ImpulseBaseline::fit(&healthy).unwrap();
        let mut h = ImpulseHistory::new(5);
        let cap = window_cap(5.0, 5, 0.5);
        let top = (0..400)
            .map(|_| h.push(b.impulse(window(10_000), 10_000), cap).z())
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(top < 3.0, "{top}");
    }

    #[test]
    fn one_transient_cannot_reach_the_threshold_and_a_lasting_one_does() {
        let cap = window_cap(5.0, 5, 0.5);
        assert_eq!(cap, 10.0);
        let i = |z: f32| Impulse {
            beyond_healthy: z,
            beyond_gaussian: z,
        };
        // a spike in two overlapping windows (z in the thousands), from the very start
        let mut h = ImpulseHistory::new(5);
        let zs: Vec<f32> = [3000.0, 3000.0, 0.0, 0.0, 0.0, 0.0]
            .iter()
            .map(|&z| h.push(i(z), cap).z())
            .collect();
        assert!(zs.iter().all(|&z| z < 5.0), "{zs:?}");
        assert!((zs[1] - 4.0).abs() < 1e-6, "{zs:?}");
        // impacts that last: four windows at 8 of the last five reach it
        let mut h = ImpulseHistory::new(5);
        let z = [8.0, 8.0, 8.0]
            .iter()
            .map(|&z| h.push(i(z), cap).z())
            .last();
        assert!(z.unwrap() < 5.0);
        assert!(h.push(i(8.0), cap).z() >= 5.0);
        assert!(i(f32::NAN).z().is_nan());
    }
}
