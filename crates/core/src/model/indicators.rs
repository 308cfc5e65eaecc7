//! Speed-free health indicators of one window against the machine's healthy baseline (issue
//! 35): the classifier channel's **RMS**, **crest factor** (peak / RMS), **excess kurtosis**
//! and **resonance-band RMS** (the part of the signal between a quarter of the rig's low-pass
//! and the low-pass, where a defect's impacts ring the structure's resonances and the shaft's
//! own lines do not reach). None needs a speed, so they judge a 0.1 s capture as well as a
//! streamed window.
//!
//! The baseline ([`IndicatorBaseline`], stored by `rigmon align` / `adapt` beside the
//! kurtosis baseline in the model's `alignment` JSON as `healthy_indicators`) keeps, per
//! indicator, the healthy windows' median and robust spread (1.4826 x the median absolute
//! deviation, never below a floor: 5 % for the levels, taken as logarithms; the Gaussian
//! sampling spread `sqrt(24 / N)` for the kurtosis) and the highest value the healthy windows'
//! smoothed score reached ([`super::departure`]). A window's score per indicator is its
//! distance from the median in spreads ([`IndicatorBaseline::scores`]).

use realfft::{RealFftPlanner, RealToComplex};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Lowest spread of a level indicator's logarithm (5 %: a healthy machine measured twice in
/// the same hour differs by about that; a tighter spread would call a recalibrated cable a
/// departure).
pub const LEVEL_FLOOR: f32 = 0.05;
/// The resonance band starts at this fraction of the rig's low-pass frequency.
pub const RESONANCE_FROM: f64 = 0.25;

/// One window's indicators (classifier channel).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Indicators {
    /// RMS around the mean, in the channel's unit.
    pub rms: f32,
    /// Largest absolute deviation from the mean / RMS.
    pub crest: f32,
    /// Excess kurtosis (0 for Gaussian noise).
    pub kurtosis: f32,
    /// RMS in the resonance band, in the channel's unit.
    pub resonance: f32,
    /// Samples the window had.
    pub samples: usize,
}

/// A value per indicator (scores, thresholds).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PerIndicator {
    pub rms: f32,
    pub crest: f32,
    pub kurtosis: f32,
    pub resonance: f32,
}

/// One of the indicators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Indicator {
    Rms,
    Crest,
    Kurtosis,
    Resonance,
}

impl Indicator {
    /// All, in the order of [`PerIndicator::to_array`].
    pub const ALL: [Indicator; 4] = [
        Indicator::Rms,
        Indicator::Crest,
        Indicator::Kurtosis,
        Indicator::Resonance,
    ];

    /// The name used in JSON and pictures.
    pub fn as_str(self) -> &'static str {
        match self {
            Indicator::Rms => "rms",
            Indicator::Crest => "crest",
            Indicator::Kurtosis => "kurtosis",
            Indicator::Resonance => "resonance",
        }
    }
}

impl PerIndicator {
    pub fn from_array(a: [f32; 4]) -> Self {
        PerIndicator {
            rms: a[0],
            crest: a[1],
            kurtosis: a[2],
            resonance: a[3],
        }
    }

    pub fn to_array(self) -> [f32; 4] {
        [self.rms, self.crest, self.kurtosis, self.resonance]
    }
}

impl Indicators {
    /// The values the baseline works on: the levels as natural logarithms (a factor is a
    /// distance), the kurtosis as it is.
    pub fn scaled(&self) -> [f32; 4] {
        [
            self.rms.max(1e-30).ln(),
            self.crest.max(1e-30).ln(),
            self.kurtosis,
            self.resonance.max(1e-30).ln(),
        ]
    }

    pub fn is_sound(&self) -> bool {
        self.rms > 0.0 && self.scaled().iter().all(|v| v.is_finite())
    }
}

/// Measures [`Indicators`] of windows of one length (keeps its FFT plan, buffers and scratch:
/// nothing is allocated per window of the same length).
pub struct IndicatorMeter {
    sample_rate: f64,
    lowpass_hz: f64,
    fft: Option<Arc<dyn RealToComplex<f32>>>,
    input: Vec<f32>,
    spectrum: Vec<realfft::num_complex::Complex<f32>>,
    scratch: Vec<realfft::num_complex::Complex<f32>>,
    planner: RealFftPlanner<f32>,
}

impl IndicatorMeter {
    /// For windows sampled at `sample_rate`, the resonance band up to `lowpass_hz`.
    pub fn new(sample_rate: f64, lowpass_hz: f64) -> Self {
        IndicatorMeter {
            sample_rate,
            lowpass_hz,
            fft: None,
            input: Vec::new(),
            spectrum: Vec::new(),
            scratch: Vec::new(),
            planner: RealFftPlanner::new(),
        }
    }

    /// The indicators of one window (None: fewer than 16 samples, a flat or non-finite one).
    pub fn measure(&mut self, x: &[f32]) -> Option<Indicators> {
        let n = x.len();
        if n < 16 || x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mean = x.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64;
        let (mut m2, mut m4, mut peak) = (0.0f64, 0.0f64, 0.0f64);
        for &v in x {
            let d = f64::from(v) - mean;
            m2 += d * d;
            m4 += d * d * d * d;
            peak = peak.max(d.abs());
        }
        m2 /= n as f64;
        m4 /= n as f64;
        if m2 <= 0.0 {
            return None;
        }
        let rms = m2.sqrt();
        let share = self.band_share(x, mean)?;
        let i = Indicators {
            rms: rms as f32,
            crest: (peak / rms) as f32,
            kurtosis: (m4 / (m2 * m2) - 3.0) as f32,
            resonance: (rms * share.sqrt()) as f32,
            samples: n,
        };
        i.is_sound().then_some(i)
    }

    /// The share of the window's energy (around the mean) in the resonance band.
    fn band_share(&mut self, x: &[f32], mean: f64) -> Option<f64> {
        let n = x.len();
        if self.input.len() != n || self.fft.is_none() {
            let fft = self.planner.plan_fft_forward(n);
            self.spectrum = fft.make_output_vec();
            self.scratch = fft.make_scratch_vec();
            self.input = vec![0.0; n];
            self.fft = Some(fft);
        }
        for (o, &v) in self.input.iter_mut().zip(x) {
            *o = (f64::from(v) - mean) as f32;
        }
        let fft = self.fft.as_ref()?;
        fft.process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch)
            .ok()?;
        let df = self.sample_rate / n as f64;
        let top = self.lowpass_hz.min(self.sample_rate / 2.0);
        let (lo, hi) = (RESONANCE_FROM * top, top);
        let (mut band, mut all) = (0.0f64, 0.0f64);
        for (k, c) in self.spectrum.iter().enumerate().skip(1) {
            let p = f64::from(c.norm_sqr());
            all += p;
            let f = k as f64 * df;
            if f >= lo && f <= hi {
                band += p;
            }
        }
        (all > 0.0).then_some(band / all)
    }
}

/// One indicator's healthy statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Level {
    /// Median of the healthy windows (scaled: [`Indicators::scaled`]).
    pub center: f32,
    /// Robust spread (module doc), never below the floor.
    pub spread: f32,
    /// The highest smoothed score the healthy windows reached ([`super::departure`]).
    pub healthy_max: f32,
}

/// The machine's healthy indicator statistics (stored as `healthy_indicators`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IndicatorBaseline {
    pub rms: Level,
    pub crest: Level,
    pub kurtosis: Level,
    pub resonance: Level,
    /// Healthy windows it was fitted on.
    pub windows: usize,
    /// Windows in the running median the scores are smoothed by ([`super::departure`]).
    pub median_of: usize,
}

impl IndicatorBaseline {
    /// The levels (median, spread) of the healthy windows' indicators, for scores smoothed
    /// over `median_of` windows (None: fewer sound windows than that, too few to smooth once);
    /// each `healthy_max` is left 0: [`super::departure::fit_baseline`] fits the whole.
    pub fn fit(healthy: &[Indicators], median_of: usize) -> Option<Self> {
        let median_of = median_of.max(1);
        let sound: Vec<&Indicators> = healthy.iter().filter(|i| i.is_sound()).collect();
        if sound.len() < median_of.max(2) {
            return None;
        }
        let samples = sound.iter().map(|i| i.samples).min().unwrap_or(0);
        let kurtosis_floor = (24.0 / samples.max(1) as f64).sqrt() as f32;
        let floors = [LEVEL_FLOOR, LEVEL_FLOOR, kurtosis_floor, LEVEL_FLOOR];
        let mut levels = [Level {
            center: 0.0,
            spread: 1.0,
            healthy_max: 0.0,
        }; 4];
        for (j, level) in levels.iter_mut().enumerate() {
            let mut v: Vec<f32> = sound.iter().map(|i| i.scaled()[j]).collect();
            let center = median(&mut v);
            let mut dev: Vec<f32> = v.iter().map(|x| (x - center).abs()).collect();
            level.center = center;
            level.spread = (1.4826 * median(&mut dev)).max(floors[j]);
        }
        Some(IndicatorBaseline {
            rms: levels[0],
            crest: levels[1],
            kurtosis: levels[2],
            resonance: levels[3],
            windows: sound.len(),
            median_of,
        })
    }

    /// The four levels in [`NAMES`] order.
    pub fn levels(&self) -> [Level; 4] {
        [self.rms, self.crest, self.kurtosis, self.resonance]
    }

    /// One window's scores: its distance from the healthy median in spreads, per indicator.
    pub fn scores(&self, i: &Indicators) -> PerIndicator {
        let s = i.scaled();
        let l = self.levels();
        PerIndicator::from_array(std::array::from_fn(|j| (s[j] - l[j].center) / l[j].spread))
    }
}

/// Median (sorts `v`; NaN-free input; 0 for none).
pub fn median(v: &mut [f32]) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f32::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noise(n: usize, sd: f32, seed: u64) -> Vec<f32> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let d = Normal::new(0.0f32, sd).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    #[test]
    fn a_sine_and_noise_have_their_textbook_indicators() {
        let fs = 25_600.0;
        let mut m = IndicatorMeter::new(fs, 10_000.0);
        // a 100 Hz sine: RMS a / sqrt 2, crest sqrt 2, excess kurtosis -1.5, nothing in the band
        let x: Vec<f32> = (0..2560)
            .map(|i| 2.0 * (2.0 * std::f32::consts::PI * 100.0 * i as f32 / fs as f32).sin())
            .collect();
        let i = m.measure(&x).unwrap();
        assert!((i.rms - 2.0f32.sqrt()).abs() < 1e-3, "{i:?}");
        assert!((i.crest - 2.0f32.sqrt()).abs() < 1e-2, "{i:?}");
        assert!((i.kurtosis + 1.5).abs() < 1e-2, "{i:?}");
        assert!(i.resonance < 0.02 * i.rms, "{i:?}");
        // white noise: the band 2.5-10 kHz holds 7.5 / 12.8 of the energy
        let i = m.measure(&noise(2560, 1.0, 3)).unwrap();
        let share = (i.resonance / i.rms).powi(2);
        assert!((share - 7.5 / 12.8).abs() < 0.05, "{share}");
        assert!(i.kurtosis.abs() < 0.4, "{i:?}");
        assert!(m.measure(&[1.0; 64]).is_none());
        assert!(m.measure(&[f32::NAN; 64]).is_none());
    }

    #[test]
    fn the_baseline_is_robust_and_travels_in_the_alignment_json() {
        let mut m = IndicatorMeter::new(25_600.0, 10_000.0);
        let mut healthy: Vec<Indicators> = (0..60)
            .map(|s| m.measure(&noise(2560, 1.0, s)).unwrap())
            .collect();
        // one loud window among them moves neither the median nor the spread much
        healthy[10] = m.measure(&noise(2560, 20.0, 99)).unwrap();
        let b = IndicatorBaseline::fit(&healthy, 31).unwrap();
        assert!(b.rms.center.abs() < 0.02, "{b:?}");
        assert_eq!(b.rms.spread, LEVEL_FLOOR, "{b:?}");
        assert!(
            (b.kurtosis.spread - (24.0f32 / 2560.0).sqrt()).abs() < 0.05,
            "{b:?}"
        );
        let twice = m.measure(&noise(2560, 2.0, 7)).unwrap();
        let z = b.scores(&twice);
        assert!((z.rms - 2.0f32.ln() / LEVEL_FLOOR).abs() < 1.0, "{z:?}");
        assert!(IndicatorBaseline::fit(&healthy[..5], 31).is_none());
    }
}
