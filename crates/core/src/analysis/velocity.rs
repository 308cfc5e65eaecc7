//! Broadband velocity RMS (10-1000 Hz, ISO 20816-3) from an acceleration window: Hann window,
//! real FFT, divide by j*2*pi*f, sum the band (Parseval, corrected for the window's power).
//! The FFT plan and buffers are made once per window length and reused.

use crate::vocabulary::AccelUnit;
use realfft::{RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex32;
use std::sync::Arc;

/// Band of ISO 20816-3 for machines above 600 rpm.
pub const BAND_HZ: (f64, f64) = (10.0, 1000.0);

/// Velocity RMS calculator for one window length.
pub struct VelocityRms {
    fft: Arc<dyn RealToComplex<f32>>,
    window: Vec<f32>,
    input: Vec<f32>,
    spectrum: Vec<Complex32>,
    scratch: Vec<Complex32>,
    sample_rate: f64,
    /// Mean of window^2 (power correction).
    window_power: f64,
}

impl VelocityRms {
    pub fn new(len: usize, sample_rate: f64) -> Self {
        let fft = RealFftPlanner::<f32>::new().plan_fft_forward(len);
        let window: Vec<f32> = (0..len)
            .map(|i| {
                (0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / len as f64).cos()) as f32
            })
            .collect();
        let window_power = window.iter().map(|&w| (w as f64).powi(2)).sum::<f64>() / len as f64;
        VelocityRms {
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            window,
            sample_rate,
            window_power,
        }
    }

    /// Velocity RMS in mm/s of `accel` given in `unit`. None for a wrong length or
    /// non-finite samples.
    pub fn mm_per_s(&mut self, accel: &[f32], unit: AccelUnit) -> Option<f64> {
        let to_m_s2 = unit.factor_to_m_s2();
        let n = self.window.len();
        if accel.len() != n || accel.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let mean = accel.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        for ((dst, &x), &w) in self.input.iter_mut().zip(accel).zip(&self.window) {
            *dst = ((x as f64 - mean) as f32) * w;
        }
        self.fft
            .process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch)
            .ok()?;
        let df = self.sample_rate / n as f64;
        let (lo, hi) = BAND_HZ;
        let mut sum = 0.0f64;
        for (k, c) in self.spectrum.iter().enumerate().skip(1) {
            let f = k as f64 * df;
            if f < lo || f > hi {
                continue;
            }
            let a2 = (c.re as f64).powi(2) + (c.im as f64).powi(2);
            let w = 2.0 * std::f64::consts::PI * f;
            // One-sided: bins other than DC/Nyquist count twice.
            let twice = if 2 * k == n { 1.0 } else { 2.0 };
            sum += twice * a2 / (w * w);
        }
        let v_rms = (sum / (n as f64 * n as f64 * self.window_power)).sqrt();
        Some(v_rms * to_m_s2 * 1000.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sine_velocity_matches_the_analytic_value() {
        // a(t) = A sin(2 pi f t): v_rms = A / (2 pi f) / sqrt(2).
        let fs = 10_000.0;
        let n = 10_000;
        let (f, a) = (100.0, 5.0);
        let x: Vec<f32> = (0..n)
            .map(|i| (a * (2.0 * std::f64::consts::PI * f * i as f64 / fs).sin()) as f32)
            .collect();
        let mut v = VelocityRms::new(n, fs);
        let got = v.mm_per_s(&x, AccelUnit::MetrePerSecondSquared).unwrap();
        let want = a / (2.0 * std::f64::consts::PI * f) / 2f64.sqrt() * 1000.0;
        assert!((got / want - 1.0).abs() < 0.01, "got {got}, want {want}");
        // In g the same numbers mean 9.81 times more.
        let got_g = v.mm_per_s(&x, AccelUnit::StandardGravity).unwrap();
        assert!((got_g / got - 9.80665).abs() < 1e-6);
        // Outside the band (5 Hz and 2 kHz) contributes almost nothing.
        let y: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (a * (2.0 * std::f64::consts::PI * 5.0 * t).sin()
                    + a * (2.0 * std::f64::consts::PI * 2000.0 * t).sin()) as f32
            })
            .collect();
        let m_s2 = AccelUnit::MetrePerSecondSquared;
        assert!(v.mm_per_s(&y, m_s2).unwrap() < 0.02 * want);
        let mut bad = x.clone();
        bad[3] = f32::NAN;
        assert!(v.mm_per_s(&bad, AccelUnit::StandardGravity).is_none());
    }
}
