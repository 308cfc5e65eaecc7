//! Order spectra of an angle-domain (order-tracked) signal: the per-window power spectrum
//! used for the RMS bins ([`OrderFft`]), and the high-resolution whole-recording envelope
//! order spectrum ([`whole_recording`]) used by `inspect`, the CWRU checks and calibration.

use crate::dsp::envelope::Envelope;
use crate::dsp::fft_len::fast_len_at_most;
use crate::dsp::order_tracking::OrderTracker;
use crate::dsp::speed::SpeedTrack;
use anyhow::{bail, Result};
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

/// Hann-windowed, zero-padded FFT of an angle-domain signal. Buffers are reused; a new plan is
/// made only when the padded length changes (the planner caches it).
pub struct OrderFft {
    planner: RealFftPlanner<f32>,
    pad: usize,
    buf: Vec<f32>,
    spec: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
    window: Vec<f32>,
    window_sum: f32,
    window_sq: f32,
    lines: Vec<f32>,
}

impl OrderFft {
    /// `pad`: zero-padding factor (the FFT length is the next power of two >= pad x count).
    pub fn new(pad: usize) -> Self {
        OrderFft {
            planner: RealFftPlanner::new(),
            pad: pad.max(1),
            buf: Vec::new(),
            spec: Vec::new(),
            scratch: Vec::new(),
            window: Vec::new(),
            window_sum: 0.0,
            window_sq: 0.0,
            lines: Vec::new(),
        }
    }

    fn transform(&mut self, x: &[f32]) -> usize {
        let n = x.len();
        if self.window.len() != n {
            // Hann window by a rotation recurrence (the length follows the speed, so this runs
            // often; no trigonometry per sample). Headroom avoids regrowing by a sample or two.
            self.window.clear();
            self.window.reserve(n + n / 4);
            let (sd, cd) = (2.0 * std::f64::consts::PI / n as f64).sin_cos();
            let (mut c, mut s) = (1.0f64, 0.0f64);
            for _ in 0..n {
                self.window.push((0.5 - 0.5 * c) as f32);
                (c, s) = (c * cd - s * sd, s * cd + c * sd);
            }
            self.window_sum = self.window.iter().sum();
            self.window_sq = self.window.iter().map(|w| w * w).sum();
        }
        let len = (self.pad * n).next_power_of_two().max(256);
        let fft = self.planner.plan_fft_forward(len);
        self.buf.resize(len, 0.0);
        self.spec.resize(len / 2 + 1, Complex::new(0.0, 0.0));
        if self.scratch.len() < fft.get_scratch_len() {
            self.scratch
                .resize(fft.get_scratch_len(), Complex::new(0.0, 0.0));
        }
        let mean = x.iter().sum::<f32>() / n as f32;
        for ((b, &v), &w) in self.buf.iter_mut().zip(x).zip(&self.window) {
            *b = (v - mean) * w;
        }
        self.buf[n..].iter_mut().for_each(|b| *b = 0.0);
        fft.process_with_scratch(&mut self.buf, &mut self.spec, &mut self.scratch)
            .expect("buffer sizes match the plan");
        len
    }

    /// One-sided power per line, scaled so that the lines sum to the mean square of `x`
    /// (window-corrected). Returns (order step between lines, lines). `samples_per_rev` is
    /// the angular sample rate of `x`.
    pub fn power(&mut self, x: &[f32], samples_per_rev: usize) -> (f64, &[f32]) {
        let len = self.transform(x);
        let c = 1.0 / (len as f32 * self.window_sq);
        self.lines.resize(self.spec.len(), 0.0);
        let last = self.spec.len() - 1;
        for (j, (p, z)) in self.lines.iter_mut().zip(&self.spec).enumerate() {
            let two = if j == 0 || j == last { 1.0 } else { 2.0 };
            *p = two * c * z.norm_sqr();
        }
        (samples_per_rev as f64 / len as f64, &self.lines)
    }

    /// Peak-amplitude spectrum (a sinusoid of amplitude A at a line reads A).
    pub fn amplitude(&mut self, x: &[f32], samples_per_rev: usize) -> (f64, &[f32]) {
        let len = self.transform(x);
        let c = 2.0 / self.window_sum;
        self.lines.resize(self.spec.len(), 0.0);
        for (a, z) in self.lines.iter_mut().zip(&self.spec) {
            *a = c * z.norm();
        }
        (samples_per_rev as f64 / len as f64, &self.lines)
    }
}

/// A whole-recording envelope order spectrum.
#[derive(Debug, Clone, PartialEq)]
pub struct WholeSpectrum {
    /// Order step between lines.
    pub order_step: f64,
    /// Peak amplitude per line (unit of the channel), from order 0 to `max_order`.
    pub amplitude: Vec<f64>,
    /// Mean speed over the analysed span, rpm.
    pub rpm: f64,
    /// Revolutions analysed.
    pub revolutions: f64,
}

/// A peak of the spectrum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Order (parabolic interpolation between lines).
    pub order: f64,
    pub amplitude: f64,
}

impl WholeSpectrum {
    /// Order of line `j`.
    pub fn order(&self, j: usize) -> f64 {
        j as f64 * self.order_step
    }

    /// The highest line in `(lo, hi)`, refined by parabolic interpolation.
    pub fn peak_between(&self, lo: f64, hi: f64) -> Option<Peak> {
        let a = ((lo / self.order_step).floor() as usize + 1).max(1);
        let b =
            ((hi / self.order_step).ceil() as usize).min(self.amplitude.len().saturating_sub(1));
        let j = (a..b).max_by(|&x, &y| self.amplitude[x].total_cmp(&self.amplitude[y]))?;
        Some(self.refine(j))
    }

    fn refine(&self, j: usize) -> Peak {
        let a = &self.amplitude;
        if j == 0 || j + 1 >= a.len() {
            return Peak {
                order: self.order(j),
                amplitude: a[j],
            };
        }
        let (y0, y1, y2) = (a[j - 1], a[j], a[j + 1]);
        let den = y0 - 2.0 * y1 + y2;
        let d = if den.abs() > 0.0 {
            (0.5 * (y0 - y2) / den).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        Peak {
            order: (j as f64 + d) * self.order_step,
            amplitude: y1 - 0.25 * (y0 - y2) * d,
        }
    }

    /// The `n` highest local maxima in `(lo, hi)`, at least `min_sep` orders apart.
    pub fn top_peaks(&self, n: usize, lo: f64, hi: f64, min_sep: f64) -> Vec<Peak> {
        let a = &self.amplitude;
        let first = ((lo / self.order_step).floor() as usize + 1).max(1);
        let last = ((hi / self.order_step).ceil() as usize).min(a.len().saturating_sub(1));
        let mut cands: Vec<usize> = (first..last)
            .filter(|&j| a[j] > a[j - 1] && a[j] >= a[j + 1])
            .collect();
        cands.sort_by(|&x, &y| a[y].total_cmp(&a[x]));
        let mut out: Vec<Peak> = Vec::new();
        for j in cands {
            let p = self.refine(j);
            if out.iter().all(|q| (q.order - p.order).abs() >= min_sep) {
                out.push(p);
                if out.len() == n {
                    break;
                }
            }
        }
        out
    }
}

/// Envelope order spectrum of a whole recording channel: low-pass at `lowpass_hz`, Hilbert
/// envelope, order tracking along `speed`, one Hann-windowed FFT over all revolutions
/// (zero-padded x2). Lines up to `max_order`.
pub fn whole_recording(
    samples: &[f32],
    sample_rate: f64,
    speed: &SpeedTrack,
    lowpass_hz: f64,
    max_order: f64,
) -> Result<WholeSpectrum> {
    whole_recording_band(samples, sample_rate, speed, (0.0, lowpass_hz), max_order)
}

/// As [`whole_recording`], the envelope taken over the band `lo_hz..hi_hz` (an ideal
/// band-pass; `(0, lowpass_hz)` is the low-pass).
pub fn whole_recording_band(
    samples: &[f32],
    sample_rate: f64,
    speed: &SpeedTrack,
    (lo_hz, hi_hz): (f64, f64),
    max_order: f64,
) -> Result<WholeSpectrum> {
    if !(lo_hz >= 0.0 && lo_hz < hi_hz) {
        bail!(
            "envelope band {lo_hz}-{hi_hz} Hz: the low edge must be >= 0 and below the high edge"
        );
    }
    if let Some(i) = samples.iter().position(|v| !v.is_finite()) {
        bail!(
            "sample {i} (t = {:.4} s) is {}; the recording must be finite",
            i as f64 / sample_rate,
            samples[i]
        );
    }
    if samples.len() < 64 {
        bail!(
            "only {} samples; need at least 64 for an order spectrum",
            samples.len()
        );
    }
    let n = fast_len_at_most(samples.len());
    let x = &samples[..n];
    let mut env = Envelope::new(n, sample_rate, hi_hz);
    env.set_band(lo_hz, hi_hz);
    let mut e = vec![0.0f32; n];
    env.process(x, &mut e);
    let mut tracker = OrderTracker::new(n, sample_rate, max_order);
    let info = tracker.prepare(0.0, speed)?;
    let mut ang = vec![0.0f32; info.count];
    tracker.resample(&e, &mut ang);
    let spr = tracker.samples_per_rev();
    let mut fft = OrderFft::new(2);
    let (step, lines) = fft.amplitude(&ang, spr);
    let top = ((max_order / step).ceil() as usize + 1).min(lines.len());
    Ok(WholeSpectrum {
        order_step: step,
        amplitude: lines[..top].iter().map(|&v| v as f64).collect(),
        rpm: speed.mean_rpm(0.0, n as f64 / sample_rate),
        revolutions: info.revolutions,
    })
}
