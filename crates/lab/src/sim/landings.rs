//! The sensor-stage signal of a loose housing ([`LooseImpactsConfig`]): one landing every two
//! shaft revolutions, each a damped ring-down of one structural mode, added to the radial
//! channels. The landing times come from the engine's shaft angles (sample boundaries), so
//! the train follows the simulated speed, fluctuation included; each ring-down is evaluated
//! from the landing's interpolated time, so its timing is exact below one sample.

use crate::config::simulation::{LooseImpactsConfig, SimulationConfig};
use std::f64::consts::TAU;

/// The landings of a section's `loose_impacts` on the radial channels (none when absent).
pub struct Radial {
    vertical: Vec<f64>,
    horizontal_ratio: f64,
}

impl Radial {
    /// The landings over a run's shaft angles at the sample boundaries.
    pub fn new(sim: &SimulationConfig, boundary_angles: &[f64], fs: f64) -> Self {
        match &sim.loose_impacts {
            Some(l) => Radial {
                vertical: signal(l, boundary_angles, fs),
                horizontal_ratio: l.horizontal_ratio,
            },
            None => Radial {
                vertical: Vec::new(),
                horizontal_ratio: 0.0,
            },
        }
    }

    /// Sample `i` on the vertical (`true`) or horizontal channel, m/s^2.
    pub fn at(&self, vertical: bool, i: usize) -> f64 {
        let y = self.vertical.get(i).copied().unwrap_or(0.0);
        if vertical {
            y
        } else {
            self.horizontal_ratio * y
        }
    }
}

/// Ring-downs are cut where they have decayed to this fraction of their peak.
const DECAYED: f64 = 1e-4;

/// A loose joint does not land the same way twice: each landing's time slips by the
/// section's `timing_jitter` (a fraction of the landing spacing, standard deviation) and its
/// strength by this fraction. Without them the train is a perfect comb of lines up to the
/// mode's frequency, which no real landing train is (at 2.5 kHz and 1200 rpm a 1 % slip is
/// 1 ms, several periods of the ring: the comb's high lines smear into a band).
const STRENGTH_JITTER: f64 = 0.1;

/// Two standard normal draws fixed by landing `k` (SplitMix64 and Box-Muller): the same
/// landing train for every evaluation of a section, so a search sees a smooth objective.
fn normals(k: i64) -> (f64, f64) {
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let a = mix(k as u64);
    let b = mix(a);
    let u = |x: u64| ((x >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let (r, th) = ((-2.0 * u(a).ln()).sqrt(), TAU * u(b));
    (r * th.cos(), r * th.sin())
}

/// The vertical landing signal (m/s^2) per output sample: `boundary_angles` holds the shaft
/// angle (rad) at the n + 1 sample boundaries, `fs` the output rate. The horizontal channel
/// takes `horizontal_ratio` of it.
pub fn signal(l: &LooseImpactsConfig, boundary_angles: &[f64], fs: f64) -> Vec<f64> {
    let n = boundary_angles.len().saturating_sub(1);
    let mut y = vec![0.0; n];
    if n == 0 || l.impact_m_s2 == 0.0 {
        return y;
    }
    let w = TAU * l.mode_hz;
    let decay = l.damping * w;
    let wd = w * (1.0 - l.damping * l.damping).max(0.0).sqrt();
    let len = ((-DECAYED.ln()) / decay * fs).ceil() as usize + 1;
    let phase = l.phase_deg.to_radians();
    // the landing index of a shaft angle: k such that phase + 2 TAU k <= angle
    let index = |a: f64| ((a - phase) / (2.0 * TAU)).floor();
    for i in 0..n {
        let (a0, a1) = (boundary_angles[i], boundary_angles[i + 1]);
        if index(a1) <= index(a0) || a1 <= a0 {
            continue;
        }
        // the landing's angle, its time inside the sample by linear interpolation, then its
        // slip (`timing_jitter`) and strength ([`STRENGTH_JITTER`])
        let k = index(a1);
        let at = phase + 2.0 * TAU * k;
        let rpm = 60.0 * (a1 - a0) * fs / TAU;
        let (g_time, g_strength) = normals(k as i64);
        let t0 = (i as f64 + (at - a0) / (a1 - a0)) / fs + l.timing_jitter * 120.0 / rpm * g_time;
        let peak =
            l.impact_m_s2 * l.speed_gain(rpm) * (1.0 + STRENGTH_JITTER * g_strength).max(0.0);
        let first = (t0 * fs).ceil().max(0.0) as usize;
        for (j, v) in y.iter_mut().enumerate().skip(first).take(len) {
            let t = j as f64 / fs - t0;
            *v += peak * (-decay * t).exp() * (wd * t).sin();
        }
    }
    y
}

/// The peak of one landing's ring-down at `ref_rpm`, m/s^2: `impact_m_s2` e^(-damping w t)
/// sin(w_d t) is largest where tan(w_d t) = w_d / (damping w), a little below `impact_m_s2`.
pub fn peak(l: &LooseImpactsConfig) -> f64 {
    let w = TAU * l.mode_hz;
    let (decay, wd) = (
        l.damping * w,
        w * (1.0 - l.damping * l.damping).max(0.0).sqrt(),
    );
    let t = (wd / decay).atan() / wd;
    l.impact_m_s2 * (-decay * t).exp() * (wd * t).sin()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(mode_hz: f64) -> LooseImpactsConfig {
        LooseImpactsConfig {
            ref_rpm: 1200.0,
            exponent: 2.0,
            impact_m_s2: 10.0,
            mode_hz,
            damping: 0.05,
            horizontal_ratio: 0.5,
            phase_deg: 0.0,
            timing_jitter: 0.01,
        }
    }

    /// At 1200 rpm (20 rev/s) and 10 kHz, 2 s: landings every 0.1 s (20 of them), each
    /// ringing at the mode, the train's spectrum peaking at the mode; at 600 rpm a quarter
    /// as strong (speed^2).
    #[test]
    fn lands_every_other_revolution_and_rings_the_mode() {
        let fs = 10_000.0;
        let n = 20_000;
        let angles =
            |rpm: f64| -> Vec<f64> { (0..=n).map(|i| TAU * rpm / 60.0 * i as f64 / fs).collect() };
        let y = signal(&config(900.0), &angles(1200.0), fs);
        // count the landings: the first sample above 3 after 50 quiet ones (a ring-down
        // lasts ~35 samples per e-fold, so its own zero crossings are not counted; the
        // two samples just before may already be rising)
        let mut peaks: Vec<usize> = Vec::new();
        for i in 50..n {
            let quiet = y[i - 50..i - 2].iter().all(|v| v.abs() < 1.0);
            if y[i].abs() > 3.0 && quiet && peaks.last().is_none_or(|&p| i > p + 50) {
                peaks.push(i);
            }
        }
        assert!((19..=21).contains(&peaks.len()), "{}", peaks.len());
        let gaps: Vec<usize> = peaks.windows(2).map(|p| p[1] - p[0]).collect();
        // 1000 samples apart, each landing slipping by 1 % of that (sd 10 samples)
        let mean = gaps.iter().sum::<usize>() as f64 / gaps.len() as f64;
        assert!((990.0..=1010.0).contains(&mean), "{gaps:?}");
        assert!(gaps.iter().all(|g| (900..=1100).contains(g)), "{gaps:?}");
        // zero crossings of the first ring-down: 2 per mode period
        let first = &y[peaks[0]..peaks[0] + 100];
        let crossings = first.windows(2).filter(|w| w[0] * w[1] < 0.0).count();
        assert!((17..=19).contains(&crossings), "{crossings}");
        let slow = signal(&config(900.0), &angles(600.0), fs);
        let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let ratio = max(&slow) / max(&y);
        // speed^2, and the strength jitter (10 %) on the largest landing of each
        assert!((0.17..0.33).contains(&ratio), "{ratio}");
    }
}
