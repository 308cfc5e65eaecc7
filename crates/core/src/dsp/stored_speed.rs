//! A recording's stored speed checked against its own vibration. Files that store one speed
//! (CWRU's `X<nnn>RPM`, MFPT's `bearing.rate`) store what the experimenter wrote down, which
//! is usually right and sometimes not: CWRU's fan-end record 279 (0.007 in inner race, 1 hp)
//! stores 1732 rpm where its 1x line, like every other 1 hp record's, is at ~1774 rpm, so its
//! fault orders are read 2.4 % off. The 1x line is searched only near the stored speed
//! (+- `within`), so the check cannot jump to a harmonic or a mains line; the stored speed is
//! replaced only when the line is clear ([`MIN_SCORE`]), inside the search range, and more than
//! [`TOLERANCE`] away. A stored speed within that tolerance is kept as it is, so a file whose
//! speed is right is read exactly as before.

use super::speed_estimate::{Estimate, SpeedEstimator};
use anyhow::Result;

/// A stored speed this close to the vibration's 1x line (relative) is kept.
pub const TOLERANCE: f64 = 0.01;
/// Harmonic prominence (natural-log units above the whitened background, mean over the
/// harmonics summed) below which the 1x line is not trusted over the stored speed. Measured:
/// 2.6-5.2 on every CWRU record; Gaussian noise reads about 0.5 (`noise_is_not_trusted`).
pub const MIN_SCORE: f64 = 2.0;
/// An estimate this close (relative to the stored speed) to either end of the search range
/// sits on the bound, not on a line.
const EDGE: f64 = 0.002;

/// What the vibration says about a stored speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoredSpeedCheck {
    pub stored_rpm: f64,
    /// The 1x line searched within +-`within` of the stored speed.
    pub estimate: Estimate,
    /// `estimate.rpm / stored_rpm - 1`.
    pub off: f64,
    /// The speed to use: the estimate when the stored speed is clearly off, else the stored one.
    pub rpm: f64,
}

impl StoredSpeedCheck {
    /// Whether the stored speed was replaced by the vibration's.
    pub fn replaced(&self) -> bool {
        self.rpm != self.stored_rpm
    }
}

/// Check `stored_rpm` against the 1x line of `x` (sampled at `fs`), searched within
/// +-`within` (a fraction, e.g. 0.05) of it.
pub fn check(x: &[f32], fs: f64, stored_rpm: f64, within: f64) -> Result<StoredSpeedCheck> {
    let (lo, hi) = (stored_rpm * (1.0 - within), stored_rpm * (1.0 + within));
    let estimate = SpeedEstimator::new().estimate_constant(x, fs, lo, hi)?;
    let off = estimate.rpm / stored_rpm - 1.0;
    let interior = off.abs() < within - EDGE;
    let rpm = if off.abs() > TOLERANCE && estimate.score >= MIN_SCORE && interior {
        estimate.rpm
    } else {
        stored_rpm
    };
    Ok(StoredSpeedCheck {
        stored_rpm,
        estimate,
        off,
        rpm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1x..6x shaft lines with noise, at `rpm`.
    fn shaft(rpm: f64, fs: f64, seconds: f64, seed: u64) -> Vec<f32> {
        let f = rpm / 60.0;
        let mut s = seed;
        (0..(fs * seconds) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                let lines: f64 = (1..=6)
                    .map(|k| (std::f64::consts::TAU * k as f64 * f * t + k as f64).sin() / k as f64)
                    .sum();
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (s >> 33) as f64 / (1u64 << 31) as f64 - 1.0;
                (0.3 * lines + u) as f32
            })
            .collect()
    }

    #[test]
    fn a_stored_speed_off_by_more_than_the_tolerance_is_replaced() {
        let x = shaft(1774.0, 12_000.0, 10.0, 7);
        let c = check(&x, 12_000.0, 1732.0, 0.05).unwrap();
        assert!(c.replaced(), "{c:?}");
        assert!((c.rpm / 1774.0 - 1.0).abs() < 0.001, "{c:?}");
        assert!((c.off - (1774.0 / 1732.0 - 1.0)).abs() < 0.001, "{c:?}");
    }

    #[test]
    fn a_stored_speed_within_the_tolerance_is_kept_exactly() {
        let x = shaft(1774.0, 12_000.0, 10.0, 8);
        for stored in [1774.0, 1776.0, 1770.0] {
            let c = check(&x, 12_000.0, stored, 0.05).unwrap();
            assert!(!c.replaced(), "{c:?}");
            assert_eq!(c.rpm, stored);
        }
    }

    #[test]
    fn a_line_outside_the_search_range_is_not_taken() {
        // the true speed is 10 % above the stored one, outside +-5 %: the search ends on its
        // bound or on noise, and the stored speed stays
        let x = shaft(1900.0, 12_000.0, 10.0, 9);
        let c = check(&x, 12_000.0, 1727.0, 0.05).unwrap();
        assert!(!c.replaced(), "{c:?}");
    }

    #[test]
    fn noise_is_not_trusted() {
        let mut s = 3u64;
        let x: Vec<f32> = (0..120_000)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 33) as f64 / (1u64 << 31) as f64 - 1.0) as f32
            })
            .collect();
        let c = check(&x, 12_000.0, 1732.0, 0.05).unwrap();
        assert!(c.estimate.score < 1.5, "{c:?}");
        assert!(!c.replaced(), "{c:?}");
    }
}
