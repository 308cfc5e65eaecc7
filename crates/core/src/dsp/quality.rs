//! Signal-quality flags attached to every feature window: clipping, flat (dead) sensor,
//! NaN/Inf samples, dropouts, a DC offset (advisory), repaired tacho pulses and speed out of
//! range. The checks are
//! cheap single passes over the window; the flags travel with the features so that the
//! health stage can ignore or down-weight a doubtful window.

use serde::{Deserialize, Serialize};

/// Quality flags of one window (or of a whole recording).
///
/// Per-channel problems list the channel names; counts and booleans cover the speed reference.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Quality {
    /// Channels whose peaks sit flat at their extreme value (3+ identical samples): clipped.
    pub clipped: Vec<String>,
    /// Channels with no signal at all (peak-to-peak zero): dead or disconnected sensor.
    pub flat: Vec<String>,
    /// Channels containing NaN or Inf samples.
    pub non_finite: Vec<String>,
    /// Channels with a run of identical samples longer than 10 ms inside a live signal.
    pub dropout: Vec<String>,
    /// Channels whose mean exceeds their AC RMS (a drifted IEPE bias, a DC-coupled input, a
    /// sensor losing its mount): advisory, the envelope features ignore DC.
    pub dc_offset: Vec<String>,
    /// Tacho pulses that were missing and were inserted by the speed track.
    pub missing_pulses: u32,
    /// Spurious tacho pulses that were removed by the speed track.
    pub extra_pulses: u32,
    /// Shaft speed outside what the recipe can resolve (too few revolutions per window, or the
    /// highest order above the low-pass cut-off) or outside the configured rpm range.
    pub speed_out_of_range: bool,
    /// The window reaches beyond the tacho pulses; speed there is extrapolated.
    pub speed_extrapolated: bool,
    /// The speed read from the vibration is not known well enough (no clear shaft line, a
    /// line that just jumped, too little history, or an unresolved octave): the window is
    /// not to be classified.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub speed_uncertain: bool,
    /// Half or twice the speed read from the vibration explains the spectrum nearly as well
    /// (advisory: a bearing's fault orders keep their family under doubling, so the window
    /// is still classified; the health message names the rival speed).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub speed_ambiguous: bool,
    /// Not a flag: the shaft revolutions the window held and the order resolution they give
    /// (1 / revolutions, orders): a 0.1 s capture at 1800 rpm holds 3 revolutions, so lines
    /// closer than 1/3 order blur into one (0 when the window was not order-tracked).
    #[serde(skip_serializing_if = "is_zero")]
    pub revolutions: f32,
    #[serde(skip_serializing_if = "is_zero")]
    pub order_resolution: f32,
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

impl Quality {
    /// Record the revolutions a window held and the order resolution they give.
    pub fn set_resolution(&mut self, revolutions: f64) {
        self.revolutions = revolutions as f32;
        self.order_resolution = (1.0 / revolutions) as f32;
    }

    /// True when no flag is raised.
    pub fn is_clean(&self) -> bool {
        self.flags().is_empty()
    }

    /// Raised flags as short strings, e.g. `clipped:vertical`, `missing_pulses:2`.
    pub fn flags(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (name, list) in [
            ("clipped", &self.clipped),
            ("flat", &self.flat),
            ("non_finite", &self.non_finite),
            ("dropout", &self.dropout),
            ("dc_offset", &self.dc_offset),
        ] {
            out.extend(list.iter().map(|c| format!("{name}:{c}")));
        }
        if self.missing_pulses > 0 {
            out.push(format!("missing_pulses:{}", self.missing_pulses));
        }
        if self.extra_pulses > 0 {
            out.push(format!("extra_pulses:{}", self.extra_pulses));
        }
        if self.speed_out_of_range {
            out.push("speed_out_of_range".into());
        }
        if self.speed_extrapolated {
            out.push("speed_extrapolated".into());
        }
        if self.speed_uncertain {
            out.push("speed_uncertain".into());
        }
        if self.speed_ambiguous {
            out.push("speed_ambiguous".into());
        }
        out
    }

    /// Check one channel's samples and raise its flags. `sample_rate` sets the dropout length.
    pub fn check_channel(&mut self, name: &str, samples: &[f32], sample_rate: f64) {
        let s = scan(samples, sample_rate);
        if s.non_finite.is_some() {
            self.non_finite.push(name.to_string());
            return;
        }
        if s.flat {
            self.flat.push(name.to_string());
            return;
        }
        if s.clipped {
            self.clipped.push(name.to_string());
        }
        if s.dropout {
            self.dropout.push(name.to_string());
        }
        if s.dc_offset {
            self.dc_offset.push(name.to_string());
        }
    }
}

/// Result of one pass over a channel.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ChannelScan {
    /// Index of the first NaN/Inf sample.
    pub non_finite: Option<usize>,
    pub flat: bool,
    pub clipped: bool,
    pub dropout: bool,
    /// |mean| > AC RMS (see [`Quality::dc_offset`]).
    pub dc_offset: bool,
    /// Excess kurtosis of the samples (fourth central moment over the squared variance,
    /// minus 3): 0 for Gaussian noise, -1.5 for a sine, large for sparse impacts (Dyer &
    /// Stewart's bearing-damage indicator). 0 for a flat or non-finite channel.
    pub excess_kurtosis: f32,
}

/// Minimum run of identical samples at the extreme value that counts as clipping.
const CLIP_RUN: usize = 3;
/// Share of a window's samples sitting exactly at its maximum (or minimum) that counts as
/// clipping even without a run (0.1 %: 10 samples of a 1 s window at 10 kHz).
const CLIP_SHARE: f64 = 1e-3;

/// Scan a channel once: first non-finite sample, flat, clipped, dropout.
pub fn scan(samples: &[f32], sample_rate: f64) -> ChannelScan {
    let mut out = ChannelScan::default();
    if samples.is_empty() {
        out.flat = true;
        return out;
    }
    // Pass 1: the first non-finite sample, range and mean.
    let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f64);
    for (i, &x) in samples.iter().enumerate() {
        if !x.is_finite() {
            out.non_finite = Some(i);
            return out;
        }
        lo = lo.min(x);
        hi = hi.max(x);
        sum += f64::from(x);
    }
    if hi - lo <= 0.0 {
        out.flat = true;
        return out;
    }
    let n = samples.len() as f64;
    let mean = sum / n;
    // Pass 2: variance, runs of identical samples, and the histogram at the rails. Clipped
    // impulsive vibration rarely stays at the rail for CLIP_RUN samples, but then many separate
    // samples share the exact extreme: a spike in the histogram, more samples exactly at the
    // extreme than in the 2 % of the range just inside it (a quantised or periodic signal
    // that merely repeats its maximum has its neighbours there too).
    let dropout_run = ((0.010 * sample_rate).round() as usize).max(8);
    let band = 0.02 * (hi - lo);
    let (mut at_hi, mut near_hi, mut at_lo, mut near_lo) = (0usize, 0usize, 0usize, 0usize);
    let (mut sq, mut quad) = (0.0f64, 0.0f64);
    let (mut run, mut prev) = (0usize, f32::NAN);
    for &x in samples {
        let d2 = (f64::from(x) - mean).powi(2);
        sq += d2;
        quad += d2 * d2;
        if x == hi {
            at_hi += 1;
        } else if x >= hi - band {
            near_hi += 1;
        }
        if x == lo {
            at_lo += 1;
        } else if x <= lo + band {
            near_lo += 1;
        }
        if x == prev {
            run += 1;
            if run >= CLIP_RUN && (x == hi || x == lo) {
                out.clipped = true;
            }
            if run >= dropout_run {
                out.dropout = true;
            }
        } else {
            run = 1;
            prev = x;
        }
    }
    out.dc_offset = mean.abs() > (sq / n).sqrt();
    if sq > 0.0 {
        out.excess_kurtosis = (quad * n / (sq * sq) - 3.0) as f32;
    }
    let many = ((CLIP_SHARE * n).ceil() as usize).max(CLIP_RUN + 1);
    if (at_hi >= many && at_hi >= 2 * near_hi) || (at_lo >= many && at_lo >= 2 * near_lo) {
        out.clipped = true;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(n: usize) -> Vec<f32> {
        (0..n).map(|i| (i as f32 * 0.05).sin()).collect()
    }

    #[test]
    fn excess_kurtosis_tells_impacts_from_a_sine_and_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let k = |x: &[f32]| scan(x, 10_000.0).excess_kurtosis;
        // a sine: -1.5 (exactly, over whole periods)
        let s: Vec<f32> = (0..10_000)
            .map(|i| (i as f32 * std::f32::consts::TAU / 100.0).sin())
            .collect();
        assert!((k(&s) + 1.5).abs() < 1e-3, "{}", k(&s));
        // Gaussian noise: 0 within its sampling spread sqrt(24 / n) = 0.049
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = Normal::new(0.0f32, 1.0).unwrap();
        let g: Vec<f32> = (0..10_000).map(|_| normal.sample(&mut rng)).collect();
        assert!(k(&g).abs() < 0.2, "{}", k(&g));
        // the same noise with a unit impact every 1000 samples, ten times its RMS
        let mut hit = g.clone();
        for i in (0..10_000).step_by(1000) {
            hit[i] += 10.0;
        }
        assert!(k(&hit) > 5.0, "{}", k(&hit));
    }

    #[test]
    fn clean_sine_raises_nothing() {
        let mut q = Quality::default();
        q.check_channel("v", &sine(10_000), 10_000.0);
        assert!(q.is_clean(), "{:?}", q.flags());
    }

    #[test]
    fn short_clipped_peaks_without_a_run_are_flagged() {
        // Impacts ringing at 2.5 kHz sampled at 10 kHz: each excursion past the rail lasts
        // one or two samples, so only the count of samples at the rail shows the clipping.
        let ring: Vec<f32> = (0..10_000)
            .map(|i| {
                let t = (i % 1000) as f32 / 10_000.0;
                (-t * 300.0).exp() * (2.0 * std::f32::consts::PI * 2500.0 * t + 0.3).sin()
                    + 0.001 * ((i * 7919) % 13) as f32
            })
            .collect();
        assert!(!scan(&ring, 10_000.0).clipped, "unclipped ringing");
        // A periodic, coarsely quantised signal repeats its maximum without being clipped.
        let steps: Vec<f32> = (0..10_000)
            .map(|i| ((i * 7919) % 1000) as f32 / 500.0 - 1.0)
            .collect();
        assert!(!scan(&steps, 10_000.0).clipped, "repeated maximum");
        let peak = ring.iter().fold(0f32, |m, x| m.max(x.abs()));
        let c = 0.5 * peak;
        let clipped: Vec<f32> = ring.iter().map(|x| x.clamp(-c, c)).collect();
        assert!(scan(&clipped, 10_000.0).clipped);
    }

    #[test]
    fn each_fault_is_flagged() {
        let mut q = Quality::default();
        let clipped: Vec<f32> = sine(10_000).iter().map(|x| x.clamp(-0.8, 0.8)).collect();
        q.check_channel("c", &clipped, 10_000.0);
        q.check_channel("f", &[0.25; 1000], 10_000.0);
        let mut nan = sine(1000);
        nan[17] = f32::NAN;
        q.check_channel("n", &nan, 10_000.0);
        let mut drop = sine(10_000);
        drop[5000..5200].iter_mut().for_each(|x| *x = 0.0);
        q.check_channel("d", &drop, 10_000.0);
        assert_eq!(q.clipped, ["c"]);
        assert_eq!(q.flat, ["f"]);
        assert_eq!(q.non_finite, ["n"]);
        assert_eq!(q.dropout, ["d"]);
        assert_eq!(scan(&nan, 1.0).non_finite, Some(17));
        assert!(q.flags().contains(&"dropout:d".to_string()));
        assert!(q.dc_offset.is_empty(), "{:?}", q.dc_offset);
    }

    #[test]
    fn a_dc_offset_above_the_ac_rms_is_flagged_and_a_small_one_is_not() {
        let mut q = Quality::default();
        let big: Vec<f32> = sine(10_000).iter().map(|x| x + 2.0).collect();
        let small: Vec<f32> = sine(10_000).iter().map(|x| x + 0.3).collect();
        q.check_channel("big", &big, 10_000.0);
        q.check_channel("small", &small, 10_000.0);
        assert_eq!(q.dc_offset, ["big"]);
        assert!(q.flags().contains(&"dc_offset:big".to_string()));
    }
}
