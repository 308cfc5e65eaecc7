//! Fault-signature check for simulated constant-speed signals: the thesis' envelope spectrum
//! (low-pass, Hilbert envelope via FFT, Hann-windowed spectrum of the envelope) and peak
//! picking with parabolic interpolation. Used by the simulator's tests and the validation
//! table in `rigmon bench simulate`; the product's feature pipeline lives in `dsp`.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;

/// One-sided amplitude spectrum of the envelope: bin spacing `df` Hz.
#[derive(Debug, Clone)]
pub struct EnvelopeSpectrum {
    pub df: f64,
    pub amp: Vec<f64>,
}

/// Envelope spectrum of `x` sampled at `fs`: band [highpass_hz, lowpass_hz] kept before the
/// Hilbert envelope; the envelope spectrum is zero-padded `pad` times.
pub fn envelope_spectrum(
    x: &[f32],
    fs: f64,
    highpass_hz: f64,
    lowpass_hz: f64,
    pad: usize,
) -> EnvelopeSpectrum {
    let n = x.len();
    let mut planner = FftPlanner::<f64>::new();
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
    let mut buf: Vec<Complex<f64>> = x
        .iter()
        .map(|&v| Complex::new(v as f64 - mean, 0.0))
        .collect();
    planner.plan_fft_forward(n).process(&mut buf);
    // analytic signal restricted to the band
    for (k, b) in buf.iter_mut().enumerate() {
        let f = k as f64 * fs / n as f64;
        if k == 0 || k > n / 2 || f < highpass_hz || f > lowpass_hz {
            *b = Complex::new(0.0, 0.0);
        } else {
            *b *= 2.0;
        }
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    let env: Vec<f64> = buf.iter().map(|c| c.norm() / n as f64).collect();
    let em = env.iter().sum::<f64>() / n as f64;
    let m = n * pad.max(1);
    let mut spec = vec![Complex::new(0.0, 0.0); m];
    let mut wsum = 0.0;
    for (i, &e) in env.iter().enumerate() {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
        wsum += w;
        spec[i] = Complex::new((e - em) * w, 0.0);
    }
    planner.plan_fft_forward(m).process(&mut spec);
    let amp = spec[..m / 2]
        .iter()
        .map(|c| 2.0 * c.norm() / wsum)
        .collect();
    EnvelopeSpectrum {
        df: fs / m as f64,
        amp,
    }
}

impl EnvelopeSpectrum {
    /// Largest peak within `f0 * (1 +- rel)`: (interpolated frequency, amplitude).
    pub fn peak_near(&self, f0: f64, rel: f64) -> (f64, f64) {
        let lo = ((f0 * (1.0 - rel)) / self.df).floor().max(1.0) as usize;
        let hi = (((f0 * (1.0 + rel)) / self.df).ceil() as usize).min(self.amp.len() - 2);
        let k = (lo..=hi)
            .max_by(|&a, &b| self.amp[a].total_cmp(&self.amp[b]))
            .unwrap_or(lo);
        let (a, b, c) = (self.amp[k - 1], self.amp[k], self.amp[k + 1]);
        let den = a - 2.0 * b + c;
        let off = if den.abs() > 0.0 {
            (0.5 * (a - c) / den).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        ((k as f64 + off) * self.df, b)
    }

    /// Median amplitude over [f_lo, f_hi] Hz: the noise floor.
    pub fn median(&self, f_lo: f64, f_hi: f64) -> f64 {
        let lo = (f_lo / self.df).floor().max(1.0) as usize;
        let hi = ((f_hi / self.df).ceil() as usize).min(self.amp.len() - 1);
        let mut v: Vec<f64> = self.amp[lo..=hi].to_vec();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn am_signal_envelope_line() {
        let fs = 10_000.0;
        let x: Vec<f32> = (0..40_000)
            .map(|i| {
                let t = i as f64 / fs;
                ((1.0 + 0.5 * (std::f64::consts::TAU * 45.3 * t).cos())
                    * (std::f64::consts::TAU * 3000.0 * t).sin()) as f32
            })
            .collect();
        let s = envelope_spectrum(&x, fs, 500.0, 4000.0, 4);
        let (f, a) = s.peak_near(45.0, 0.05);
        assert!((f - 45.3).abs() < 0.02, "{f}");
        assert!((a - 0.5).abs() < 0.05, "{a}");
        assert!(s.median(5.0, 200.0) < 0.01);
    }
}
