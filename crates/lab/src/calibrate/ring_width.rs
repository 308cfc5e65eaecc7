//! The damping of the mode a loose housing's landings ring, read off a measured recording by
//! the half-power method: a mode of damping ratio z at f rings with a power spectrum whose
//! excess over the floor falls to half at f (1 +- z), so the width between the half-power
//! points is 2 z f. `looseness_impacts` judged on band energies alone trades the landing
//! strength against the damping (a mode's energy goes as strength^2 / damping: every point of
//! that ridge rings about the same band energy); the width tells the damping on its own.
//!
//! The spectrum is Welch's (Hann, 50 % overlap) over segments of one shaft revolution, so the
//! landings' lines (every multiple of half the shaft rate) merge within each bin and the bins
//! follow the mode's shape. The peak is the highest bin half an octave either side of where
//! the landings ring (the half-octave band the landing comb is strongest in), followed up the
//! slope it may lie on to the top of its peak, within an octave of there; the floor is the [`views::FLOOR_QUANTILE`] of the spectrum an octave either
//! side of the peak. The width between the half-power points of the excess (linearly
//! interpolated) is the mode's widened by the Hann window's own half-power width
//! ([`HANN_HALF_POWER_BINS`]); the two are taken apart as a Lorentzian and a Gaussian line
//! (the Voigt width, Olivero & Longbothum 1977). It is read only where the peak stands
//! [`MIN_SNR_DB`] above the floor, its half-power points lie within that octave and its width
//! is resolved ([`MIN_RESOLVED`] window widths): else `None`, and the damping is searched.

use super::stats::quantile;
use super::views::{self, FLOOR_QUANTILE};
use serde::Serialize;

/// The peak must stand this far above the floor: its half-power points then lie 7 dB above
/// the floor, which moves each by a few percent of the width at most.
pub const MIN_SNR_DB: f64 = 10.0;
/// Half-power full width of the Hann window's power response, in bins.
pub const HANN_HALF_POWER_BINS: f64 = 1.44;
/// A measured width below this many window widths is the window's, not the mode's.
pub const MIN_RESOLVED: f64 = 1.5;

/// The mode's frequency, its damping ratio from the half-power width, and how far it stands
/// above the floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RingWidth {
    pub hz: f64,
    pub damping: f64,
    pub snr_db: f64,
}

/// The ring width of `x` (sampled at `fs`, turning at `shaft_hz`) for a mode ringing near
/// `centre_hz`; `None` where the width cannot be read (see the module doc).
pub fn measure(x: &[f32], fs: f64, shaft_hz: f64, centre_hz: f64) -> Option<RingWidth> {
    if !(shaft_hz > 0.0 && centre_hz > 0.0 && fs > 0.0) {
        return None;
    }
    let nseg = (fs / shaft_hz).round() as usize;
    if nseg < 16 || x.len() < 2 * nseg {
        return None;
    }
    let (_, power) = views::welch(x, nseg);
    let df = fs / nseg as f64;
    let bin = |hz: f64| ((hz / df).round() as usize).min(power.len() - 1);
    let half_octave = std::f64::consts::SQRT_2;
    let (lo, hi) = (bin(centre_hz / half_octave), bin(centre_hz * half_octave));
    let mut k = (lo..=hi).max_by(|a, b| power[*a].total_cmp(&power[*b]))?;
    // up the slope the band's highest bin may lie on, to the top of its peak, within an
    // octave of the centre
    let (cap_lo, cap_hi) = (bin(centre_hz / 2.0), bin(centre_hz * 2.0));
    while k < cap_hi && power[k + 1] > power[k] {
        k += 1;
    }
    while k > cap_lo && power[k - 1] > power[k] {
        k -= 1;
    }
    if k <= cap_lo || k >= cap_hi {
        return None;
    }
    let f0 = k as f64 * df;
    let (clo, chi) = (bin(f0 / 2.0), bin(f0 * 2.0));
    let floor = quantile(&power[clo..=chi], FLOOR_QUANTILE);
    if !(floor > 0.0) || 10.0 * (power[k] / floor).log10() < MIN_SNR_DB {
        return None;
    }
    let excess = |j: usize| power[j] - floor;
    let half = 0.5 * excess(k);
    // the half-power crossing on each side, interpolated between the bins around it
    let crossing = |step: isize| -> Option<f64> {
        let mut j = k;
        loop {
            let next = j
                .checked_add_signed(step)
                .filter(|n| (clo..=chi).contains(n))?;
            if excess(next) <= half {
                let t = (excess(j) - half) / (excess(j) - excess(next));
                return Some((j as f64 + t * step as f64) * df);
            }
            j = next;
        }
    };
    let measured = crossing(1)? - crossing(-1)?;
    let window = HANN_HALF_POWER_BINS * df;
    if measured < MIN_RESOLVED * window {
        return None;
    }
    let width = lorentzian_width(measured, window);
    Some(RingWidth {
        hz: f0,
        damping: width / (2.0 * f0),
        snr_db: 10.0 * (power[k] / floor).log10(),
    })
}

/// The Lorentzian full width of a Voigt line `voigt` wide whose Gaussian part is `gauss`
/// wide (all half-power full widths): the root of V = 0.5346 L + sqrt(0.2166 L^2 + G^2).
fn lorentzian_width(voigt: f64, gauss: f64) -> f64 {
    let (a, b) = (0.5346, 0.2166);
    // (V - a L)^2 = b L^2 + G^2  ->  (a^2 - b) L^2 - 2 a V L + (V^2 - G^2) = 0
    let qa = a * a - b;
    let qb = -2.0 * a * voigt;
    let qc = voigt * voigt - gauss * gauss;
    (-qb - (qb * qb - 4.0 * qa * qc).max(0.0).sqrt()) / (2.0 * qa)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ring-downs of a known mode landing once every two revolutions over white noise: the
    /// damping comes back within 10 %, at two speeds and three modes; a train too weak to
    /// stand above the floor gives no reading, and so does noise alone.
    #[test]
    fn the_half_power_width_tells_the_damping() {
        let fs = 10_000.0;
        let ring = |shaft_hz: f64, mode_hz: f64, z: f64, peak: f64, seed: u64| -> Vec<f32> {
            let n = (3.0 * fs) as usize;
            let mut s = seed;
            let mut noise = || {
                // sum of 12 uniforms: near-Gaussian, unit variance
                (0..12)
                    .map(|_| {
                        s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                        (s >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0
            };
            let mut x: Vec<f64> = (0..n).map(|_| 0.3 * noise()).collect();
            let w = std::f64::consts::TAU * mode_hz;
            let spacing = 2.0 / shaft_hz;
            let mut t0 = 0.01;
            while t0 < n as f64 / fs {
                let jitter = 0.005 * spacing * noise();
                let a = ((t0 + jitter) * fs).max(0.0) as usize;
                for (j, v) in x
                    .iter_mut()
                    .skip(a)
                    .enumerate()
                    .take((8.0 / (z * w) * fs) as usize)
                {
                    let t = j as f64 / fs;
                    *v += peak * (-z * w * t).exp() * (w * t).sin();
                }
                t0 += spacing;
            }
            x.iter().map(|v| *v as f32).collect()
        };
        for (shaft_hz, mode_hz, z) in [
            (10.0, 1000.0, 0.04),
            (20.0, 2500.0, 0.03),
            (10.0, 700.0, 0.06),
        ] {
            let r = measure(&ring(shaft_hz, mode_hz, z, 6.0, 7), fs, shaft_hz, mode_hz).unwrap();
            assert!(
                (r.damping / z - 1.0).abs() <= 0.1,
                "{shaft_hz} Hz, {mode_hz} Hz, {z}: {r:?}"
            );
            assert!((r.hz / mode_hz - 1.0).abs() <= 0.03, "{r:?}");
        }
        assert_eq!(
            measure(&ring(10.0, 1000.0, 0.04, 0.05, 7), fs, 10.0, 1000.0),
            None
        );
        assert_eq!(
            measure(&ring(10.0, 1000.0, 0.04, 0.0, 8), fs, 10.0, 1000.0),
            None
        );
    }

    /// The Voigt inversion gives the Lorentzian back.
    #[test]
    fn the_window_is_taken_out_of_the_width() {
        for (l, g) in [(80.0_f64, 14.4_f64), (50.0, 30.0), (200.0, 10.0)] {
            let v: f64 = 0.5346 * l + (0.2166 * l * l + g * g).sqrt();
            assert!((lorentzian_width(v, g) - l).abs() < 1e-6 * l, "{l} {g}");
        }
    }
}
