//! Computed order tracking: the envelope of one block is band-limited (anti-aliasing) and
//! decimated in the frequency domain, then resampled at constant shaft-angle increments
//! (`samples_per_rev` per revolution) along the [`SpeedTrack`] with cubic interpolation.
//! The angle grid is computed once per window and shared by every channel.

use crate::dsp::fft_len::fast_len_at_least;
use crate::dsp::speed::SpeedTrack;
use anyhow::{bail, Result};
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::sync::Arc;

/// Oversampling of the decimated envelope relative to its band edge (for cubic interpolation).
const OVERSAMPLE: usize = 5;

/// Samples per revolution for a recipe reaching `max_order`: a power of two with the order
/// Nyquist at least 1.28 x max_order.
pub fn samples_per_rev(max_order: f64) -> usize {
    ((2.56 * max_order).ceil() as usize)
        .next_power_of_two()
        .max(16)
}

/// What the angle grid of the current window looks like.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridInfo {
    /// Angle samples in the window.
    pub count: usize,
    /// Revolutions covered.
    pub revolutions: f64,
    /// Slowest and fastest shaft frequency in the window, Hz.
    pub f_min: f64,
    pub f_max: f64,
    /// Anti-aliasing cut-off applied to the envelope, Hz.
    pub cutoff_hz: f64,
}

/// Order tracker for blocks of exactly `len` samples.
pub struct OrderTracker {
    len: usize,
    sample_rate: f64,
    samples_per_rev: usize,
    max_order: f64,
    r2c: Arc<dyn RealToComplex<f32>>,
    planner: RealFftPlanner<f32>,
    input: Vec<f32>,
    spec: Vec<Complex<f32>>,
    scratch_r: Vec<Complex<f32>>,
    // decimation (length depends on the slowest speed in the window)
    dec_len: usize,
    keep: usize,
    c2r: Option<Arc<dyn ComplexToReal<f32>>>,
    dec_spec: Vec<Complex<f32>>,
    dec: Vec<f32>,
    scratch_c: Vec<Complex<f32>>,
    // angle grid of the current window: positions in decimated samples
    times: Vec<f64>,
    pos: Vec<f64>,
    count: usize,
}

impl OrderTracker {
    /// A tracker for `len`-sample blocks at `sample_rate`, for orders up to `max_order`.
    pub fn new(len: usize, sample_rate: f64, max_order: f64) -> Self {
        let mut planner = RealFftPlanner::<f32>::new();
        let r2c = planner.plan_fft_forward(len);
        OrderTracker {
            len,
            sample_rate,
            samples_per_rev: samples_per_rev(max_order),
            max_order,
            input: vec![0.0; len],
            spec: r2c.make_output_vec(),
            scratch_r: r2c.make_scratch_vec(),
            r2c,
            planner,
            dec_len: 0,
            keep: 0,
            c2r: None,
            dec_spec: Vec::with_capacity(len / 2 + 1),
            dec: Vec::with_capacity(len),
            scratch_c: Vec::new(),
            times: Vec::new(),
            pos: Vec::new(),
            count: 0,
        }
    }

    pub fn samples_per_rev(&self) -> usize {
        self.samples_per_rev
    }

    /// Build the angle grid for the block starting at `t_start` (s). Fails when the window
    /// holds less than one revolution.
    pub fn prepare(&mut self, t_start: f64, speed: &SpeedTrack) -> Result<GridInfo> {
        let dur = self.len as f64 / self.sample_rate;
        let t_end = t_start + dur;
        let (f_min, f_max) = speed.speed_range_hz(t_start, t_end);
        let th0 = speed.angle_at(t_start);
        let th1 = speed.angle_at(t_end - 1.0 / self.sample_rate);
        let revolutions = th1 - th0;
        let s = self.samples_per_rev as f64;
        let count = (revolutions * s).floor() as usize + 1;
        if !(revolutions >= 1.0 && f_min > 0.0) {
            bail!(
                "window at t = {t_start:.3} s covers {revolutions:.2} revolutions (speed {:.1} rpm); at least one is needed — use longer windows (features.window_s) or check the speed source",
                60.0 * f_min
            );
        }
        // anti-aliasing: content above (S - max_order) orders would fold into the bins
        let nyq = self.sample_rate / 2.0;
        let cutoff_hz = ((s - self.max_order) * f_min).min(nyq);
        let keep = ((cutoff_hz * dur).floor() as usize).min(self.len / 2);
        let dec_len = if OVERSAMPLE * keep >= self.len {
            self.len
        } else {
            fast_len_at_least(OVERSAMPLE * keep).min(self.len)
        };
        if dec_len != self.dec_len || self.c2r.is_none() {
            let c2r = self.planner.plan_fft_inverse(dec_len);
            if self.scratch_c.len() < c2r.get_scratch_len() {
                self.scratch_c
                    .resize(c2r.get_scratch_len(), Complex::new(0.0, 0.0));
            }
            self.dec_spec
                .resize(dec_len / 2 + 1, Complex::new(0.0, 0.0));
            self.dec.resize(dec_len, 0.0);
            self.c2r = Some(c2r);
            self.dec_len = dec_len;
        }
        self.keep = keep;
        if self.times.len() < count {
            // headroom: the count follows the speed; do not regrow for a sample or two
            self.times.resize(count + count / 4, 0.0);
            self.pos.resize(count + count / 4, 0.0);
        }
        self.count = count;
        speed.times_at_angles(th0, 1.0 / s, &mut self.times[..count]);
        let to_pos = self.sample_rate * dec_len as f64 / self.len as f64;
        for (p, &t) in self.pos[..count].iter_mut().zip(&self.times[..count]) {
            *p = (t - t_start) * to_pos;
        }
        Ok(GridInfo {
            count,
            revolutions,
            f_min,
            f_max,
            cutoff_hz,
        })
    }

    /// Resample one channel's envelope (`len` samples) onto the prepared angle grid:
    /// the first angle-sample count of `out` receives the order-domain signal.
    pub fn resample(&mut self, envelope: &[f32], out: &mut [f32]) {
        assert_eq!(envelope.len(), self.len, "order tracker input length");
        let c2r = self.c2r.as_ref().expect("prepare() before resample()");
        self.input.copy_from_slice(envelope);
        self.r2c
            .process_with_scratch(&mut self.input, &mut self.spec, &mut self.scratch_r)
            .expect("buffer sizes match the plan");
        let scale = 1.0 / self.len as f32;
        self.dec_spec
            .iter_mut()
            .for_each(|c| *c = Complex::new(0.0, 0.0));
        for k in 1..=self.keep.min(self.dec_len / 2) {
            self.dec_spec[k] = self.spec[k] * scale;
        }
        let last = self.dec_len / 2;
        self.dec_spec[last].im = 0.0;
        c2r.process_with_scratch(&mut self.dec_spec, &mut self.dec, &mut self.scratch_c)
            .expect("buffer sizes match the plan");
        let m = self.dec_len as isize;
        let d = &self.dec;
        let at = |i: isize| d[i.rem_euclid(m) as usize];
        for (o, &p) in out[..self.count].iter_mut().zip(&self.pos[..self.count]) {
            let i = p.floor();
            let f = (p - i) as f32;
            let i = i as isize;
            let (y0, y1, y2, y3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
            // Catmull-Rom
            *o = y1
                + 0.5
                    * f
                    * (y2 - y0
                        + f * (2.0 * y0 - 5.0 * y1 + 4.0 * y2 - y3
                            + f * (3.0 * (y1 - y2) + y3 - y0)));
        }
    }
}
