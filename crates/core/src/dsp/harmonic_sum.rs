//! The evidence for a shaft fundamental in a vibration signal: harmonic summation over a
//! whitened spectrum (log magnitude minus its running median, so a line counts by how far it
//! stands above its own neighbourhood, not by its level), with an octave guard against mains
//! lines and strong 2x/3x harmonics. Used by the whole-signal estimate ([`super::speed_estimate`])
//! and by the streaming tracker ([`super::speed_tracker`]); plans and buffers are made once.

use crate::dsp::fft_len::fast_len_at_most;
use crate::dsp::sliding_median::SlidingMedian;
use realfft::RealFftPlanner;
use rustfft::num_complex::Complex32;

/// Harmonics summed per candidate fundamental.
pub const HARMONICS: usize = 5;
/// Width of the running median that defines the spectral background, Hz.
const BACKGROUND_HZ: f64 = 8.0;
/// What a lone fundamental line gives up against a series ([`Whitened::shaft`]): the best
/// of a few hundred noise bins reads about 1.1-1.3 (a bin of Gaussian noise exceeds 1.3
/// with probability 9e-5: log-Rayleigh), so a lone noise bin scores 0.5-0.7, as the mean
/// of five harmonics of noise does (about 0.5); a real 1x line ten times its floor (2.3)
/// scores 1.7.
pub const LONE_ALLOW: f64 = 0.6;
/// Prominence from which a harmonic's own peak refines the speed ([`Whitened::line_speed`]):
/// a bin of noise exceeds 1.5 with probability 1e-6.
const REFINE_LINE: f64 = 1.5;

/// A candidate fundamental and its evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub rpm: f64,
    /// Mean prominence (natural-log units above background) of the harmonics found.
    pub score: f64,
}

/// Whitened spectrum: prominence (log magnitude minus running median) per bin up to a top
/// frequency. Harmonics that fall on a mains line are skipped when `skip_mains` is set.
#[derive(Debug, Clone, Default)]
pub struct Whitened {
    pub df: f64,
    pub prom: Vec<f64>,
    /// Leave out harmonics that sit on a 50/60 Hz mains line (the streaming tracker: a mains
    /// line must not vote for a fundamental it happens to be a multiple of).
    pub skip_mains: bool,
    /// Read the prominence between bins by linear interpolation (the streaming tracker: the
    /// harmonic sum then varies smoothly with the fundamental, so its peak can be refined
    /// below the search grid); else the nearest bin.
    pub interpolate: bool,
    /// Half-width of a line's main lobe, Hz (two bins of the signal before zero padding, Hann
    /// window): how far a line's own peak reaches.
    pub lobe: f64,
    /// Relative spread of the mains lines in this spectrum: 0 for a spectrum in time, |r| x
    /// span for a history warped along a speed trend r (a fixed line becomes a sweep).
    pub mains_spread: f64,
    /// Let a lone fundamental line count as a shaft series ([`Self::shaft`]; the streaming
    /// tracker): an accelerometer at low speed often shows the 1x line and little else, and
    /// the mean over five harmonics would divide it by five.
    pub lone: bool,
    /// Evaluate every grid point in [`Self::best_in`] (the search before issue 37 item 4,
    /// for measuring the bounded search against it; the results are the same).
    pub scan: bool,
}

/// FFT plans (cached per length by the planner) and buffers for whitened spectra.
pub struct Whitener {
    planner: RealFftPlanner<f32>,
    buf: Vec<f32>,
    spec: Vec<Complex32>,
    scratch: Vec<Complex32>,
    logm: Vec<f64>,
    median: SlidingMedian,
    /// Hann coefficients of the last few lengths (newest first).
    hann: Vec<(usize, Vec<f64>)>,
}

/// Lengths whose Hann coefficients a [`Whitener`] keeps (the tracker uses a handful).
const HANN_KEPT: usize = 8;

impl Default for Whitener {
    fn default() -> Self {
        Self::new()
    }
}

impl Whitener {
    pub fn new() -> Self {
        Whitener {
            planner: RealFftPlanner::new(),
            buf: Vec::new(),
            spec: Vec::new(),
            scratch: Vec::new(),
            logm: Vec::new(),
            median: SlidingMedian::default(),
            hann: Vec::new(),
        }
    }

    /// The Hann window of length `n` (`0.5 - 0.5 cos(2 pi i / n)`), computed once per length.
    fn hann(&mut self, n: usize) -> &[f64] {
        match self.hann.iter().position(|(m, _)| *m == n) {
            Some(0) => {}
            Some(i) => {
                let kept = self.hann.remove(i);
                self.hann.insert(0, kept);
            }
            None => {
                let w = (0..n)
                    .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
                    .collect();
                self.hann.truncate(HANN_KEPT - 1);
                self.hann.insert(0, (n, w));
            }
        }
        &self.hann[0].1
    }

    /// Whitened spectrum of `x` (cut to the largest fast FFT length, Hann window, zero-padded
    /// `pad` times) up to `f_top` Hz, written into `out` (its buffers are reused). The
    /// background median is taken at every `stride`-th bin and held in between (1: every bin).
    pub fn whiten_into(
        &mut self,
        x: &[f32],
        fs: f64,
        (pad, stride): (usize, usize),
        f_top: f64,
        out: &mut Whitened,
    ) {
        let n = fast_len_at_most(x.len());
        let x = &x[..n];
        let mean = x.iter().map(|&v| v as f64).sum::<f64>() / n as f64;
        let len = n * pad;
        let fft = self.planner.plan_fft_forward(len);
        let mut buf = std::mem::take(&mut self.buf);
        buf.clear();
        buf.resize(len, 0.0);
        for ((b, &v), &w) in buf.iter_mut().zip(x).zip(self.hann(n)) {
            *b = ((v as f64 - mean) * w) as f32;
        }
        self.buf = buf;
        self.spec.clear();
        self.spec.resize(len / 2 + 1, Complex32::default());
        self.scratch.clear();
        self.scratch
            .resize(fft.get_scratch_len(), Complex32::default());
        fft.process_with_scratch(&mut self.buf, &mut self.spec, &mut self.scratch)
            .expect("buffer sizes match the plan");
        let df = fs / len as f64;
        let top = ((f_top / df).ceil() as usize).min(self.spec.len() - 1);
        let half = ((BACKGROUND_HZ / df / 2.0).round() as usize).max(2);
        self.logm.clear();
        self.logm.extend(
            self.spec[..(top + half + 1).min(self.spec.len())]
                .iter()
                .map(|c| (c.norm() as f64 + 1e-30).ln()),
        );
        let (logm, median) = (&self.logm, &mut self.median);
        median.reset();
        let stride = stride.max(1);
        let mut med = 0.0;
        out.df = df;
        out.lobe = 2.0 * fs / n as f64;
        out.mains_spread = 0.0;
        out.prom.clear();
        out.prom.extend((0..=top).map(|i| {
            if i % stride == 0 {
                let c = (i + stride / 2).min(top);
                let (a, b) = (c.saturating_sub(half), (c + half + 1).min(logm.len()));
                med = median.median(logm, a, b);
            }
            logm[i] - med
        }));
    }

    /// As [`whiten_into`](Self::whiten_into), into a new spectrum (mains harmonics counted).
    pub fn whiten(&mut self, x: &[f32], fs: f64, pad: usize, f_top: f64) -> Whitened {
        let mut w = Whitened::default();
        self.whiten_into(x, fs, (pad, 1), f_top, &mut w);
        w
    }
}

/// True within 0.3 % of 50 or 60 Hz: the mains series. An induction motor never turns at
/// exactly synchronous speed (slip), so these candidates are skipped.
pub fn is_mains(f: f64) -> bool {
    [50.0, 60.0].iter().any(|m| (f / m - 1.0).abs() < 0.003)
}

/// True when `f` sits on a harmonic of 50 or 60 Hz, within `tol` Hz (or 0.3 %).
pub(crate) fn on_mains_harmonic(f: f64, tol: f64) -> bool {
    [50.0, 60.0].iter().any(|&m: &f64| {
        let k = (f / m).round();
        k >= 1.0 && (f - k * m).abs() <= tol.max(0.003 * k * m)
    })
}

impl Whitened {
    /// Prominence at `f` (the nearest bin, or interpolated; -inf beyond the spectrum).
    pub fn at(&self, f: f64) -> f64 {
        if self.interpolate {
            let x = f / self.df;
            // the cast truncates: floor for x >= 0, and 0 below as floor's cast gives (a
            // call to floor is a libm call on the baseline x86-64 target: 1/10 of the search)
            let i = x as usize;
            return match (self.prom.get(i), self.prom.get(i + 1)) {
                (Some(&a), Some(&b)) => {
                    let w = x - i as f64;
                    a + w * (b - a)
                }
                _ => f64::NEG_INFINITY,
            };
        }
        let i = (f / self.df).round() as usize;
        self.prom.get(i).copied().unwrap_or(f64::NEG_INFINITY)
    }

    /// `f` lies on a mains harmonic's line in this spectrum: within its main lobe (a strong
    /// mains line lifts the bins beside it well above the background, and a fundamental whose
    /// harmonic sits there would read it as its own: 50 Hz hum alone read 1484-1511 rpm) and,
    /// in a warped spectrum, within its sweep. The tracker's check of the newest signal uses
    /// it; the harmonic sum itself leaves out 1.5 bins around each mains harmonic.
    pub fn on_mains(&self, f: f64) -> bool {
        on_mains_harmonic(f, (1.5 * self.df).max(self.lobe) + self.mains_spread * f)
    }

    /// Mean prominence of harmonics `ks` of `f0` (mains lines left out when `skip_mains`).
    pub fn score(&self, f0: f64, ks: impl Iterator<Item = usize>) -> f64 {
        let (mut s, mut n) = (0.0, 0);
        let tol = 1.5 * self.df;
        for k in ks {
            let f = k as f64 * f0;
            if self.skip_mains && on_mains_harmonic(f, tol) {
                continue;
            }
            s += self.at(f);
            n += 1;
        }
        if n == 0 {
            return f64::NEG_INFINITY;
        }
        s / n as f64
    }

    /// Mean prominence of harmonics 1..=[`HARMONICS`].
    pub fn full(&self, f0: f64) -> f64 {
        self.score(f0, 1..=HARMONICS)
    }

    /// The evidence for a shaft at `f0`: its series ([`Self::full`]), or, with `lone` set,
    /// its fundamental line alone less [`LONE_ALLOW`] when that is more (off the mains lines).
    pub fn shaft(&self, f0: f64) -> f64 {
        let full = self.full(f0);
        if !self.lone || self.on_mains(f0) {
            return full;
        }
        full.max(self.at(f0) - LONE_ALLOW)
    }

    /// The speed near `hz` read from its harmonics' own peaks ([`Self::peak_near`], within
    /// half a main lobe or 0.5 % of where each belongs), each harmonic that stands
    /// [`REFINE_LINE`] above its floor off the mains lines weighted by k^2 times its power
    /// above the floor (the variance of a line's frequency falls with its SNR, and harmonic k
    /// divides its error by k). A grid maximum of the harmonic sum is pulled within the 1x
    /// line's lobe by the noise at the absent harmonics (a clean 1x at 1188 rpm read 0.76 %
    /// high); the peaks themselves are not. None when no harmonic stands out.
    pub fn line_speed(&self, hz: f64) -> Option<f64> {
        let (mut num, mut den) = (0.0, 0.0);
        for k in 1..=HARMONICS {
            let f = k as f64 * hz;
            if self.on_mains(f) {
                continue;
            }
            let Some((peak, p)) = self.peak_near(f, (0.5 * self.lobe).max(0.005 * f)) else {
                continue;
            };
            if p < REFINE_LINE {
                continue;
            }
            let w = (k * k) as f64 * ((2.0 * p).exp() - 1.0);
            num += w * peak / k as f64;
            den += w;
        }
        (den > 0.0).then(|| num / den)
    }

    /// The local maximum of the spectrum within `half` Hz of `f`, interpolated between bins
    /// (a parabola through the log magnitudes of the three bins around it: a Gaussian fit,
    /// nearly exact for a Hann main lobe): (Hz, prominence). None when the highest bin of the
    /// span sits at its edge (a slope, not a line).
    pub fn peak_near(&self, f: f64, half: f64) -> Option<(f64, f64)> {
        let lo = ((f - half) / self.df).floor().max(1.0) as usize;
        let hi = ((f + half) / self.df).ceil() as usize;
        if hi + 1 >= self.prom.len() || lo >= hi {
            return None;
        }
        let i = (lo..=hi).max_by(|&a, &b| self.prom[a].total_cmp(&self.prom[b]))?;
        if i == lo || i == hi {
            return None;
        }
        let (a, b, c) = (self.prom[i - 1], self.prom[i], self.prom[i + 1]);
        let den = a - 2.0 * b + c;
        let d = if den < 0.0 {
            (0.5 * (a - c) / den).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        Some(((i as f64 + d) * self.df, b - 0.25 * (a - c) * d))
    }

    /// Best fundamental in [lo, hi] on a grid fine enough that every harmonic lands within a
    /// quarter bin of its line, every grid point evaluated (the first of equal maxima).
    /// [`Self::best_in`] returns the same without evaluating every point
    /// ([`super::harmonic_bound`]).
    pub fn best_in_scan(&self, lo: f64, hi: f64) -> (f64, f64) {
        let step = self.df / (2 * HARMONICS) as f64;
        let mut best = (lo, f64::NEG_INFINITY);
        let mut f = lo;
        while f <= hi {
            let s = self.shaft(f);
            if s > best.1 && !is_mains(f) {
                best = (f, s);
            }
            f += step;
        }
        best
    }

    /// Best score of the harmonics of `f0` that are not multiples of `m` (the lines a true
    /// fundamental `f0` adds to the series of `m * f0`), searched within +-0.5 % of `f0`.
    pub fn odd_support(&self, f0: f64, m: usize) -> (f64, f64) {
        let (mut cb, mut cs) = (f0, f64::NEG_INFINITY);
        let step = self.df / (2 * HARMONICS) as f64;
        let mut f = f0 * 0.995;
        while f <= f0 * 1.005 {
            let s = self.score(f, (1..=HARMONICS).filter(|k| k % m != 0));
            if s > cs {
                (cb, cs) = (f, s);
            }
            f += step;
        }
        (cb, cs)
    }
}

/// The strongest harmonic series in [fmin, fmax] Hz, with the octave guard: prefer best/m
/// when the harmonics best/m adds (not multiples of m) are clearly present too (mains at 60 Hz
/// next to a 2x line at 59.9 Hz is the classic trap).
pub fn fundamental(w: &Whitened, fmin: f64, fmax: f64) -> Estimate {
    let (mut best, mut score) = w.best_in(fmin, fmax);
    'outer: loop {
        for m in [2usize, 3] {
            let c = best / m as f64;
            if c < fmin {
                continue;
            }
            let (cb, cs) = w.odd_support(c, m);
            if cs >= 0.5 * score.min(w.full(best)) && cs > 1.0 {
                best = cb;
                score = w.shaft(cb);
                continue 'outer;
            }
        }
        break;
    }
    Estimate {
        rpm: best * 60.0,
        score,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mains_harmonics_are_recognised() {
        assert!(on_mains_harmonic(100.02, 0.05));
        assert!(on_mains_harmonic(180.3, 0.05));
        assert!(!on_mains_harmonic(70.0, 0.05));
        assert!(!on_mains_harmonic(54.0, 0.05));
    }

    #[test]
    fn a_mains_line_does_not_vote_when_skipped() {
        // background 0, one strong line at 50 Hz only
        let df = 0.1;
        let mut w = Whitened {
            df,
            prom: vec![0.0; 2000],
            skip_mains: false,
            interpolate: false,
            ..Whitened::default()
        };
        w.prom[500] = 10.0;
        assert!(w.full(10.0) > 1.9, "50 Hz is the 5th harmonic of 10 Hz");
        w.skip_mains = true;
        assert!(w.full(10.0).abs() < 1e-12);
    }
}
