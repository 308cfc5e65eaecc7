//! Impacts once every two revolutions, looked for in the band where they ring: a loose
//! housing lands on its seat at half the shaft rate, and each landing rings a structural mode
//! of the joint. Weak landings are lost in the broadband energy the `impacts` view reads (the
//! whole band from [`super::views::BAND_MIN_HZ`] to 0.4 fs), but not in the band of the mode
//! they ring: the recording is band-passed to half-octave bands ([`BAND_RATIO`] wide, a
//! quarter octave apart), each band's energy envelope is Fourier-transformed, and its power
//! is summed at the half orders of the shaft, 0.5x to [`HALF_ORDERS`] - 0.5 (the comb of
//! impacts at 0.5x). The same sum at other fractions of an order ([`NULL_OFFSETS`]: a comb
//! shifted off the half orders, where landings put nothing) gives the band's own level: the
//! **ratio** of the half-order comb to the median of the shifted combs is about 1 on noise,
//! whatever the signal's level or the band's, and the recording's ratio is that of its
//! strongest band (the kurtogram's idea: judge impacts where they ring).
//!
//! On a labelled faulty recording the half orders on the fault's own comb (its harmonics and
//! their modulation sidebands) are left out of every comb: that comb is the fault's.
//!
//! [`DETECT_RATIO`] is set from the ratio's distribution on Gaussian noise, not on any
//! recording: one band's ratio (10,500 bands of 3 s noise, numpy, outside rigmon) has its
//! median at 1.0 and its 99.99th percentile at 2.7; a recording's, the strongest of its
//! bands (the unit test below, 200 two-second recordings at 10 kHz), has its median at 1.5,
//! its 99th percentile at 2.0 and its largest at 2.14.

use super::fault_peaks;
use crate::bearing::FaultOrders;
use crate::vocabulary::Condition;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use serde::Serialize;
use std::cell::RefCell;

/// Half orders summed: 0.5x, 1.5x, ... up to this many (0.5x-9.5x: the landings' comb below
/// 10x, where [`super::trace`] reads a half order as impacting).
pub const HALF_ORDERS: usize = 10;
/// Upper over lower edge of a band: half an octave.
pub const BAND_RATIO: f64 = std::f64::consts::SQRT_2;
/// Step between bands' lower edges: a quarter octave (each band overlaps the next by half).
const BAND_STEP: f64 = 1.189_207_115_002_721; // 2^(1/4)
/// Fractions of an order the reference combs sit at (a comb at k + f for each k): off the
/// half orders by at least 0.1 and off the integer orders by at least 0.1.
pub const NULL_OFFSETS: [f64; 14] = [
    0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40, 0.60, 0.65, 0.70, 0.75, 0.80, 0.85, 0.90,
];
/// A recording shows landings when its strongest band's ratio reaches this: three times the
/// power of the shifted combs, beyond the 99.99th percentile of one band on noise (2.7) and
/// so, over a dozen bands, a false alarm in fewer than one recording in a thousand.
pub const DETECT_RATIO: f64 = 3.0;
/// Half orders that must stand on their own for a comb: one line of the envelope (a
/// modulation at one frequency that happens to sit on a half order) can carry the summed
/// comb past [`DETECT_RATIO`]; a train of impacts puts lines at every half order up to its
/// ring-down's bandwidth. On noise a line stands 6 dB above the lines beside it in about 2 %
/// of cases, so three of ten in about one in a thousand.
pub const MIN_LINES: usize = 3;
/// A half order within this of a fault-comb line (relative, at least one bin) is the fault's.
const FAULT_TOL: f64 = 0.03;
/// Fault harmonics and sidebands masked.
const FAULT_HARMONICS: i32 = 3;
const FAULT_SIDEBANDS: i32 = 2;

thread_local! {
    static PLANNER: RefCell<RealFftPlanner<f64>> = RefCell::new(RealFftPlanner::new());
}

/// The landing comb of one recording, band by band (the bands are fixed by the sample rate,
/// so a simulated twin's line up with its measured recording's).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LandingComb {
    /// Lower edge of each band, Hz (the upper is [`BAND_RATIO`] times it).
    pub band_lo_hz: Vec<f64>,
    /// Each band's half-order comb over its shifted combs' median.
    pub ratio: Vec<f64>,
    /// Each band's half orders 0.5x-9.5x, each in dB above the shifted lines beside it less
    /// [`LEVEL_THRESHOLD_DB`] (0 below it, and on a fault's own comb): what the report's
    /// looseness figure draws ([`super::plots::looseness`]).
    pub levels_db: Vec<[f64; HALF_ORDERS]>,
}

/// Per-line levels below this above the shifted combs' level are noise, dB (the threshold of
/// every thresholded view).
pub const LEVEL_THRESHOLD_DB: f64 = 6.0;
const LEVEL_CAP_DB: f64 = 60.0;

impl LandingComb {
    /// The band whose comb stands highest, if any was measured.
    pub fn strongest(&self) -> Option<usize> {
        self.ratio
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, _)| k)
    }

    /// The strongest band's ratio (0: not measured).
    pub fn best_ratio(&self) -> f64 {
        self.strongest().map_or(0.0, |k| self.ratio[k])
    }

    /// The strongest band's edges, Hz.
    pub fn best_band_hz(&self) -> Option<(f64, f64)> {
        self.strongest()
            .map(|k| (self.band_lo_hz[k], self.band_lo_hz[k] * BAND_RATIO))
    }

    /// Band `k`'s ratio (0 where not measured).
    pub fn ratio_in(&self, k: usize) -> f64 {
        self.ratio.get(k).copied().unwrap_or(0.0)
    }

    /// Half orders of the strongest band standing [`LEVEL_THRESHOLD_DB`] above the lines
    /// beside them.
    pub fn standing_lines(&self) -> usize {
        self.strongest().map_or(0, |k| {
            self.levels_db[k].iter().filter(|d| **d > 0.0).count()
        })
    }

    /// The recording shows impacts once every two revolutions: its strongest band's comb
    /// reaches [`DETECT_RATIO`] with at least [`MIN_LINES`] of its lines standing (a comb, not
    /// one envelope line that happens to sit on a half order).
    pub fn detected(&self) -> bool {
        self.best_ratio() >= DETECT_RATIO && self.standing_lines() >= MIN_LINES
    }

    /// The mean of several segments' combs (the same bands); empty when they differ.
    pub fn mean(parts: &[&LandingComb]) -> LandingComb {
        let Some(first) = parts.first() else {
            return LandingComb::default();
        };
        if parts.iter().any(|p| p.band_lo_hz != first.band_lo_hz) {
            return LandingComb::default();
        }
        let n = parts.len() as f64;
        let mut out = (*first).clone();
        for (k, r) in out.ratio.iter_mut().enumerate() {
            *r = parts.iter().map(|p| p.ratio[k]).sum::<f64>() / n;
        }
        for (k, l) in out.levels_db.iter_mut().enumerate() {
            for (j, v) in l.iter_mut().enumerate() {
                *v = parts.iter().map(|p| p.levels_db[k][j]).sum::<f64>() / n;
            }
        }
        out
    }
}

/// The half orders `k + 1/2` (k < [`HALF_ORDERS`]) that are not on a labelled fault's
/// comb.
fn free_half_orders(faults: &[Condition], orders: &FaultOrders, bin_orders: f64) -> Vec<usize> {
    let lines: Vec<f64> = faults
        .iter()
        .filter_map(|f| fault_peaks::family(*f, orders))
        .flat_map(|(_, o, side)| {
            (1..=FAULT_HARMONICS).flat_map(move |m| {
                (-FAULT_SIDEBANDS..=FAULT_SIDEBANDS).map(move |j| m as f64 * o + j as f64 * side)
            })
        })
        .filter(|t| *t > 0.0)
        .collect();
    (0..HALF_ORDERS)
        .filter(|&k| {
            let h = k as f64 + 0.5;
            !lines
                .iter()
                .any(|t| (h - t).abs() <= (FAULT_TOL * t).max(bin_orders))
        })
        .collect()
}

/// The landing comb of `x` (sampled at `fs`, turning at `shaft_hz` on average), its bands
/// from `band_min_hz` to 0.4 fs; `faults` is the recording's label. Not measured (ratio 0)
/// when the recording is too short to resolve the half orders or no band fits.
pub fn measure(
    x: &[f32],
    fs: f64,
    shaft_hz: f64,
    band_min_hz: f64,
    faults: &[Condition],
    orders: &FaultOrders,
) -> LandingComb {
    let n = x.len() - x.len() % 2;
    let band_max_hz = 0.4 * fs;
    if n < 64 || !(shaft_hz > 0.0) || band_min_hz * BAND_RATIO > band_max_hz {
        return LandingComb::default();
    }
    let df = fs / n as f64;
    // a half order must stand apart from the shifted combs: a tenth of an order at least a
    // bin (a 2 s recording at 300 rpm; the nearest shifted combs may then share the half
    // order's bins, and the median of all fourteen ignores them)
    if 0.1 * shaft_hz / df < 1.0 - 1e-6 {
        return LandingComb::default();
    }
    let half = free_half_orders(faults, orders, df / shaft_hz);
    if half.is_empty() {
        return LandingComb::default();
    }
    let (fft, inv) = PLANNER.with(|p| {
        let mut p = p.borrow_mut();
        (p.plan_fft_forward(n), p.plan_fft_inverse(n))
    });
    let mut input = fft.make_input_vec();
    let mean = x[..n].iter().map(|v| *v as f64).sum::<f64>() / n as f64;
    for (d, v) in input.iter_mut().zip(&x[..n]) {
        *d = *v as f64 - mean;
    }
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum)
        .expect("fft sizes match");
    let hann: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
        .collect();
    let mut band_spec = spectrum.clone();
    let mut band = inv.make_output_vec();
    let mut energy_spec = fft.make_output_vec();
    let mut power = vec![0.0; energy_spec.len()];
    let mut out = LandingComb::default();
    let mut lo = band_min_hz;
    while lo * BAND_RATIO <= band_max_hz {
        let hi = lo * BAND_RATIO;
        for (k, (d, s)) in band_spec.iter_mut().zip(&spectrum).enumerate() {
            let f = k as f64 * df;
            *d = if (lo..=hi).contains(&f) {
                *s
            } else {
                Complex::new(0.0, 0.0)
            };
        }
        inv.process(&mut band_spec, &mut band)
            .expect("fft sizes match");
        let e_mean = band.iter().map(|b| b * b).sum::<f64>() / n as f64;
        for ((d, b), w) in input.iter_mut().zip(&band).zip(&hann) {
            *d = (b * b - e_mean) * w;
        }
        fft.process(&mut input, &mut energy_spec)
            .expect("fft sizes match");
        for (p, c) in power.iter_mut().zip(&energy_spec) {
            *p = c.norm_sqr();
        }
        let (ratio, levels) = comb(&power, df, shaft_hz, &half);
        out.band_lo_hz.push(lo);
        out.ratio.push(ratio);
        out.levels_db.push(levels);
        lo *= BAND_STEP;
    }
    out
}

/// The power at the half orders `half` (each line the largest within +-1 bin; beyond the
/// spectrum 0) over the median of the same sum shifted to [`NULL_OFFSETS`]; and each half
/// order's level above the median of the shifted lines beside it (thresholded dB; 0 where
/// masked).
fn comb(power: &[f64], df: f64, shaft_hz: f64, half: &[usize]) -> (f64, [f64; HALF_ORDERS]) {
    let line = |order: f64| -> f64 {
        let i = (order * shaft_hz / df).round() as usize;
        let hi = (i + 1).min(power.len() - 1);
        power[i.saturating_sub(1).min(hi)..=hi]
            .iter()
            .copied()
            .fold(0.0, f64::max)
    };
    let median = |mut v: Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
    };
    let mut levels = [0.0; HALF_ORDERS];
    for &k in half {
        let beside = median(NULL_OFFSETS.iter().map(|&o| line(k as f64 + o)).collect());
        if beside > 0.0 {
            let db = 10.0 * (line(k as f64 + 0.5) / beside).max(1e-6).log10();
            levels[k] = (db - LEVEL_THRESHOLD_DB).clamp(0.0, LEVEL_CAP_DB);
        }
    }
    let sum_at = |offset: f64| -> f64 { half.iter().map(|&k| line(k as f64 + offset)).sum() };
    let null = median(NULL_OFFSETS.iter().map(|&o| sum_at(o)).collect());
    let ratio = if null > 0.0 { sum_at(0.5) / null } else { 0.0 };
    (ratio, levels)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Lcg(u64);
    impl Lcg {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn gauss(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    fn orders() -> FaultOrders {
        FaultOrders {
            ftf: 0.4,
            bpfo: 3.58,
            bpfi: 5.42,
            bsf: 2.36,
            two_bsf: 4.72,
        }
    }

    /// The threshold's ground: on Gaussian noise (200 two-second recordings at 10 kHz, shaft
    /// rates 8-22 Hz, each the strongest of its bands) the ratio's median is 1.5 and none
    /// reaches 2.5 (the largest 2.14).
    #[test]
    fn noise_stays_far_below_the_threshold() {
        let mut rng = Lcg(5);
        let mut ratios = Vec::new();
        for _ in 0..200 {
            let x: Vec<f32> = (0..20_000).map(|_| rng.gauss() as f32).collect();
            let fr = 8.0 + 14.0 * rng.uniform();
            ratios.push(measure(&x, 10_000.0, fr, 300.0, &[], &orders()).best_ratio());
        }
        ratios.sort_by(f64::total_cmp);
        let max = ratios[ratios.len() - 1];
        assert!(max < 2.5, "{max}");
        assert!(!ratios.iter().any(|r| *r >= DETECT_RATIO));
        // the strongest of a dozen bands, so above 1
        let median = ratios[ratios.len() / 2];
        assert!((1.0..1.8).contains(&median), "{median}");
    }

    /// Landings at half the shaft rate ringing a 2.2 kHz mode, their ring-down peak twice the
    /// noise's standard deviation (their energy 2 % of the noise's), are found in the band of
    /// the mode; the same
    /// ring-downs once per revolution (an integer-order comb) are not landings.
    #[test]
    fn weak_landings_are_found_in_the_band_they_ring() {
        let fs = 10_000.0;
        let fr = 10.0;
        let ring = |rate: f64, rng: &mut Lcg| -> Vec<f32> {
            (0..20_000)
                .map(|i| {
                    let t = i as f64 / fs;
                    let since = (t * rate).fract() / rate;
                    let r = 1.0
                        * (-since * 0.02 * std::f64::consts::TAU * 2200.0).exp()
                        * (std::f64::consts::TAU * 2200.0 * since).sin();
                    (r + 0.5 * rng.gauss()) as f32
                })
                .collect()
        };
        let mut rng = Lcg(9);
        let landings = measure(&ring(fr / 2.0, &mut rng), fs, fr, 300.0, &[], &orders());
        assert!(landings.detected(), "{landings:?}");
        let (lo, hi) = landings.best_band_hz().unwrap();
        assert!(lo < 2200.0 && hi > 2200.0, "{lo}-{hi} Hz");
        // the lines stand above the threshold in that band
        let k = landings.strongest().unwrap();
        assert!(
            landings.levels_db[k][0] > 0.0,
            "{:?}",
            landings.levels_db[k]
        );
        let once_a_turn = measure(&ring(fr, &mut rng), fs, fr, 300.0, &[], &orders());
        assert!(!once_a_turn.detected(), "{once_a_turn:?}");
    }

    /// A labelled fault's comb is the fault's: an inner race whose order sits on a half order
    /// (5.5x, its sidebands at 4.5x and 6.5x) is not read as landings.
    #[test]
    fn a_fault_comb_on_half_orders_is_masked() {
        let fs = 10_000.0;
        let fr = 10.0;
        let mut o = orders();
        o.bpfi = 5.5;
        let mut rng = Lcg(3);
        let x: Vec<f32> = (0..20_000)
            .map(|i| {
                let t = i as f64 / fs;
                let rate = o.bpfi * fr;
                let since = (t * rate).fract() / rate;
                let am = 1.0 + 0.5 * (std::f64::consts::TAU * fr * t).cos();
                let r =
                    4.0 * am * (-since * 600.0).exp() * (std::f64::consts::TAU * 3000.0 * t).sin();
                (r + rng.gauss()) as f32
            })
            .collect();
        assert!(measure(&x, fs, fr, 300.0, &[], &o).detected());
        let masked = measure(&x, fs, fr, 300.0, &[Condition::InnerRace], &o);
        assert!(!masked.detected(), "{masked:?}");
    }
}
