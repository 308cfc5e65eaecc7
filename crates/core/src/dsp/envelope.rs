//! Low-pass (or band-pass) and Hilbert envelope of a fixed-length block via realfft: one
//! forward real FFT, the bins outside the band and the negative frequencies zeroed (positive
//! ones doubled), one inverse complex FFT, magnitude. Plans and buffers are made once in
//! [`Envelope::new`]; [`Envelope::set_band`] moves the band without re-planning (a band chosen
//! per window by the kurtogram).

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Envelope detector for blocks of exactly `len` samples.
pub struct Envelope {
    len: usize,
    sample_rate: f64,
    /// Lowest FFT bin kept (1: DC removed).
    first: usize,
    /// Highest FFT bin kept (the low-pass cut-off).
    keep: usize,
    r2c: Arc<dyn RealToComplex<f32>>,
    ifft: Arc<dyn Fft<f32>>,
    input: Vec<f32>,
    spec: Vec<Complex<f32>>,
    analytic: Vec<Complex<f32>>,
    scratch_r: Vec<Complex<f32>>,
    scratch_c: Vec<Complex<f32>>,
}

impl Envelope {
    /// A detector for `len`-sample blocks at `sample_rate`, low-passed at `lowpass_hz`
    /// (clamped to Nyquist). DC is removed.
    pub fn new(len: usize, sample_rate: f64, lowpass_hz: f64) -> Self {
        assert!(len >= 4, "envelope block of {len} samples is too short");
        let r2c = RealFftPlanner::<f32>::new().plan_fft_forward(len);
        let ifft = FftPlanner::<f32>::new().plan_fft_inverse(len);
        let keep = ((lowpass_hz / sample_rate * len as f64).floor() as usize).min(len / 2);
        Envelope {
            len,
            sample_rate,
            first: 1,
            keep,
            input: vec![0.0; len],
            spec: r2c.make_output_vec(),
            analytic: vec![Complex::new(0.0, 0.0); len],
            scratch_r: r2c.make_scratch_vec(),
            scratch_c: vec![Complex::new(0.0, 0.0); ifft.get_inplace_scratch_len()],
            r2c,
            ifft,
        }
    }

    /// Keep only `lo_hz..=hi_hz` (FFT bins, clamped to DC excluded and Nyquist): an ideal
    /// band-pass before the envelope. `set_band(0.0, lowpass_hz)` is the detector of `new`.
    pub fn set_band(&mut self, lo_hz: f64, hi_hz: f64) {
        let bins = |hz: f64| hz / self.sample_rate * self.len as f64; // as in `new`
        self.first = (bins(lo_hz).ceil().max(1.0) as usize).min(self.len / 2 + 1);
        self.keep = (bins(hi_hz).floor().max(0.0) as usize).min(self.len / 2);
    }

    /// Block length this detector was planned for.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Envelope of `x` (exactly `len` samples) into `out` (same length).
    pub fn process(&mut self, x: &[f32], out: &mut [f32]) {
        assert_eq!(x.len(), self.len, "envelope input length");
        assert_eq!(out.len(), self.len, "envelope output length");
        self.input.copy_from_slice(x);
        self.r2c
            .process_with_scratch(&mut self.input, &mut self.spec, &mut self.scratch_r)
            .expect("buffer sizes match the plan");
        let n = self.len;
        let scale = 1.0 / n as f32;
        self.analytic
            .iter_mut()
            .for_each(|c| *c = Complex::new(0.0, 0.0));
        // DC removed; positive frequencies doubled; Nyquist (even n) kept once
        for k in self.first..=self.keep {
            let f = if 2 * k == n { 1.0 } else { 2.0 };
            self.analytic[k] = self.spec[k] * (f * scale);
        }
        self.ifft
            .process_with_scratch(&mut self.analytic, &mut self.scratch_c);
        for (o, z) in out.iter_mut().zip(&self.analytic) {
            *o = z.norm();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_of_am_carrier_is_the_modulation() {
        let (fs, n) = (10_000.0, 10_000);
        let x: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                ((1.0 + 0.5 * (2.0 * std::f64::consts::PI * 7.0 * t).cos())
                    * (2.0 * std::f64::consts::PI * 2500.0 * t).sin()
                    + 0.3) as f32
            })
            .collect();
        let mut env = Envelope::new(n, fs, 4000.0);
        let mut out = vec![0.0; n];
        env.process(&x, &mut out);
        for i in (500..9500).step_by(97) {
            let t = i as f64 / fs;
            let want = 1.0 + 0.5 * (2.0 * std::f64::consts::PI * 7.0 * t).cos();
            assert!(
                (out[i] as f64 - want).abs() < 0.01,
                "at {i}: {} vs {want}",
                out[i]
            );
        }
        // a carrier above the low-pass disappears
        let y: Vec<f32> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 4500.0 * i as f64 / fs).sin() as f32)
            .collect();
        env.process(&y, &mut out);
        assert!(out.iter().all(|v| *v < 1e-3));
    }

    #[test]
    fn a_band_keeps_only_its_carrier() {
        // two carriers, 7 Hz modulation on 2500 Hz and 3 Hz on 1000 Hz: the 2-3 kHz band's
        // envelope is the first modulation alone; the low-pass at 4 kHz mixes both
        let (fs, n) = (10_000.0, 10_000);
        let tau = 2.0 * std::f64::consts::PI;
        let x: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                ((1.0 + 0.5 * (tau * 7.0 * t).cos()) * (tau * 2500.0 * t).sin()
                    + (1.0 + 0.5 * (tau * 3.0 * t).cos()) * (tau * 1000.0 * t).sin())
                    as f32
            })
            .collect();
        let mut env = Envelope::new(n, fs, 4000.0);
        let mut out = vec![0.0; n];
        env.set_band(2000.0, 3000.0);
        env.process(&x, &mut out);
        for i in (500..9500).step_by(97) {
            let t = i as f64 / fs;
            let want = 1.0 + 0.5 * (tau * 7.0 * t).cos();
            assert!(
                (out[i] as f64 - want).abs() < 0.01,
                "at {i}: {} vs {want}",
                out[i]
            );
        }
        // back to the low-pass: bit for bit the detector of `new`, whose envelope is the sum
        // of both carriers, not the 7 Hz envelope alone
        env.set_band(0.0, 4000.0);
        env.process(&x, &mut out);
        let mut fresh = vec![0.0; n];
        Envelope::new(n, fs, 4000.0).process(&x, &mut fresh);
        assert_eq!(out, fresh);
        let worst = (500..9500)
            .map(|i| {
                let t = i as f64 / fs;
                (out[i] as f64 - (1.0 + 0.5 * (tau * 7.0 * t).cos())).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst > 0.5, "{worst}");
    }
}
