//! Band selection for the envelope by spectral kurtosis: the fast kurtogram of J. Antoni,
//! "Fast computation of the kurtogram for the detection of transient faults", MSSP 21 (2007)
//! 108-124. Impacts of a local bearing fault ring a structural resonance; in the band of that
//! resonance the signal is impulsive (high kurtosis) even when gear mesh, shaft harmonics and
//! noise dominate the full-band signal. The kurtogram measures the kurtosis of the complex
//! envelope in every band of a dyadic grid and returns the band where it is highest.
//!
//! The 1/3-binary tree, as in Antoni's paper: level k splits 0..top into 2^k bands of width
//! top / 2^k, and between two binary levels a "1/3 level" k + log2(3) - 1 (printed k.6) splits
//! every band of level k - 1 into three, so a resonance on a binary band edge is still found
//! in one band. Each split is a short quasi-analytic FIR filter followed by decimation: two
//! 17-tap filters (Hamming-windowed low-pass cut at 0.4 x Nyquist, shifted to 1/8 and 3/8 of
//! the node's rate) and decimation by 2 for the binary levels, three 25-tap filters (cut at
//! 2/3 of that, centred at 1/12, 3/12 and 5/12) and decimation by 3 for the 1/3 levels. The
//! upper band of a binary split is shifted back by half its rate ((-1)^n) so every node holds
//! its band at 0..rate/2, in frequency order. The cost is about 42 complex multiply-adds per
//! input sample and level (O(N log N) over the whole tree).
//!
//! Kurtosis of a node's complex envelope c (its first filter-length samples, the transient,
//! left out): `E|c - mean|^4 / (E|c - mean|^2)^2 - 2`, which is 0 for circular complex Gaussian
//! noise, -1 for a pure tone and large for sparse impacts.
//!
//! Two departures from Antoni's reference code, both so that Gaussian noise reads 0 in every
//! band: the window is made analytic first (one real FFT of the window followed by its mirror
//! image, so its ends meet without a jump; negative frequencies dropped; one inverse complex
//! FFT), so the tree runs on a circular complex signal (his runs on the real signal,
//! whose lowest and highest bands hold both a frequency and its mirror and read above 0 on
//! pure noise, and whose level 0 is a real-signal kurtosis, minus 3); and the upper binary
//! filter is the lower one shifted to 3/8 rather than its time reverse (the same magnitude
//! response). Kurtoses are kept as computed (negative values too); plots clamp at 0.
//!
//! With [`KurtogramSettings::max_hz`] the band-limiting FFT also decimates: only 0..max_hz is
//! kept and the tree runs at 2 x max_hz, so a 48 kHz and a 12 kHz recording are searched on
//! the same grid of bands (CWRU's healthy 97 beside its 12 kHz fault records).
//!
//! [`Kurtogram::new`] plans the FFTs and allocates every buffer once for a fixed window
//! length; [`Kurtogram::compute`] allocates nothing, so it can run on every window.

use crate::dsp::fft_len::fast_len_at_most;
use anyhow::{bail, Result};
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
use serde::Serialize;
use std::sync::Arc;

type C64 = Complex<f64>;

/// Taps of the binary (halving) filters and of the 1/3 (thirding) filters.
const TAPS2: usize = 17;
const TAPS3: usize = 25;
/// Cut-off of the binary prototype low-pass, fraction of Nyquist (Antoni: "a short filter is
/// just good enough").
const FC: f64 = 0.4;
/// A band holding less than this fraction of the window's power is numerically empty (its
/// kurtosis would be that of rounding noise): it reads 0.
const EMPTY_BAND: f64 = 1e-12;
/// Antoni's depth limit: a window of N samples takes at most log2(N) - 7 levels, so the
/// deepest node keeps at least 128 samples for its kurtosis.
const MIN_NODE_LOG2: usize = 7;

/// How deep the tree goes and which frequencies it searches.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KurtogramSettings {
    /// Deepest binary level: the narrowest bands are top / 2^levels wide.
    pub levels: usize,
    /// Highest frequency searched, Hz; `None`: the Nyquist frequency. Lower, the window is
    /// band-limited and decimated to 2 x max_hz before the tree.
    pub max_hz: Option<f64>,
}

impl Default for KurtogramSettings {
    fn default() -> Self {
        KurtogramSettings {
            levels: 6,
            max_hz: None,
        }
    }
}

/// One row of the kurtogram: the bands of one level, side by side from 0 Hz.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KurtogramRow {
    /// Level: k for the binary levels, k + log2(3) - 1 for the 1/3 levels.
    pub level: f64,
    /// Width of every band of the row, Hz; band i spans [i, i + 1] x bandwidth.
    pub bandwidth_hz: f64,
    /// Kurtosis of the complex envelope per band.
    pub kurtosis: Vec<f64>,
}

impl KurtogramRow {
    /// The level as Antoni prints it: 0, 1, 1.6, 2, 2.6, ...
    pub fn label(&self) -> String {
        level_label(self.level)
    }

    /// Band `i` of the row.
    pub fn band(&self, i: usize) -> KurtogramBand {
        KurtogramBand {
            level: self.level,
            index: i,
            lo_hz: i as f64 * self.bandwidth_hz,
            hi_hz: (i + 1) as f64 * self.bandwidth_hz,
            kurtosis: self.kurtosis[i],
        }
    }
}

/// The level as printed: one decimal (1.585 -> 1.6).
pub fn level_label(level: f64) -> String {
    if (level - level.round()).abs() < 1e-9 {
        format!("{}", level.round() as i64)
    } else {
        format!("{level:.1}")
    }
}

/// One band of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KurtogramBand {
    pub level: f64,
    /// Position in its row (0 = lowest frequency).
    pub index: usize,
    pub lo_hz: f64,
    pub hi_hz: f64,
    pub kurtosis: f64,
}

impl KurtogramBand {
    pub fn centre_hz(&self) -> f64 {
        0.5 * (self.lo_hz + self.hi_hz)
    }

    pub fn bandwidth_hz(&self) -> f64 {
        self.hi_hz - self.lo_hz
    }

    pub fn contains(&self, hz: f64) -> bool {
        self.lo_hz <= hz && hz <= self.hi_hz
    }
}

/// The fast kurtogram for windows of exactly `len` samples at one sample rate.
pub struct Kurtogram {
    len: usize,
    sample_rate: f64,
    settings: KurtogramSettings,
    /// Positive-frequency bins kept from the FFT of the mirrored window (1..=keep; DC
    /// dropped).
    keep: usize,
    /// Rate of the analytic signal the tree runs on (the window's rate, or 2 x max_hz).
    rate: f64,
    r2c: Arc<dyn RealToComplex<f64>>,
    ifft: Arc<dyn Fft<f64>>,
    input: Vec<f64>,
    spec: Vec<C64>,
    scratch_r: Vec<C64>,
    scratch_c: Vec<C64>,
    /// Analytic signal of the mirrored window (its first half is level 0).
    mirrored: Vec<C64>,
    /// Binary level k: its 2^k nodes of `node_len[k]` samples each, one after the other.
    nodes: Vec<Vec<C64>>,
    node_len: Vec<usize>,
    /// One band of a 1/3 split.
    third: Vec<C64>,
    low: Vec<C64>,
    high: Vec<C64>,
    thirds: [Vec<C64>; 3],
    rows: Vec<KurtogramRow>,
}

impl Kurtogram {
    /// Plan the kurtogram of `len`-sample windows at `sample_rate`. Errors say which setting
    /// does not fit the window.
    pub fn new(len: usize, sample_rate: f64, settings: KurtogramSettings) -> Result<Self> {
        if !(sample_rate.is_finite() && sample_rate > 0.0) {
            bail!("kurtogram: sample rate {sample_rate} Hz must be a positive number");
        }
        let nyquist = sample_rate / 2.0;
        if len < 2 {
            bail!("kurtogram: a window of {len} samples is too short");
        }
        // the window and its mirror image: 2 len samples, bins fs / (2 len) apart
        let keep = match settings.max_hz {
            Some(f) if !(f.is_finite() && f > 0.0) => bail!(
                "kurtogram: the highest frequency searched ({f} Hz) must be a positive number"
            ),
            Some(f) if f < nyquist => (f / sample_rate * 2.0 * len as f64).floor() as usize,
            _ => len,
        };
        // Tree length: the window itself, or the kept bins' span when band-limited (the
        // mirrored window decimated to 2 keep samples, of which the first half is the window).
        let m = keep;
        let rate = sample_rate * m as f64 / len as f64;
        let needed = 1usize << (settings.levels + MIN_NODE_LOG2);
        if m < needed {
            bail!(
                "kurtogram: {} levels need windows of at least {needed} samples at the searched rate; a {len}-sample window at {sample_rate} Hz{} gives {m} (at most {} levels): use fewer levels or longer windows",
                settings.levels,
                settings
                    .max_hz
                    .filter(|&f| f < nyquist)
                    .map(|f| format!(" searched up to {f} Hz"))
                    .unwrap_or_default(),
                (m.max(1).ilog2() as usize).saturating_sub(MIN_NODE_LOG2),
            );
        }
        let r2c = RealFftPlanner::<f64>::new().plan_fft_forward(2 * len);
        let ifft = FftPlanner::<f64>::new().plan_fft_inverse(2 * m);
        let zero = C64::new(0.0, 0.0);
        let mut node_len = vec![m];
        for k in 1..=settings.levels {
            node_len.push(node_len[k - 1] / 2);
        }
        let nodes = (0..=settings.levels)
            .map(|k| vec![zero; node_len[k] << k])
            .collect();
        let mut rows = Vec::with_capacity(2 * settings.levels + 1);
        let top = rate / 2.0;
        rows.push(KurtogramRow {
            level: 0.0,
            bandwidth_hz: top,
            kurtosis: vec![0.0],
        });
        for k in 1..=settings.levels {
            rows.push(KurtogramRow {
                level: k as f64,
                bandwidth_hz: top / (1usize << k) as f64,
                kurtosis: vec![0.0; 1 << k],
            });
            if k < settings.levels {
                // the 1/3 split of level k - 1
                rows.push(KurtogramRow {
                    level: k as f64 + 3f64.log2() - 1.0,
                    bandwidth_hz: top / (3usize << (k - 1)) as f64,
                    kurtosis: vec![0.0; 3 << (k - 1)],
                });
            }
        }
        Ok(Kurtogram {
            len,
            sample_rate,
            settings,
            keep,
            rate,
            input: vec![0.0; 2 * len],
            spec: r2c.make_output_vec(),
            scratch_r: r2c.make_scratch_vec(),
            scratch_c: vec![zero; ifft.get_inplace_scratch_len()],
            mirrored: vec![zero; 2 * m],
            r2c,
            ifft,
            nodes,
            node_len,
            third: vec![zero; m / 3],
            low: binary_filter(1.0 / 8.0),
            high: binary_filter(3.0 / 8.0),
            thirds: [
                third_filter(1.0 / 12.0),
                third_filter(3.0 / 12.0),
                third_filter(5.0 / 12.0),
            ],
            rows,
        })
    }

    /// Window length this kurtogram was planned for.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn settings(&self) -> KurtogramSettings {
        self.settings
    }

    /// Highest frequency of the grid, Hz (Nyquist, or just under `max_hz`).
    pub fn top_hz(&self) -> f64 {
        self.rate / 2.0
    }

    /// The kurtogram of `x` (exactly [`len`](Self::len) finite samples): rows in the order
    /// 0, 1, 1.6, 2, 2.6, ..., `levels`.
    pub fn compute(&mut self, x: &[f32]) -> Result<&[KurtogramRow]> {
        if x.len() != self.len {
            bail!(
                "kurtogram: the window has {} samples, the kurtogram was planned for {}",
                x.len(),
                self.len
            );
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            bail!(
                "kurtogram: sample {i} (t = {:.4} s into the window) is {}; repair or drop the input",
                i as f64 / self.sample_rate,
                x[i]
            );
        }
        self.analytic(x);
        // per-sample power below which a band is numerically empty
        let level0 = &self.nodes[0];
        let floor =
            EMPTY_BAND * level0.iter().map(|v| v.norm_sqr()).sum::<f64>() / level0.len() as f64;
        self.rows[0].kurtosis[0] = kurtosis(level0, 0, floor);
        for k in 0..self.settings.levels {
            let (n, child_n) = (self.node_len[k], self.node_len[k + 1]);
            let (parents, children) = self.nodes.split_at_mut(k + 1);
            let (parents, children) = (&parents[k], &mut children[0]);
            for i in 0..(1usize << k) {
                let c = &parents[i * n..(i + 1) * n];
                let (a, d) = children[2 * i * child_n..(2 * i + 2) * child_n].split_at_mut(child_n);
                filter_decimate(c, &self.low, 2, a);
                filter_decimate(c, &self.high, 2, d);
                // the upper band sits at -rate/2..0 after decimation: shift it up by rate/2
                d.iter_mut().skip(1).step_by(2).for_each(|v| *v = -*v);
            }
            let row = &mut self.rows[2 * k + 1];
            for (j, kurt) in row.kurtosis.iter_mut().enumerate() {
                *kurt = kurtosis(&children[j * child_n..(j + 1) * child_n], TAPS2, floor);
            }
            if k + 1 < self.settings.levels {
                let third_n = n / 3;
                let row = &mut self.rows[2 * k + 2];
                for i in 0..(1usize << k) {
                    let c = &parents[i * n..(i + 1) * n];
                    for (b, f) in self.thirds.iter().enumerate() {
                        let out = &mut self.third[..third_n];
                        filter_decimate(c, f, 3, out);
                        row.kurtosis[3 * i + b] = kurtosis(out, TAPS3, floor);
                    }
                }
            }
        }
        Ok(&self.rows)
    }

    /// The rows of the last [`compute`](Self::compute).
    pub fn rows(&self) -> &[KurtogramRow] {
        &self.rows
    }

    /// The band of highest kurtosis in the last [`compute`](Self::compute) (on a tie the
    /// wider, then the lower band).
    pub fn best(&self) -> KurtogramBand {
        best_band(&self.rows)
    }

    /// Analytic signal of the window, band-limited to the kept bins, into level 0. The FFT
    /// takes the window followed by its mirror image: that periodic signal has no jump at
    /// its ends (the window's own ends would otherwise meet in a step, whose spectrum spreads
    /// into every band as a burst at the window's edges).
    fn analytic(&mut self, x: &[f32]) {
        let n = self.len;
        for (i, &s) in x.iter().enumerate() {
            self.input[i] = s as f64;
            self.input[2 * n - 1 - i] = s as f64;
        }
        self.r2c
            .process_with_scratch(&mut self.input, &mut self.spec, &mut self.scratch_r)
            .expect("buffer sizes match the plan");
        let z = &mut self.mirrored;
        z.iter_mut().for_each(|v| *v = C64::new(0.0, 0.0));
        let scale = 1.0 / (2 * n) as f64;
        for k in 1..=self.keep {
            let f = if k == n { 1.0 } else { 2.0 };
            z[k] = self.spec[k] * (f * scale);
        }
        self.ifft.process_with_scratch(z, &mut self.scratch_c);
        let m = self.nodes[0].len();
        self.nodes[0].copy_from_slice(&z[..m]);
    }
}

/// The kurtogram of a whole recording channel, over its first `fast_len_at_most(len)` samples
/// (a length the FFTs handle fast, as for the whole-recording order spectrum).
pub fn of_recording(
    samples: &[f32],
    sample_rate: f64,
    settings: KurtogramSettings,
) -> Result<Kurtogram> {
    if samples.len() < 2 {
        bail!("kurtogram: {} samples are too few", samples.len());
    }
    let n = fast_len_at_most(samples.len());
    let mut k = Kurtogram::new(n, sample_rate, settings)?;
    k.compute(&samples[..n])?;
    Ok(k)
}

/// The band of highest kurtosis over `rows` (on a tie the earlier row, then the lower band).
pub fn best_band(rows: &[KurtogramRow]) -> KurtogramBand {
    let mut best = rows[0].band(0);
    for row in rows {
        for (i, &k) in row.kurtosis.iter().enumerate() {
            if k > best.kurtosis {
                best = row.band(i);
            }
        }
    }
    best
}

/// `fir1(taps - 1, cutoff)`: Hamming-windowed ideal low-pass, unit gain at DC.
fn hamming_lowpass(taps: usize, cutoff: f64) -> Vec<f64> {
    let mid = (taps - 1) as f64 / 2.0;
    let sinc = |x: f64| {
        if x.abs() < 1e-12 {
            1.0
        } else {
            (std::f64::consts::PI * x).sin() / (std::f64::consts::PI * x)
        }
    };
    let mut h: Vec<f64> = (0..taps)
        .map(|n| {
            let w = 0.54 - 0.46 * (2.0 * std::f64::consts::PI * n as f64 / (taps - 1) as f64).cos();
            w * cutoff * sinc(cutoff * (n as f64 - mid))
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= sum);
    h
}

/// The prototype `p` shifted to `centre` (fraction of the sample rate).
fn modulate(p: &[f64], centre: f64) -> Vec<C64> {
    p.iter()
        .enumerate()
        .map(|(n, &v)| C64::from_polar(v, 2.0 * std::f64::consts::PI * centre * n as f64))
        .collect()
}

fn binary_filter(centre: f64) -> Vec<C64> {
    modulate(&hamming_lowpass(TAPS2, FC), centre)
}

fn third_filter(centre: f64) -> Vec<C64> {
    modulate(&hamming_lowpass(TAPS3, 2.0 / 3.0 * FC), centre)
}

/// `out[j] = sum_t f[t] x[D j + D - 1 - t]` (samples before the window are 0): the filter's
/// output at every D-th sample, the last of each group of D.
fn filter_decimate(x: &[C64], f: &[C64], d: usize, out: &mut [C64]) {
    for (j, o) in out.iter_mut().enumerate() {
        let n = d * j + d - 1;
        let mut acc = C64::new(0.0, 0.0);
        for (t, &c) in f.iter().enumerate().take(n + 1) {
            acc += c * x[n - t];
        }
        *o = acc;
    }
}

/// Kurtosis of a complex envelope, its first `skip` samples left out; 0 when its power per
/// sample is below `floor` (a numerically empty band).
fn kurtosis(x: &[C64], skip: usize, floor: f64) -> f64 {
    let Some(x) = x.get(skip..).filter(|s| s.len() >= 2) else {
        return 0.0;
    };
    let n = x.len() as f64;
    let mean = x.iter().sum::<C64>() / n;
    let (mut m2, mut m4) = (0.0, 0.0);
    for v in x {
        let p = (v - mean).norm_sqr();
        m2 += p;
        m4 += p * p;
    }
    m2 /= n;
    m4 /= n;
    if !(m2 > floor) {
        return 0.0;
    }
    m4 / (m2 * m2) - 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn gaussian(n: usize, sd: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let d = Normal::new(0.0, sd).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    /// Impacts every 1 / `rate_hz` s (slightly jittered, as a bearing's are), each ringing a
    /// resonance at `res_hz` (damping 0.05, peak 1), at `fs` for `seconds`.
    fn impacts(fs: f64, seconds: f64, rate_hz: f64, res_hz: f64, seed: u64) -> Vec<f64> {
        let n = (fs * seconds) as usize;
        let mut out = vec![0.0; n];
        let jitter = gaussian(n, 0.01 / rate_hz, seed);
        let w = 2.0 * std::f64::consts::PI * res_hz;
        let zeta = 0.05;
        let tau = 1.0 / (zeta * w);
        let mut k = 0;
        loop {
            let t0 = (k as f64 + 0.5) / rate_hz + jitter[k];
            if t0 >= seconds {
                break;
            }
            let first = (t0 * fs).ceil() as usize;
            for (i, o) in out
                .iter_mut()
                .enumerate()
                .skip(first)
                .take((10.0 * tau * fs) as usize)
            {
                let dt = i as f64 / fs - t0;
                *o += (-dt / tau).exp() * (w * dt).sin();
            }
            k += 1;
        }
        out
    }

    /// Impacts at 107 Hz ringing `res_hz` (RMS 0.14-0.26 for 4.4-1.3 kHz), under Gaussian
    /// noise (sd 0.3) and a 30 Hz sine of amplitude 5: 2 s at 12 kHz.
    fn buried(res_hz: f64) -> Vec<f32> {
        let fs = 12_000.0;
        let imp = impacts(fs, 2.0, 107.0, res_hz, 1);
        let noise = gaussian(imp.len(), 0.3, 2);
        imp.iter()
            .zip(&noise)
            .enumerate()
            .map(|(i, (a, b))| {
                let t = i as f64 / fs;
                (a + b + 5.0 * (2.0 * std::f64::consts::PI * 30.0 * t).sin()) as f32
            })
            .collect()
    }

    #[test]
    fn the_band_of_a_buried_resonance_is_selected() {
        // 3 kHz sits on the edge between the two level-1 bands (a 1/3 level must find it);
        // 1.3 and 4.4 kHz are off-centre, so a band order reversed in the tree would miss them
        for res in [3000.0, 1300.0, 4400.0] {
            let x = buried(res);
            let mut k = Kurtogram::new(x.len(), 12_000.0, KurtogramSettings::default()).unwrap();
            k.compute(&x).unwrap();
            let best = k.best();
            assert!(best.contains(res), "resonance {res} Hz: best band {best:?}");
            assert!(
                best.kurtosis > 0.5,
                "resonance {res} Hz: best band {best:?}"
            );
            // buried: the full band, dominated by the sine, is not impulsive at all
            let full = k.rows()[0].kurtosis[0];
            assert!(full < 0.0, "resonance {res} Hz: level 0 reads {full}");
        }
    }

    #[test]
    fn gaussian_noise_reads_zero_in_every_band() {
        // 2^17 samples: the deepest nodes keep 2^11, so the estimate's spread is
        // 2 / sqrt(2048) = 0.044; 0.2 is 4.5 of those
        let x: Vec<f32> = gaussian(1 << 17, 1.0, 3)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let mut k = Kurtogram::new(x.len(), 12_000.0, KurtogramSettings::default()).unwrap();
        let rows = k.compute(&x).unwrap();
        assert_eq!(rows.len(), 2 * 6);
        for row in rows {
            for (i, &v) in row.kurtosis.iter().enumerate() {
                assert!(
                    v.abs() < 0.2,
                    "level {} band {i}: kurtosis {v}",
                    row.label()
                );
            }
        }
    }

    #[test]
    fn the_grid_is_antonis() {
        let k = Kurtogram::new(12_000, 12_000.0, KurtogramSettings::default()).unwrap();
        let labels: Vec<String> = k.rows().iter().map(|r| r.label()).collect();
        assert_eq!(
            labels,
            ["0", "1", "1.6", "2", "2.6", "3", "3.6", "4", "4.6", "5", "5.6", "6"]
        );
        let widths: Vec<f64> = k.rows().iter().map(|r| r.bandwidth_hz).collect();
        assert_eq!(
            widths,
            [
                6000.0, 3000.0, 2000.0, 1500.0, 1000.0, 750.0, 500.0, 375.0, 250.0, 187.5, 125.0,
                93.75
            ]
        );
        for r in k.rows() {
            assert!((r.kurtosis.len() as f64 * r.bandwidth_hz - 6000.0).abs() < 1e-9);
        }
        // 12 000 samples hold 6 levels (2^13 = 8192 <= 12 000 < 2^14), not 7
        let e = Kurtogram::new(
            12_000,
            12_000.0,
            KurtogramSettings {
                levels: 7,
                max_hz: None,
            },
        )
        .err()
        .expect("7 levels on 12 000 samples");
        assert!(e.to_string().contains("at most 6 levels"), "{e}");
    }

    #[test]
    fn a_band_limited_search_sees_the_grid_of_the_lower_rate() {
        // 48 kHz: the buried 3 kHz resonance plus a stronger impulsive one at 15 kHz
        let fs = 48_000.0;
        let slow = impacts(fs, 1.0, 107.0, 3000.0, 4);
        let fast = impacts(fs, 1.0, 61.0, 15_000.0, 5);
        let noise = gaussian(slow.len(), 0.3, 6);
        let x: Vec<f32> = (0..slow.len())
            .map(|i| (slow[i] + 2.0 * fast[i] + noise[i]) as f32)
            .collect();
        let mut all = Kurtogram::new(x.len(), fs, KurtogramSettings::default()).unwrap();
        all.compute(&x).unwrap();
        assert!(all.best().contains(15_000.0), "{:?}", all.best());
        let settings = KurtogramSettings {
            levels: 6,
            max_hz: Some(6000.0),
        };
        let mut low = Kurtogram::new(x.len(), fs, settings).unwrap();
        assert_eq!(low.top_hz(), 6000.0);
        low.compute(&x).unwrap();
        assert!(low.best().contains(3000.0), "{:?}", low.best());
        let at_12k = Kurtogram::new(12_000, 12_000.0, KurtogramSettings::default()).unwrap();
        let widths =
            |k: &Kurtogram| -> Vec<f64> { k.rows().iter().map(|r| r.bandwidth_hz).collect() };
        assert_eq!(widths(&low), widths(&at_12k));
    }

    #[test]
    fn kurtosis_of_tone_noise_and_impacts() {
        let n = 4096;
        let tone: Vec<C64> = (0..n)
            .map(|i| C64::from_polar(2.0, 0.37 * i as f64))
            .collect();
        assert!((kurtosis(&tone, 0, 0.0) + 1.0).abs() < 1e-3);
        let mut sparse = vec![C64::new(0.0, 0.0); n];
        for i in (0..n).step_by(64) {
            sparse[i] = C64::new(1.0, 0.0);
        }
        // 1 in 64 samples: E|c|^4 / E|c|^2^2 ~ 64
        assert!(kurtosis(&sparse, 0, 0.0) > 50.0);
        // below the floor a band is empty
        assert_eq!(kurtosis(&sparse, 0, 1.0), 0.0);
    }
}
