//! Band-limited resampling of a whole stretch of samples down to a lower rate, in the
//! frequency domain: the stretch is mirrored at its end (so its periodic continuation has no
//! jump to ring, only a kink that rings for about 2.5 ms at the new rate at each end), transformed once, its spectrum kept unchanged up to [`PASS_FRACTION`] of
//! the new rate, rolled off with a raised cosine to zero at the new Nyquist frequency and cut
//! there (nothing above it can alias), and transformed back at the new length. The new
//! length is the largest whole number of samples the target rate allows, so the new rate is
//! reported exactly as the ratio used (`rate_in * len_out / len_in`, at most the target).
//! A [`Resampler`] is planned once for a stretch length and reused for every channel.

use anyhow::{bail, Result};
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex64;
use std::sync::Arc;

/// Content below this fraction of the new sample rate passes unchanged (0.45: 90 % of the
/// new Nyquist band; the calibration views read up to 0.4 of the rate).
pub const PASS_FRACTION: f64 = 0.45;

/// The kink the mirror leaves at each end of the stretch rings for about this long at the
/// new rate (a sine just below the pass band's edge: under 0.2 % of its amplitude after it).
#[cfg(test)]
const EDGE_S: f64 = 0.0025;

/// FFT plans, the gain per output bin and buffers for one stretch length and rate pair.
pub struct Resampler {
    len_in: usize,
    len_out: usize,
    rate_in: f64,
    rate_out: f64,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
    /// Gain of output bin k (0..=len_out), the 1 / (2 len_in) of the transform pair included.
    gain: Vec<f64>,
    mirrored: Vec<f64>,
    spectrum: Vec<Complex64>,
    kept: Vec<Complex64>,
    out: Vec<f64>,
    scratch: Vec<Complex64>,
}

impl Resampler {
    /// Plan the resampling of `len_in` samples at `rate_in` Hz to at most `target_rate` Hz
    /// (below `rate_in`).
    pub fn new(len_in: usize, rate_in: f64, target_rate: f64) -> Result<Resampler> {
        if !(rate_in.is_finite() && rate_in > 0.0) {
            bail!("cannot resample from a sample rate of {rate_in} Hz; the rate must be a positive number");
        }
        if !(target_rate.is_finite() && target_rate > 0.0 && target_rate < rate_in) {
            bail!(
                "cannot resample from {rate_in} Hz to {target_rate} Hz: the resampler only lowers the rate, to a positive one"
            );
        }
        // the largest whole number of output samples the target rate allows (the small
        // tolerance keeps an exact ratio such as 4:1 from losing a sample to rounding)
        let len_out = (len_in as f64 * target_rate / rate_in + 1e-9).floor() as usize;
        if len_out < 2 {
            bail!(
                "cannot resample {len_in} samples at {rate_in} Hz to {target_rate} Hz: fewer than 2 samples would be left; use a longer stretch"
            );
        }
        let rate_out = rate_in * len_out as f64 / len_in as f64;
        let mut planner = RealFftPlanner::<f64>::new();
        let forward = planner.plan_fft_forward(2 * len_in);
        let inverse = planner.plan_fft_inverse(2 * len_out);
        let scratch_len = forward.get_scratch_len().max(inverse.get_scratch_len());
        // Output bin k of the mirrored stretch (length 2 len_out) is at k rate_out / (2 len_out) Hz.
        let nyquist_bin = len_out as f64;
        let pass_bin = 2.0 * PASS_FRACTION * nyquist_bin;
        let scale = 1.0 / (2 * len_in) as f64;
        let gain = (0..=len_out)
            .map(|k| {
                let k = k as f64;
                let g = if k <= pass_bin {
                    1.0
                } else if k >= nyquist_bin {
                    0.0
                } else {
                    0.5 * (1.0
                        + (std::f64::consts::PI * (k - pass_bin) / (nyquist_bin - pass_bin)).cos())
                };
                g * scale
            })
            .collect();
        Ok(Resampler {
            len_in,
            len_out,
            rate_in,
            rate_out,
            mirrored: forward.make_input_vec(),
            spectrum: forward.make_output_vec(),
            kept: inverse.make_input_vec(),
            out: inverse.make_output_vec(),
            scratch: vec![Complex64::default(); scratch_len],
            forward,
            inverse,
            gain,
        })
    }

    /// Samples per stretch at the new rate.
    #[cfg(test)]
    pub fn len_out(&self) -> usize {
        self.len_out
    }

    /// The new rate, Hz: `rate_in * len_out / len_in`.
    pub fn rate_out(&self) -> f64 {
        self.rate_out
    }

    /// `x` (`len_in` samples at the old rate) at the new rate; sample k is at time
    /// k / rate_out from the first sample of `x`.
    pub fn process(&mut self, x: &[f32]) -> Result<Vec<f32>> {
        if x.len() != self.len_in {
            bail!(
                "the resampler was planned for {} samples but got {}; plan one per stretch length",
                self.len_in,
                x.len()
            );
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            bail!(
                "sample {i} ({} s) is {}; resampling to {:.3} Hz needs finite samples (cut the stretch to avoid it)",
                i as f64 / self.rate_in,
                x[i],
                self.rate_out
            );
        }
        let n = self.len_in;
        for (i, &v) in x.iter().enumerate() {
            self.mirrored[i] = v as f64;
            self.mirrored[2 * n - 1 - i] = v as f64;
        }
        self.forward
            .process_with_scratch(&mut self.mirrored, &mut self.spectrum, &mut self.scratch)
            .map_err(|e| anyhow::anyhow!("forward FFT of the stretch: {e}"))?;
        for (k, (o, g)) in self.kept.iter_mut().zip(&self.gain).enumerate() {
            *o = self.spectrum[k] * *g;
        }
        // the DC and Nyquist bins of a real signal are real (Nyquist is cut to 0 anyway)
        self.kept[0].im = 0.0;
        self.kept[self.len_out].im = 0.0;
        self.inverse
            .process_with_scratch(&mut self.kept, &mut self.out, &mut self.scratch)
            .map_err(|e| anyhow::anyhow!("inverse FFT of the stretch: {e}"))?;
        Ok(self.out[..self.len_out].iter().map(|&v| v as f32).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(n: usize, fs: f64, hz: f64, amp: f64, phase: f64) -> Vec<f32> {
        (0..n)
            .map(|i| (amp * (std::f64::consts::TAU * hz * i as f64 / fs + phase).sin()) as f32)
            .collect()
    }

    fn rms(x: &[f32]) -> f64 {
        (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    }

    /// Amplitude and frequency of the one sine in `x` (least squares on a fine frequency
    /// grid around `near`), away from the stretch's ends.
    fn fit_sine(x: &[f32], fs: f64, near: f64) -> (f64, f64) {
        let skip = x.len() / 10;
        let y = &x[skip..x.len() - skip];
        let amp_at = |hz: f64| {
            let (mut c, mut s) = (0.0, 0.0);
            for (i, &v) in y.iter().enumerate() {
                let p = std::f64::consts::TAU * hz * (i + skip) as f64 / fs;
                c += v as f64 * p.cos();
                s += v as f64 * p.sin();
            }
            2.0 * (c * c + s * s).sqrt() / y.len() as f64
        };
        let mut best = (near, 0.0);
        for k in -200..=200 {
            let hz = near * (1.0 + k as f64 * 1e-5);
            let a = amp_at(hz);
            if a > best.1 {
                best = (hz, a);
            }
        }
        best
    }

    #[test]
    fn a_sine_below_the_new_nyquist_keeps_its_frequency_and_amplitude() {
        // 48 kHz -> 12 kHz, 2 s; 1 kHz and 4.5 kHz (in the pass band, 0.375 of the new rate)
        let (fs, n) = (48_000.0, 96_000);
        let mut r = Resampler::new(n, fs, 12_000.0).unwrap();
        assert_eq!(r.len_out(), 24_000);
        assert_eq!(r.rate_out(), 12_000.0);
        for (hz, amp) in [(1000.0, 1.0), (4500.0, 0.3), (29.93, 2.0)] {
            let y = r.process(&sine(n, fs, hz, amp, 0.4)).unwrap();
            assert_eq!(y.len(), 24_000);
            let (f, a) = fit_sine(&y, r.rate_out(), hz);
            assert!((f - hz).abs() <= 1e-4 * hz, "{hz} Hz came out at {f} Hz");
            assert!(
                (a - amp).abs() <= 0.005 * amp,
                "{hz} Hz: amplitude {a}, was {amp}"
            );
            // and sample by sample, where it should be in time: the mirror leaves no jump,
            // only a kink whose ringing dies out within EDGE_S of the ends
            let truth = sine(24_000, 12_000.0, hz, amp, 0.4);
            let edge = (EDGE_S * 12_000.0) as usize;
            let worst = y[edge..y.len() - edge]
                .iter()
                .zip(&truth[edge..])
                .map(|(a, b)| (a - b).abs() as f64)
                .fold(0.0, f64::max);
            assert!(worst < 0.002 * amp, "{hz} Hz: worst sample off by {worst}");
        }
    }

    #[test]
    fn content_above_the_new_nyquist_is_gone() {
        let (fs, n) = (48_000.0, 96_000);
        let mut r = Resampler::new(n, fs, 12_000.0).unwrap();
        // 6.6 kHz (just above the new Nyquist) and 8.4 kHz (would alias to 3.6 kHz)
        for hz in [6600.0, 8400.0, 20_000.0] {
            let x = sine(n, fs, hz, 1.0, 0.0);
            let y = r.process(&x).unwrap();
            let down_db = 20.0 * (rms(&y) / rms(&x)).log10();
            assert!(down_db <= -40.0, "{hz} Hz only {down_db:.1} dB down");
        }
        // a mix keeps its low part and loses its high part
        let low = sine(n, fs, 700.0, 1.0, 0.0);
        let mix: Vec<f32> = low
            .iter()
            .zip(sine(n, fs, 8400.0, 1.0, 1.0))
            .map(|(a, b)| a + b)
            .collect();
        let y = r.process(&mix).unwrap();
        let (_, a) = fit_sine(&y, 12_000.0, 3600.0);
        assert!(a < 0.01, "the 8.4 kHz line aliased to 3.6 kHz at {a}");
        let (_, a) = fit_sine(&y, 12_000.0, 700.0);
        assert!((a - 1.0).abs() < 0.005, "700 Hz at {a}");
    }

    #[test]
    fn a_non_integer_ratio_reports_the_rate_it_used() {
        // 97,656 Hz (a public 8-roller rig) -> 12 kHz, 2 s
        let (fs, n) = (97_656.0, 195_312);
        let mut r = Resampler::new(n, fs, 12_000.0).unwrap();
        assert_eq!(r.len_out(), 24_000);
        assert!((r.rate_out() - 12_000.0).abs() < 1e-9, "{}", r.rate_out());
        let y = r.process(&sine(n, fs, 2345.6, 1.0, 0.0)).unwrap();
        let (f, a) = fit_sine(&y, r.rate_out(), 2345.6);
        assert!(
            (f - 2345.6).abs() < 0.05 && (a - 1.0).abs() < 0.005,
            "{f} Hz, {a}"
        );
        // a length that does not divide: the rate is the ratio used, never above the target
        let n = 243_938; // CWRU 97, 48 kHz
        let r = Resampler::new(n, 48_000.0, 12_000.0).unwrap();
        assert_eq!(r.len_out(), 60_984);
        assert_eq!(r.rate_out(), 48_000.0 * 60_984.0 / 243_938.0);
        assert!(r.rate_out() <= 12_000.0 && r.rate_out() > 11_999.9);
        let mut r = Resampler::new(100_003, 97_656.0, 12_000.0).unwrap();
        let y = r
            .process(&sine(100_003, 97_656.0, 1500.0, 1.0, 0.0))
            .unwrap();
        assert_eq!(y.len(), r.len_out());
        let (f, a) = fit_sine(&y, r.rate_out(), 1500.0);
        assert!(
            (f - 1500.0).abs() < 0.05 && (a - 1.0).abs() < 0.005,
            "{f} Hz, {a}"
        );
    }

    #[test]
    fn refuses_what_it_cannot_do_and_says_why() {
        let e = |r: Result<Resampler>| format!("{:#}", r.err().unwrap());
        assert!(e(Resampler::new(1000, 12_000.0, 12_000.0)).contains("only lowers"));
        assert!(e(Resampler::new(1000, 12_000.0, 24_000.0)).contains("only lowers"));
        assert!(e(Resampler::new(3, 48_000.0, 12_000.0)).contains("longer stretch"));
        let mut r = Resampler::new(1000, 48_000.0, 12_000.0).unwrap();
        assert!(format!("{:#}", r.process(&[0.0; 999]).unwrap_err()).contains("999"));
        let mut x = vec![0.0f32; 1000];
        x[500] = f32::NAN;
        assert!(format!("{:#}", r.process(&x).unwrap_err()).contains("sample 500"));
    }
}
