//! Shaft speed from the vibration itself, for recordings without a tacho: find the 1x line
//! by harmonic summation over a whitened spectrum (log magnitude minus its running median),
//! guard against octave errors (mains lines and strong 2x/3x harmonics), then track it over
//! time in short segments. Fundamentals within 0.3 % of 50/60 Hz are skipped as mains (a
//! synchronous machine at exactly 3000/3600 rpm needs a tacho or `--rpm`). A steady result (all segments within 1 % of the whole-record
//! estimate) gives a constant-speed track, otherwise a speed profile.

pub use crate::dsp::harmonic_sum::Estimate;
use crate::dsp::harmonic_sum::{fundamental, Whitener, HARMONICS};
use crate::dsp::speed::SpeedTrack;
use crate::vocabulary::SpeedSourceKind;
use anyhow::{bail, Result};

/// Segment length for tracking, s.
const SEGMENT_S: f64 = 2.0;

/// FFT plans and buffers for whitened spectra, made once and reused.
#[derive(Default)]
pub struct SpeedEstimator {
    whitener: Whitener,
}

impl SpeedEstimator {
    pub fn new() -> Self {
        SpeedEstimator::default()
    }

    /// One speed for the whole signal: see [`estimate_constant`].
    pub fn estimate_constant(
        &mut self,
        x: &[f32],
        fs: f64,
        min_rpm: f64,
        max_rpm: f64,
    ) -> Result<Estimate> {
        check_input(x, fs, min_rpm, max_rpm)?;
        let (fmin, fmax) = (min_rpm / 60.0, max_rpm / 60.0);
        let w = self
            .whitener
            .whiten(x, fs, 1, (HARMONICS as f64 + 1.0) * fmax);
        Ok(fundamental(&w, fmin, fmax))
    }

    /// The 1x line tracked over time: see [`estimate_track`].
    pub fn estimate_track(
        &mut self,
        x: &[f32],
        fs: f64,
        min_rpm: f64,
        max_rpm: f64,
    ) -> Result<SpeedTrack> {
        check_input(x, fs, min_rpm, max_rpm)?;
        let (fmin, fmax) = (min_rpm / 60.0, max_rpm / 60.0);
        let seg = ((SEGMENT_S.max(8.0 / fmin).min(8.0)) * fs) as usize;
        if x.len() < 3 * seg {
            let rpm = self.estimate_constant(x, fs, min_rpm, max_rpm)?.rpm;
            return SpeedTrack::constant(rpm, SpeedSourceKind::Estimate);
        }
        let top = (HARMONICS as f64 + 1.0) * fmax;
        let whole = self.whitener.whiten(x, fs, 1, top);
        let g = fundamental(&whole, fmin, fmax).rpm / 60.0;
        let (mut ts, mut spectra, mut raw) = (Vec::new(), Vec::new(), Vec::new());
        let mut start = 0;
        while start + seg <= x.len() {
            let w = self.whitener.whiten(&x[start..start + seg], fs, 4, top);
            // prefer the whole-record line when this segment supports it nearly as well as its own
            // best (short segments are easily fooled by fault lines); follow the segment otherwise
            let own = fundamental(&w, fmin, fmax);
            let (near, near_score) = w.best_in((g * 0.95).max(fmin), (g * 1.05).min(fmax));
            raw.push(if near_score >= 0.7 * own.score {
                near
            } else {
                own.rpm / 60.0
            });
            ts.push((start + seg / 2) as f64 / fs);
            spectra.push(w);
            start += seg / 2;
        }
        let n = raw.len();
        let mut win = Vec::with_capacity(5);
        let track: Vec<f64> = (0..n)
            .map(|i| {
                win.clear();
                win.extend_from_slice(&raw[i.saturating_sub(2)..(i + 3).min(n)]);
                win.sort_by(|a, b| a.total_cmp(b));
                let smooth = win[win.len() / 2];
                spectra[i].best_in(smooth * 0.97, smooth * 1.03).0
            })
            .collect();
        let mut sorted = track.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let med = sorted[n / 2];
        if track.iter().all(|f| (f / med - 1.0).abs() < 0.01) {
            let (f, _) = whole.best_in(med * 0.99, med * 1.01);
            return SpeedTrack::constant(f * 60.0, SpeedSourceKind::Estimate);
        }
        SpeedTrack::from_profile(&ts, &track, SpeedSourceKind::Estimate)
    }
}

/// One speed for the whole record, from the strongest harmonic series of the shaft line.
pub fn estimate_constant(x: &[f32], fs: f64, min_rpm: f64, max_rpm: f64) -> Result<Estimate> {
    SpeedEstimator::new().estimate_constant(x, fs, min_rpm, max_rpm)
}

fn check_input(x: &[f32], fs: f64, min_rpm: f64, max_rpm: f64) -> Result<()> {
    if !(min_rpm > 0.0 && max_rpm > min_rpm) {
        bail!("speed estimate: need 0 < min_rpm < max_rpm (got {min_rpm}, {max_rpm})");
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        bail!(
            "speed estimate: sample {i} is {} ; remove or repair non-finite samples first",
            x[i]
        );
    }
    let dur = x.len() as f64 / fs;
    let need = 20.0 / (min_rpm / 60.0);
    if dur < need.min(4.0) {
        bail!("speed estimate: the signal lasts {dur:.2} s; at least {:.2} s are needed to resolve the 1x line down to {min_rpm} rpm", need.min(4.0));
    }
    let top = (HARMONICS as f64 + 1.0) * max_rpm / 60.0;
    if top > fs / 2.0 {
        bail!("speed estimate: sample rate {fs} Hz is too low to see {HARMONICS} harmonics at {max_rpm} rpm");
    }
    Ok(())
}

/// Track the 1x line. Segments of 2 s (at least 8 revolutions at `min_rpm`, half overlapping) are searched
/// independently (with the octave guard); a running median over five segments removes
/// isolated mistakes, and each segment is refined within +-3 % of it. A segment takes the
/// whole-record line (+-5 %) when it supports it at 70 % of its own best score. When every segment is
/// within 1 % of their median the speed is steady and one whole-record estimate near that
/// median is used (finer resolution); otherwise the track follows the segment estimates.
/// Recordings shorter than three segments get the whole-record estimate. Source "estimate".
pub fn estimate_track(x: &[f32], fs: f64, min_rpm: f64, max_rpm: f64) -> Result<SpeedTrack> {
    SpeedEstimator::new().estimate_track(x, fs, min_rpm, max_rpm)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shaft harmonics 1x..6x with weak odd ones (the octave trap), 60 Hz mains and its
    /// harmonics, noise.
    fn synthetic(rpm: f64, fs: f64, dur: f64) -> Vec<f32> {
        let f = rpm / 60.0;
        let mut rng: u64 = 12345;
        (0..(fs * dur) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                let mut v = 0.0;
                for k in 1..=6 {
                    let a = if k % 2 == 1 { 0.3 } else { 1.0 };
                    v += a * (2.0 * std::f64::consts::PI * k as f64 * f * t + k as f64).sin();
                }
                for k in 1..=5 {
                    v += 1.5 * (2.0 * std::f64::consts::PI * 60.0 * k as f64 * t).sin();
                }
                rng = rng
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                v += ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0;
                v as f32
            })
            .collect()
    }

    #[test]
    fn finds_the_shaft_line_despite_mains_and_strong_even_harmonics() {
        for rpm in [1797.0, 1000.0, 2400.0] {
            let x = synthetic(rpm, 12_000.0, 8.0);
            let e = estimate_constant(&x, 12_000.0, 300.0, 3600.0).unwrap();
            assert!((e.rpm / rpm - 1.0).abs() < 0.005, "{rpm}: got {}", e.rpm);
        }
    }

    #[test]
    fn tracks_a_speed_ramp() {
        // shaft harmonics under a 20 -> 26 Hz ramp over 12 s
        let (fs, dur, f0, f1) = (5_000.0, 12.0, 20.0, 26.0);
        let a = (f1 - f0) / dur;
        let theta = |t: f64| f0 * t + 0.5 * a * t * t;
        let mut rng: u64 = 99;
        let x: Vec<f32> = (0..(fs * dur) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                let mut v = 0.0;
                for k in 1..=5 {
                    v += (2.0 * std::f64::consts::PI * k as f64 * theta(t)).sin() / k as f64;
                }
                rng = rng
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                v += ((rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1.0;
                v as f32
            })
            .collect();
        let tr = estimate_track(&x, fs, 600.0, 3000.0).unwrap();
        assert_eq!(tr.source(), SpeedSourceKind::Estimate);
        // inside the segment centres (1 s .. 11 s) the track follows the ramp
        for t in [2.0, 4.0, 6.0, 8.0, 10.0] {
            let truth = 60.0 * (f0 + a * t);
            assert!(
                (tr.rpm_at(t) / truth - 1.0).abs() < 0.01,
                "at {t} s: {} vs {truth} rpm",
                tr.rpm_at(t)
            );
        }
    }

    #[test]
    fn too_short_or_nan_is_a_clear_error() {
        let x = synthetic(1800.0, 12_000.0, 0.5);
        assert!(estimate_constant(&x, 12_000.0, 300.0, 3600.0)
            .unwrap_err()
            .to_string()
            .contains("lasts 0.50 s"));
        let mut y = synthetic(1800.0, 12_000.0, 5.0);
        y[99] = f32::NAN;
        assert!(estimate_constant(&y, 12_000.0, 300.0, 3600.0)
            .unwrap_err()
            .to_string()
            .contains("sample 99"));
    }
}
