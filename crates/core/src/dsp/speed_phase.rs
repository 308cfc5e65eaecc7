//! The shaft's speed over the tracker's history read from the phase of its harmonics (issue
//! 34): the history is demodulated along the speed the spectrum found (each harmonic k moved
//! to 0 Hz), averaged over blocks of whole revolutions (the other harmonics cancel there),
//! Hann-weighted (a strong line elsewhere, a mains line, leaks no phase of its own into
//! the block), and the phase left in each block, unwrapped and divided by k, is the shaft angle's
//! departure from that speed. A polynomial in time fitted to it (weighted least squares, the
//! harmonics sharing the polynomial, each its own offset; the degree chosen by the Bayesian
//! information criterion) unwraps the harmonics against each other and says whether the speed
//! curves over the history (a fluctuation, not a steady speed or a linear trend). The speed at
//! every time of the history is read by a Kalman smoother from the harmonics' phases combined
//! per block
//! ([`super::phase_smoother`]: a steady speed and random walks of every freedom weighed by
//! how well each explains the phases), so the newest second's speed comes from the newest
//! blocks and the continuity of the ones before, not from the end of a polynomial, where its
//! fit is least determined; the smoother also says how probable it is that the speed wanders
//! at all (a fluctuation, not a steady speed along the reference's trend).
//!
//! The same fit says whether the newest second still shows the line: the harmonics'
//! amplitude over that second, demodulated sample by sample along the fit under one Hann
//! window, against the scatter of the blocks around the fit (the noise): a matched filter at a
//! known frequency, where the check of the newest spectrum has to search every bin for a peak,
//! and as selective as that spectrum (averaging the blocks instead let a new shaft 5 Hz off
//! a harmonic through: a block of two revolutions is 5 Hz wide at 600 rpm).

use super::harmonic_sum::{on_mains_harmonic, HARMONICS};
use super::phase_smoother;
use std::f64::consts::TAU;

/// Revolution count of a block is chosen so that it lasts about this long, s (at least two
/// revolutions: the other harmonics then fall on the Hann window's nulls): long enough for a weak 1x to keep its phase (a 1x 24x its floor in 20 s
/// reads +-0.3 rad per block), short enough to follow a fluctuation of a few tenths of a hertz.
const BLOCK_S: f64 = 0.2;
/// Fewest blocks for a fit.
const MIN_BLOCKS: usize = 8;
/// Highest degree of the phase polynomial.
const MAX_DEGREE: usize = 6;
/// Power signal-to-noise ratio per block a harmonic needs to take part (its phase then
/// scatters about 0.7 rad; a slip of a whole turn needs a 4.5 sigma excursion).
const MIN_BLOCK_SNR: f64 = 1.0;
/// ... and the harmonic the others are unwrapped against, whose phase is unwrapped block to
/// block (the difference of two blocks scatters 0.7 rad at most).
const LEAD_BLOCK_SNR: f64 = 2.0;
/// Detection statistic of the newest stretch above which it shows the line: under noise
/// alone it is a sum of K unit exponentials (K harmonics); P(> 12) < 1e-3 for K <= 5.
const NEWEST_DETECT: f64 = 12.0;
/// Highest phase degree of a speed that is steady or changes linearly (a trend, which the
/// spectrum's warp already follows).
const STRAIGHT_DEGREE: usize = 2;
/// Bayesian information criterion by which a curved speed law must beat the best straight
/// one to count as curved: "very strong" evidence on Kass and Raftery's scale (1995).
const CURVED_BIC: f64 = 10.0;

/// The speed law the phase fit found over the history.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseFit {
    /// Times (s, relative to the newest sample: <= 0) and shaft speeds (Hz) there, the
    /// smoother's: every block's centre, oldest first, and the newest sample.
    pub t: Vec<f64>,
    pub hz: Vec<f64>,
    /// Degree of the phase polynomial chosen.
    pub degree: usize,
    /// How much better (Bayesian information criterion) the chosen polynomial fits than the
    /// best steady or linearly changing one (0 when it is one of them).
    pub curved_by: f64,
    /// Harmonics that took part.
    pub harmonics: usize,
    /// Detection statistic of the line over the newest stretch ([`NEWEST_DETECT`]).
    pub newest: f64,
    /// Posterior probability that the speed wanders over the history rather than holding
    /// steady along the reference ([`phase_smoother`]).
    pub wander: f64,
    /// Shaft speeds (Hz) at `t` if it wanders: the wandering laws alone, averaged.
    pub wander_hz: Vec<f64>,
    /// Shaft speeds (Hz) at `t` if it is steady: the reference the fit was made along (the
    /// spectrum's speed along its trend).
    pub steady_hz: Vec<f64>,
}

impl PhaseFit {
    /// Shaft speed at the newest sample, Hz.
    pub fn hz_end(&self) -> f64 {
        *self.hz.last().expect("a fit has knots")
    }

    /// The newest stretch shows the line along the fit.
    pub fn newest_shows_line(&self) -> bool {
        self.newest >= NEWEST_DETECT
    }

    /// The steady and the wandering law weighed by their posterior probabilities
    /// ([`Self::wander`]), at `t`: a wander the phases barely support moves the reading little.
    pub fn weighed_hz(&self) -> Vec<f64> {
        let w = self.wander;
        self.steady_hz
            .iter()
            .zip(&self.wander_hz)
            .map(|(s, v)| (1.0 - w) * s + w * v)
            .collect()
    }

    /// The polynomial says the speed curves over the history (a fluctuation, not a steady
    /// speed or a linear trend), by very strong evidence ([`CURVED_BIC`]).
    pub fn curved(&self) -> bool {
        self.degree > STRAIGHT_DEGREE && self.curved_by >= CURVED_BIC
    }
}

/// One harmonic's blocks: demodulated mean per block (complex, as (re, im)).
struct Harmonic {
    k: usize,
    z: Vec<(f64, f64)>,
    /// Unwrapped phase per block, in shaft cycles (phase / 2 pi k).
    cyc: Vec<f64>,
    /// Inverse variance of one block's `cyc` (k^2 x its SNR per block).
    weight: f64,
}

/// Fit the phase of the harmonics of a shaft near `hz` (Hz at the newest sample, relative
/// trend `r` per second) over the samples `x` (rate `fs`, the newest last). `newest_s`: the
/// stretch checked for the line. None when no harmonic keeps its phase well enough.
pub fn fit(x: &[f32], fs: f64, hz: f64, r: f64, newest_s: f64) -> Option<PhaseFit> {
    let revs = (BLOCK_S * hz).round().max(2.0);
    let len = (revs / hz * fs).round() as usize;
    if len < 4 {
        return None;
    }
    let blocks = x.len() / len;
    if blocks < MIN_BLOCKS {
        return None;
    }
    let n = blocks * len;
    let x = &x[x.len() - n..];
    // block b's centre, t = 0 at the newest sample
    let tb: Vec<f64> = (0..blocks)
        .map(|b| -((n - 1 - b * len) as f64 - 0.5 * (len - 1) as f64) / fs)
        .collect();
    let mut hs = demodulate(x, fs, hz, r, len, -((n - 1) as f64) / fs);
    // a harmonic's block SNR from its blocks' coherence with their neighbours
    hs.retain_mut(|h| {
        let snr = neighbour_snr(&h.z);
        h.weight = (h.k * h.k) as f64 * snr;
        snr >= MIN_BLOCK_SNR
    });
    let lead = hs
        .iter()
        .enumerate()
        .filter(|(_, h)| neighbour_snr(&h.z) >= LEAD_BLOCK_SNR)
        .max_by(|a, b| a.1.weight.total_cmp(&b.1.weight))?
        .0;
    hs.swap(0, lead);
    unwrap_sequential(&mut hs[0]);
    let u: Vec<f64> = tb.iter().map(|&t| unit_time(&tb, t)).collect();
    // the lead alone, then every harmonic unwrapped to its prediction, then all together
    let (lead_fit, _, _) = best_degree(&hs[..1], &u)?;
    for h in hs.iter_mut().skip(1) {
        unwrap_to(h, &lead_fit, &u);
    }
    let (coef, degree, curved_by) = best_degree(&hs, &u)?;
    let along = Along {
        fs,
        hz,
        r,
        coef: &coef,
        tb: &tb,
    };
    let newest = newest_detection(x, &along, &hs, len, newest_s);
    let law = smoothed_law(&hs, &coef, &tb, hz)?;
    let (t, dev) = (law.t, law.dev);
    // a line that leaves the reference by a quarter turn per block is not followed: its
    // blocks' phases no longer tell the turns apart
    if dev.iter().any(|d| !(d.abs() * len as f64 / fs < 0.25)) {
        return None;
    }
    let absolute = |dev: &[f64]| -> Vec<f64> {
        t.iter()
            .zip(dev)
            .map(|(t, d)| hz * (1.0 + r * t) + d)
            .collect()
    };
    let (f, wander_hz) = (absolute(&dev), absolute(&law.wander_dev));
    let steady_hz: Vec<f64> = t.iter().map(|t| hz * (1.0 + r * t)).collect();
    if f.iter()
        .chain(&wander_hz)
        .any(|v| !(v.is_finite() && *v > 0.0))
    {
        return None;
    }
    Some(PhaseFit {
        t,
        hz: f,
        degree,
        curved_by,
        harmonics: hs.len(),
        newest,
        wander: law.wander,
        wander_hz,
        steady_hz,
    })
}

/// The speed's departure from the reference over the history, read by the Kalman smoother
/// ([`phase_smoother`]) from the harmonics' phases combined per block (each less its offset,
/// weighted by its inverse variance), at the blocks' centres and at the newest sample (the
/// newest block's speed).
struct SmoothedLaw {
    /// Times, s (<= 0).
    t: Vec<f64>,
    /// Departures, Hz: every walk intensity averaged by its posterior weight.
    dev: Vec<f64>,
    /// Posterior probability that the speed wanders.
    wander: f64,
    /// Departures under the wandering intensities alone, Hz.
    wander_dev: Vec<f64>,
}

fn smoothed_law(hs: &[Harmonic], coef: &Coef, tb: &[f64], hz: f64) -> Option<SmoothedLaw> {
    let wsum: f64 = hs.iter().map(|h| h.weight).sum();
    let y: Vec<f64> = (0..tb.len())
        .map(|b| {
            hs.iter()
                .zip(&coef.offsets)
                .map(|(h, off)| h.weight * (h.cyc[b] - off))
                .sum::<f64>()
                / wsum
        })
        .collect();
    // a block's phase (rad) scatters 1 / (2 SNR) in variance; in shaft cycles that is
    // 1 / (2 (2 pi)^2 k^2 SNR) = 1 / (2 (2 pi)^2 weight), and the harmonics add
    let var = vec![1.0 / (2.0 * TAU * TAU * wsum); tb.len()];
    let s = phase_smoother::smooth(tb, &y, &var, hz)?;
    let newest = |mut v: Vec<f64>| {
        let last = *v.last()?;
        v.push(last);
        Some(v)
    };
    let mut t = tb.to_vec();
    t.push(0.0);
    Some(SmoothedLaw {
        t,
        dev: newest(s.hz)?,
        wander: s.wander,
        wander_dev: newest(s.wander_hz)?,
    })
}

/// Blocks of `len` samples of `x` demodulated at each harmonic of the reference shaft
/// (speed `hz` (1 + r t), t = 0 at the newest sample, `t0` the first sample's time), mains
/// harmonics within a block's bandwidth left out.
fn demodulate(x: &[f32], fs: f64, hz: f64, r: f64, len: usize, t0: f64) -> Vec<Harmonic> {
    let blocks = x.len() / len;
    let tol = fs / len as f64;
    let ks: Vec<usize> = (1..=HARMONICS)
        .filter(|&k| !on_mains_harmonic(k as f64 * hz, tol))
        .collect();
    let mut z = vec![vec![(0.0, 0.0); blocks]; ks.len()];
    let kmax = ks.last().copied().unwrap_or(0);
    let mut rot = vec![(0.0, 0.0); kmax + 1];
    let hann: Vec<f64> = (0..len)
        .map(|i| 0.5 - 0.5 * (TAU * (i as f64 + 0.5) / len as f64).cos())
        .collect();
    let norm: f64 = hann.iter().sum();
    for (j, &v) in x.iter().enumerate() {
        let t = t0 + j as f64 / fs;
        let theta = hz * (t + 0.5 * r * t * t);
        let (s, c) = (TAU * theta).sin_cos();
        // e^{-i k theta} by powers of e^{-i theta}
        rot[0] = (1.0, 0.0);
        for k in 1..=kmax {
            let (a, b) = rot[k - 1];
            rot[k] = (a * c + b * s, b * c - a * s);
        }
        let (b, v) = (j / len, v as f64 * hann[j % len]);
        for (zk, &k) in z.iter_mut().zip(&ks) {
            let (a, bb) = rot[k];
            zk[b].0 += v * a;
            zk[b].1 += v * bb;
        }
    }
    ks.into_iter()
        .zip(z)
        .map(|(k, mut z)| {
            z.iter_mut().for_each(|c| {
                c.0 /= norm;
                c.1 /= norm;
            });
            Harmonic {
                k,
                z,
                cyc: Vec::new(),
                weight: 0.0,
            }
        })
        .collect()
}

/// Power SNR per block of a line from its neighbouring blocks: for a line of power a^2 in
/// noise of power s^2 per block, E[z_b conj z_(b+1)] is a^2 (the phase moves little from a
/// block to the next) and E|z_b|^2 is a^2 + s^2.
fn neighbour_snr(z: &[(f64, f64)]) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for w in z.windows(2) {
        let (a, b) = (w[1], w[0]);
        re += a.0 * b.0 + a.1 * b.1;
        im += a.1 * b.0 - a.0 * b.1;
    }
    let cross = (re * re + im * im).sqrt() / (z.len() - 1) as f64;
    let power = z.iter().map(|c| c.0 * c.0 + c.1 * c.1).sum::<f64>() / z.len() as f64;
    let noise = power - cross;
    if noise <= 0.0 {
        return f64::INFINITY;
    }
    cross / noise
}

/// Unwrap `h`'s phases block to block (each within half a turn of the one before).
fn unwrap_sequential(h: &mut Harmonic) {
    let k = h.k as f64;
    let mut prev: Option<f64> = None;
    h.cyc =
        h.z.iter()
            .map(|c| {
                let p = c.1.atan2(c.0) / TAU;
                let v = prev.map_or(p, |q| q + (p - q + 0.5).rem_euclid(1.0) - 0.5);
                prev = Some(v);
                v / k
            })
            .collect();
}

/// Unwrap `h`'s phases to the nearest turn of the lead's fit (its own offset first).
fn unwrap_to(h: &mut Harmonic, lead: &Coef, u: &[f64]) {
    let k = h.k as f64;
    let (mut re, mut im) = (0.0, 0.0);
    let pred: Vec<f64> = u.iter().map(|&uu| k * poly(&lead.poly, uu)).collect();
    for (c, p) in h.z.iter().zip(&pred) {
        let (s, co) = (TAU * p).sin_cos();
        re += c.0 * co + c.1 * s;
        im += c.1 * co - c.0 * s;
    }
    let offset = im.atan2(re) / TAU;
    h.cyc =
        h.z.iter()
            .zip(&pred)
            .map(|(c, p)| {
                let q = p + offset;
                let ph = c.1.atan2(c.0) / TAU;
                (q + (ph - q + 0.5).rem_euclid(1.0) - 0.5) / k
            })
            .collect();
}

/// A fit: the shared polynomial (coefficients of u^1..u^d, shaft cycles) and each
/// harmonic's offset.
#[derive(Debug, Clone)]
struct Coef {
    poly: Vec<f64>,
    offsets: Vec<f64>,
}

fn poly(p: &[f64], u: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, c| (acc + c) * u)
}

/// The degree (1..=[`MAX_DEGREE`], fewer than a third of the blocks) with the smallest
/// Bayesian information criterion, its fit, and by how much it beats the best degree up to
/// [`STRAIGHT_DEGREE`] (0 when it is one of those).
fn best_degree(hs: &[Harmonic], u: &[f64]) -> Option<(Coef, usize, f64)> {
    let n = (hs.len() * u.len()) as f64;
    let top = MAX_DEGREE.min(u.len() / 3).max(1);
    let mut best: Option<(f64, Coef, usize)> = None;
    let mut straight = f64::INFINITY;
    for d in 1..=top {
        let Some((coef, rss)) = solve(hs, u, d) else {
            continue;
        };
        let wsum: f64 = hs.iter().map(|h| h.weight).sum::<f64>() * u.len() as f64;
        let bic = n * (rss / wsum).max(1e-300).ln() + (d + hs.len()) as f64 * n.ln();
        if d <= STRAIGHT_DEGREE {
            straight = straight.min(bic);
        }
        if best.as_ref().is_none_or(|(b, _, _)| bic < *b) {
            best = Some((bic, coef, d));
        }
    }
    best.map(|(b, c, d)| {
        let gain = if straight.is_finite() {
            (straight - b).max(0.0)
        } else {
            0.0
        };
        (c, d, gain)
    })
}

/// Weighted least squares of degree `d`: the coefficients and the weighted residual sum.
fn solve(hs: &[Harmonic], u: &[f64], d: usize) -> Option<(Coef, f64)> {
    let m = hs.len() + d;
    let mut a = vec![vec![0.0; m + 1]; m];
    let mut row = vec![0.0; m + 1];
    for (i, h) in hs.iter().enumerate() {
        for (&uu, &y) in u.iter().zip(&h.cyc) {
            row.fill(0.0);
            row[i] = 1.0;
            let mut p = 1.0;
            for j in 0..d {
                p *= uu;
                row[hs.len() + j] = p;
            }
            row[m] = y;
            for (ar, &xr) in a.iter_mut().zip(&row) {
                for (acc, &xc) in ar.iter_mut().zip(&row) {
                    *acc += h.weight * xr * xc;
                }
            }
        }
    }
    let sol = gauss(a)?;
    let coef = Coef {
        offsets: sol[..hs.len()].to_vec(),
        poly: sol[hs.len()..].to_vec(),
    };
    let mut rss = 0.0;
    for (h, off) in hs.iter().zip(&coef.offsets) {
        for (&uu, &y) in u.iter().zip(&h.cyc) {
            let e = y - off - poly(&coef.poly, uu);
            rss += h.weight * e * e;
        }
    }
    Some((coef, rss))
}

/// Solve the augmented system `a` (m rows, m + 1 columns) by elimination with pivoting.
fn gauss(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let m = a.len();
    for c in 0..m {
        let p = (c..m).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-12 {
            return None;
        }
        a.swap(c, p);
        let (top, rest) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in rest.iter_mut() {
            let f = row[c] / pivot[c];
            for (v, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *v -= f * p;
            }
        }
    }
    let mut x = vec![0.0; m];
    for r in (0..m).rev() {
        let s: f64 = (r + 1..m).map(|k| a[r][k] * x[k]).sum();
        x[r] = (a[r][m] - s) / a[r][r];
    }
    Some(x)
}

/// Where the fit puts a window's samples: the reference shaft (speed `hz` (1 + r t), t = 0
/// at the newest sample) and the polynomial over the blocks' centres `tb`.
struct Along<'a> {
    fs: f64,
    hz: f64,
    r: f64,
    coef: &'a Coef,
    tb: &'a [f64],
}

impl Along<'_> {
    /// The shaft angle (cycles, less a harmonic's offset) at time `t` (s, <= 0) along the fit.
    fn cycles(&self, t: f64) -> f64 {
        self.hz * (t + 0.5 * self.r * t * t) + self.departure(t)
    }

    /// The polynomial's departure from the reference (cycles) at time `t`.
    fn departure(&self, t: f64) -> f64 {
        poly(&self.coef.poly, unit_time(self.tb, t))
    }
}

/// Time `t` (s) on the polynomial's scale: -1 at the oldest block's centre `tb[0]`, +1 at the
/// newest's.
fn unit_time(tb: &[f64], t: f64) -> f64 {
    let span = (tb[tb.len() - 1] - tb[0]).max(1e-9);
    2.0 * (t - tb[0]) / span - 1.0
}

/// The line's detection statistic over the newest `s` seconds of `x` (the newest sample
/// last): per harmonic, the power of those samples demodulated along the fit and averaged
/// under one Hann window (a matched filter as selective as a spectrum of that stretch: a line
/// a few hertz off, which a block of two revolutions would pass, falls on its sidelobes)
/// against the blocks' scatter around the fit over the whole history scaled to that length
/// (about 1 under noise alone), summed over the harmonics.
fn newest_detection(x: &[f32], along: &Along, hs: &[Harmonic], len: usize, s: f64) -> f64 {
    let n = x.len();
    let m = ((s * along.fs).round() as usize).clamp(len, n);
    let hann: Vec<f64> = (0..m)
        .map(|i| 0.5 - 0.5 * (TAU * (i as f64 + 0.5) / m as f64).cos())
        .collect();
    let norm: f64 = hann.iter().sum();
    let mut total = 0.0;
    for (h, off) in hs.iter().zip(&along.coef.offsets) {
        let k = h.k as f64;
        // the blocks rotated back along the fit: a line leaves a constant there, the noise
        // its scatter
        let rotated: Vec<(f64, f64)> =
            h.z.iter()
                .zip(along.tb)
                .map(|(c, &t)| {
                    let (sn, cs) = (TAU * k * (off + along.departure(t))).sin_cos();
                    (c.0 * cs + c.1 * sn, c.1 * cs - c.0 * sn)
                })
                .collect();
        let all = rotated.len() as f64;
        let mean = rotated
            .iter()
            .fold((0.0, 0.0), |a, c| (a.0 + c.0, a.1 + c.1));
        let mean = (mean.0 / all, mean.1 / all);
        let scatter = rotated
            .iter()
            .map(|c| (c.0 - mean.0).powi(2) + (c.1 - mean.1).powi(2))
            .sum::<f64>()
            / (all - 1.0);
        // the newest stretch demodulated sample by sample along the fit
        let (mut re, mut im) = (0.0, 0.0);
        for (j, (&v, w)) in x[n - m..].iter().zip(&hann).enumerate() {
            let t = -((m - 1 - j) as f64) / along.fs;
            let (sn, cs) = (TAU * k * (along.cycles(t) + off)).sin_cos();
            re += v as f64 * w * cs;
            im -= v as f64 * w * sn;
        }
        let (re, im) = (re / norm, im / norm);
        // a block's noise power over m / len blocks' worth of samples
        let noise = scatter * len as f64 / m as f64;
        if noise > 0.0 {
            total += (re * re + im * im) / noise;
        }
    }
    total
}
