//! The calibration error: one scalar, the sum of named components, each comparing one view
//! of a measured recording with its simulated twin, averaged over recordings:
//! - `env`, `bands`: mean absolute difference in dB over the view's grid;
//! - `lines`: summed absolute dB difference over the 1 Hz bins, divided by [`LINES_PER`]
//!   (one missing 10 dB line counts 1), on recordings labelled **healthy** only: in a faulty
//!   recording the raw-spectrum lines are the fault's own harmonics, which `env` compares,
//!   while in a healthy one they are what unbalance and electrical pick-up put there;
//! - `speed`: half the summed absolute difference of the speed-deviation spectra, percent.
//! The README defines it too.

use super::views::Views;
use serde::Serialize;

/// Error components; `total` is their sum.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ErrorParts {
    pub env: f64,
    pub lines: f64,
    pub bands: f64,
    pub speed: f64,
    pub total: f64,
}

/// Divisor of the summed `lines` difference, dB.
pub const LINES_PER: f64 = 10.0;

fn mean_abs(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>() / n as f64
}

/// Error of one measured/simulated pair.
pub fn pair(m: &Views, s: &Views) -> ErrorParts {
    let env = mean_abs(&m.env, &s.env);
    let lines = if m.healthy {
        m.lines
            .iter()
            .zip(&s.lines)
            .map(|(x, y)| (x - y).abs())
            .sum::<f64>()
            / LINES_PER
    } else {
        0.0
    };
    let bands = mean_abs(&m.bands, &s.bands);
    let n = m.speed.len().min(s.speed.len());
    let speed = 0.5
        * m.speed[..n]
            .iter()
            .zip(&s.speed[..n])
            .map(|(x, y)| (x - y).abs())
            .sum::<f64>();
    ErrorParts {
        env,
        lines,
        bands,
        speed,
        total: env + lines + bands + speed,
    }
}

impl ErrorParts {
    /// Sum of the named components (`env`, `lines`, `bands`, `speed`).
    pub fn of(&self, names: &[&str]) -> f64 {
        names
            .iter()
            .map(|n| match *n {
                "env" => self.env,
                "lines" => self.lines,
                "bands" => self.bands,
                "speed" => self.speed,
                _ => self.total,
            })
            .sum()
    }
}

/// Mean over pairs.
pub fn mean(parts: &[ErrorParts]) -> ErrorParts {
    let n = parts.len().max(1) as f64;
    let mut e = ErrorParts::default();
    for p in parts {
        e.env += p.env / n;
        e.lines += p.lines / n;
        e.bands += p.bands / n;
        e.speed += p.speed / n;
    }
    e.total = e.env + e.lines + e.bands + e.speed;
    e
}
