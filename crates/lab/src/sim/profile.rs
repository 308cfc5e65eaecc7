//! Operating (speed) profiles: constant speed, linear ramps and sinusoidal fluctuation.
//! Shaft speed in rpm as a function of recording time (t = 0 is the first output sample;
//! the warm-up before it runs at the starting speed).

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};

/// Shaft speed over time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SpeedProfile {
    /// A constant speed.
    Constant { rpm: f64 },
    /// Linear change from `from_rpm` to `to_rpm` over `seconds`, then constant.
    Ramp {
        from_rpm: f64,
        to_rpm: f64,
        seconds: f64,
    },
    /// rpm + amplitude_rpm * sin(2 pi t / period_s): motor speed fluctuation.
    Sine {
        rpm: f64,
        amplitude_rpm: f64,
        period_s: f64,
    },
}

impl SpeedProfile {
    /// Shaft speed (rpm) at recording time `t` (s); `t < 0` is the warm-up.
    #[inline]
    pub fn rpm_at(&self, t: f64) -> f64 {
        match *self {
            SpeedProfile::Constant { rpm } => rpm,
            SpeedProfile::Ramp {
                from_rpm,
                to_rpm,
                seconds,
            } => {
                let x = if seconds > 0.0 {
                    (t / seconds).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                from_rpm + (to_rpm - from_rpm) * x
            }
            SpeedProfile::Sine {
                rpm,
                amplitude_rpm,
                period_s,
            } => {
                if t < 0.0 {
                    rpm
                } else {
                    rpm + amplitude_rpm * (std::f64::consts::TAU * t / period_s).sin()
                }
            }
        }
    }

    /// Mean speed over `[0, seconds]` (rpm), for labels and the stored nominal speed.
    pub fn mean_rpm(&self, seconds: f64) -> f64 {
        let n = 1000;
        (0..n)
            .map(|i| self.rpm_at((i as f64 + 0.5) / n as f64 * seconds))
            .sum::<f64>()
            / n as f64
    }

    /// Lowest and highest speed over `[0, seconds]`.
    pub fn range_rpm(&self, seconds: f64) -> (f64, f64) {
        let n = 1000;
        let v: Vec<f64> = (0..=n)
            .map(|i| self.rpm_at(i as f64 / n as f64 * seconds))
            .collect();
        (
            v.iter().copied().fold(f64::INFINITY, f64::min),
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    }

    pub fn validate(&self, seconds: f64) -> Result<()> {
        if let SpeedProfile::Sine { period_s, .. } = self {
            if !(*period_s > 0.0) {
                bail!("speed profile: period_s = {period_s} must be positive");
            }
        }
        let (lo, hi) = self.range_rpm(seconds);
        if !(lo.is_finite() && lo >= 30.0 && hi <= 30_000.0) {
            bail!("speed profile {self:?} goes to {lo:.1}..{hi:.1} rpm; the simulator needs 30..30000 rpm throughout");
        }
        Ok(())
    }

    /// Short human description for metadata.
    pub fn describe(&self) -> String {
        match self {
            SpeedProfile::Constant { rpm } => format!("constant {rpm} rpm"),
            SpeedProfile::Ramp {
                from_rpm,
                to_rpm,
                seconds,
            } => format!("ramp {from_rpm} -> {to_rpm} rpm over {seconds} s"),
            SpeedProfile::Sine {
                rpm,
                amplitude_rpm,
                period_s,
            } => format!("{rpm} rpm +- {amplitude_rpm} rpm, period {period_s} s"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profiles() {
        let r = SpeedProfile::Ramp {
            from_rpm: 600.0,
            to_rpm: 1200.0,
            seconds: 10.0,
        };
        assert_eq!(r.rpm_at(-1.0), 600.0);
        assert_eq!(r.rpm_at(5.0), 900.0);
        assert_eq!(r.rpm_at(20.0), 1200.0);
        let s = SpeedProfile::Sine {
            rpm: 1000.0,
            amplitude_rpm: 10.0,
            period_s: 2.0,
        };
        assert!((s.rpm_at(0.5) - 1010.0).abs() < 1e-9);
        assert!((s.mean_rpm(4.0) - 1000.0).abs() < 1e-6);
        assert!(SpeedProfile::Constant { rpm: 1.0 }.validate(1.0).is_err());
    }
}
