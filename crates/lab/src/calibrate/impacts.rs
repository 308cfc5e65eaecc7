//! Impacting in Hz: the spectrum of the broadband energy envelope. The raw signal is
//! band-passed to the `bands` range ([`super::views::BAND_MIN_HZ`] to 0.4 fs, where impacts
//! ring through the structure), squared (its energy over time), and the Hann-windowed
//! spectrum of that energy is read on a 1 Hz grid from [`MIN_HZ`] to [`MAX_HZ`], in dB above
//! the local median (+-[`MEDIAN_HALF_WIDTH_HZ`]) less a 6 dB threshold. Repetitive impacts
//! show as lines at their rate whether or not it is a bearing fault order or locked to the
//! shaft (the `env` view is in orders and only the fault combs are located in it).

use realfft::{RealFftPlanner, RealToComplex};
use std::cell::RefCell;
use std::sync::Arc;

pub const MIN_HZ: usize = 2;
pub const MAX_HZ: usize = 500;
pub const MEDIAN_HALF_WIDTH_HZ: f64 = 25.0;
const THRESHOLD_DB: f64 = 6.0;
const CAP_DB: f64 = 60.0;

thread_local! {
    /// FFT plans by length, kept per thread (the calibrator computes this view for every
    /// simulated twin, always at the same few lengths).
    static PLANNER: RefCell<RealFftPlanner<f64>> = RefCell::new(RealFftPlanner::new());
}

fn forward(n: usize) -> Arc<dyn RealToComplex<f64>> {
    PLANNER.with(|p| p.borrow_mut().plan_fft_forward(n))
}

/// Frequencies of the view, Hz.
pub fn frequencies() -> Vec<f64> {
    (MIN_HZ..=MAX_HZ).map(|h| h as f64).collect()
}

/// Thresholded envelope-spectrum levels at [`frequencies`] (0 for fewer than 64 samples or a
/// rate too low for the band).
pub fn measure(x: &[f32], fs: f64, band_lo_hz: f64) -> Vec<f64> {
    let nf = MAX_HZ - MIN_HZ + 1;
    let n = x.len() - x.len() % 2;
    let band_hi = 0.4 * fs;
    if n < 64 || band_hi <= band_lo_hz || 2.0 * MAX_HZ as f64 >= fs {
        return vec![0.0; nf];
    }
    let fft = forward(n);
    let inv = PLANNER.with(|p| p.borrow_mut().plan_fft_inverse(n));
    let mut input = fft.make_input_vec();
    let mean = x[..n].iter().map(|v| *v as f64).sum::<f64>() / n as f64;
    for (d, v) in input.iter_mut().zip(&x[..n]) {
        *d = *v as f64 - mean;
    }
    let mut spec = fft.make_output_vec();
    fft.process(&mut input, &mut spec).expect("fft sizes match");
    let df = fs / n as f64;
    for (k, c) in spec.iter_mut().enumerate() {
        let f = k as f64 * df;
        if f < band_lo_hz || f > band_hi {
            *c = realfft::num_complex::Complex::new(0.0, 0.0);
        }
    }
    let mut band = inv.make_output_vec();
    inv.process(&mut spec, &mut band).expect("fft sizes match");
    // energy envelope, Hann-windowed, mean removed
    let w = |i: usize| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
    let e: Vec<f64> = band.iter().map(|b| b * b).collect();
    let emean = e.iter().sum::<f64>() / n as f64;
    for (i, (d, v)) in input.iter_mut().zip(&e).enumerate() {
        *d = (v - emean) * w(i);
    }
    fft.process(&mut input, &mut spec).expect("fft sizes match");
    let amp: Vec<f64> = spec.iter().map(|c| c.norm()).collect();
    // the largest bin within +-0.5 Hz of each grid frequency
    let at = |hz: f64| -> f64 {
        let lo = (((hz - 0.5) / df).ceil().max(0.0)) as usize;
        let hi = (((hz + 0.5) / df).floor() as usize).min(amp.len() - 1);
        amp[lo.min(hi)..=hi].iter().copied().fold(0.0, f64::max)
    };
    let grid: Vec<f64> = frequencies().iter().map(|&h| at(h)).collect();
    let freqs = frequencies();
    grid.iter()
        .zip(&freqs)
        .map(|(&a, &f)| {
            let local: Vec<f64> = grid
                .iter()
                .zip(&freqs)
                .filter(|(_, g)| (**g - f).abs() <= MEDIAN_HALF_WIDTH_HZ)
                .map(|(b, _)| *b)
                .collect();
            let m = super::stats::median(&local).max(1e-300);
            (20.0 * (a / m).max(1e-6).log10() - THRESHOLD_DB).clamp(0.0, CAP_DB)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bursts of a 3 kHz tone 37 times a second stand out at 37 Hz and its harmonics;
    /// steady noise alone shows nothing that repeats.
    #[test]
    fn finds_the_rate_of_repeated_bursts() {
        let fs = 10_000.0;
        let n = 20_000;
        let mut seed = 7u64;
        let mut noise = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            ((seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) * 0.2
        };
        let x: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                let phase = (t * 37.0).fract() / 37.0; // time since the last burst
                let burst = (-phase * 600.0).exp() * (std::f64::consts::TAU * 3000.0 * t).sin();
                (burst + noise()) as f32
            })
            .collect();
        let v = measure(&x, fs, 300.0);
        let f = frequencies();
        let at = |hz: f64| v[f.iter().position(|g| *g == hz).unwrap()];
        assert!(
            at(37.0) > 10.0 && at(74.0) > 10.0,
            "{} {}",
            at(37.0),
            at(74.0)
        );
        assert_eq!(at(50.0), 0.0);
        let quiet: Vec<f32> = (0..n).map(|_| noise() as f32).collect();
        let q = measure(&quiet, fs, 300.0);
        assert!(q.iter().filter(|d| **d > 10.0).count() <= 2, "{q:?}");
    }
}
