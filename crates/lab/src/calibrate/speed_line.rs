//! The speed-fluctuation line the measured recordings show: the strongest interior peak of
//! their mean `speed` view ([`super::views::speed_view`]), its frequency interpolated
//! between grid points and its depth read from its height, when it stands out of the
//! spectrum's median ([`PROMINENCE`]). `speed_fluctuation` searches around it
//! ([`super::catalog::Context::speed_line`]): on a long recording the line is so narrow
//! that a search over the catalog's whole period range would not land on it.

use super::stats::median;
use super::views::{Views, SPEED_MAX_HZ, SPEED_MIN_HZ, SPEED_STEP_TIMES_S};

/// A peak is a line when the mean spectrum there is at least this multiple of its median
/// (noise alone: the highest of the about 100 independent points of a 20 s spectrum is
/// about 2.6 times the median, less after averaging recordings).
pub const PROMINENCE: f64 = 5.0;

/// A sinusoidal speed fluctuation seen in the measured speed spectra.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedLine {
    /// Frequency of the line, Hz.
    pub hz: f64,
    /// Its depth: the amplitude of the relative speed deviation (0.04 = 4 %).
    pub fraction: f64,
    /// Frequency resolution of the shortest recording: 1 / its analysed length, Hz.
    pub resolution_hz: f64,
}

/// The line of the mean speed spectrum of `views` (each on its own grid, [`SPEED_STEP_TIMES_S`]
/// / its length, resampled linearly onto the finest one), or `None` when there are no
/// views, no interior peak, or the peak does not stand out ([`PROMINENCE`]).
pub fn find(views: &[&Views]) -> Option<SpeedLine> {
    let secs: Vec<f64> = views
        .iter()
        .filter(|v| v.seconds > 0.0 && v.speed.len() >= 3)
        .map(|v| v.seconds)
        .collect();
    if secs.is_empty() {
        return None;
    }
    let longest = secs.iter().copied().fold(0.0, f64::max);
    let shortest = secs.iter().copied().fold(f64::INFINITY, f64::min);
    let step = SPEED_STEP_TIMES_S / longest;
    let n = ((SPEED_MAX_HZ - SPEED_MIN_HZ) / step + 1e-9) as usize + 1;
    let mut mean = vec![0.0; n];
    let mut count = 0usize;
    for v in views
        .iter()
        .filter(|v| v.seconds > 0.0 && v.speed.len() >= 3)
    {
        let own_step = SPEED_STEP_TIMES_S / v.seconds;
        for (k, m) in mean.iter_mut().enumerate() {
            let x = (k as f64 * step) / own_step;
            let i = (x.floor() as usize).min(v.speed.len() - 2);
            let t = (x - i as f64).clamp(0.0, 1.0);
            *m += v.speed[i] * (1.0 - t) + v.speed[i + 1] * t;
        }
        count += 1;
    }
    mean.iter_mut().for_each(|m| *m /= count as f64);
    let k = (1..n - 1).max_by(|a, b| mean[*a].total_cmp(&mean[*b]))?;
    let (a, b, c) = (mean[k - 1], mean[k], mean[k + 1]);
    if !(b >= a && b >= c) || !(b > PROMINENCE * median(&mean)) || b <= 0.0 {
        return None;
    }
    // parabola through the three points around the top
    let den = a - 2.0 * b + c;
    let p = if den < 0.0 {
        (0.5 * (a - c) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let height = b - 0.25 * (a - c) * p;
    Some(SpeedLine {
        hz: SPEED_MIN_HZ + (k as f64 + p) * step,
        fraction: height / 100.0,
        resolution_hz: 1.0 / shortest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsp::speed::SpeedTrack;

    fn view(seconds: f64, rpm: f64, fraction: f64, period_s: f64, noise: f64) -> Views {
        let n = (seconds * 100.0).ceil() as usize + 2;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / 100.0).collect();
        // a fixed pseudo-random sequence for the noise
        let mut s = 12345u64;
        let hz: Vec<f64> = t
            .iter()
            .map(|&ti| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let r = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                rpm / 60.0
                    * (1.0 + fraction * (std::f64::consts::TAU * ti / period_s).sin() + noise * r)
            })
            .collect();
        let track =
            SpeedTrack::from_profile(&t, &hz, crate::vocabulary::SpeedSourceKind::Simulator)
                .unwrap();
        Views {
            speed: super::super::views::speed_view(&track, seconds, rpm),
            seconds,
            ..Views::default()
        }
    }

    #[test]
    fn finds_the_line_of_a_long_recording() {
        let a = view(20.0, 1200.0, 0.04, 0.8, 0.002);
        let b = view(20.0, 600.0, 0.04, 0.8, 0.002);
        let l = find(&[&a, &b]).expect("a 4 % line");
        assert!((l.hz - 1.25).abs() < 0.002, "{l:?}");
        assert!((l.fraction - 0.04).abs() < 0.002, "{l:?}");
        assert!((l.resolution_hz - 0.05).abs() < 1e-12);
        let slow = view(20.0, 1200.0, 0.04, 3.3, 0.0);
        let l = find(&[&slow]).expect("a slow line");
        assert!((1.0 / l.hz - 3.3).abs() < 0.03, "{l:?}");
    }

    #[test]
    fn mixed_lengths_share_the_finest_grid() {
        let a = view(20.0, 1200.0, 0.03, 2.0, 0.0);
        let b = view(10.0, 1200.0, 0.03, 2.0, 0.0);
        let l = find(&[&a, &b]).expect("a line");
        assert!((l.hz - 0.5).abs() < 0.005, "{l:?}");
        assert!((l.resolution_hz - 0.1).abs() < 1e-12);
    }

    #[test]
    fn noise_alone_is_no_line() {
        let a = view(20.0, 1200.0, 0.0, 1.0, 0.01);
        let b = view(20.0, 600.0, 0.0, 1.0, 0.01);
        assert_eq!(find(&[&a, &b]), None);
        assert_eq!(find(&[]), None);
    }
}
