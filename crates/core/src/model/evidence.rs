//! Fault-family evidence relative to the machine's own healthy baseline: how far the feature
//! bins at a bearing's fault orders (BPFO, BPFI, 2xBSF and their second harmonics) stand above
//! the machine's healthy windows, in standard deviations. An aligned model's graph outputs
//! each bin's deviation from the healthy reference (`baseline_deviation`, in units of the
//! baseline's pooled spread, [`super::baseline`]); this file picks the fault-family bins and
//! turns the deviation into a z-score that is honest about how well it is known:
//!
//! - the spread is the healthy windows' pooled spread, corrected for having been measured on
//!   `n` windows against their own mean (x `sqrt(n / (n - 1))`), and never below what the
//!   envelope spectrum's own noise gives a bin of `m` lines: a band of `m` noise lines has
//!   `ln RMS` with standard deviation `0.5 sqrt(psi'(m))` (`psi'` the trigamma function,
//!   about `0.5 / sqrt(m)`), `m = bin_width x revolutions per window`, so a slower window is
//!   allowed more scatter than the healthy windows it is compared with;
//! - a new window differs from the mean of `n` healthy windows by `sqrt(1 + 1/n)` of that
//!   spread.
//!
//! A family's evidence combines its two harmonics: for h = 1, 2 the largest z over the bins
//! overlapping `h x order x (1 +- SLIP)`, standardised as the largest of that many standard
//! normal values is (its mean and standard deviation subtracted and divided out, so taking
//! the largest of two bins adds no bias), summed and divided by the square root of the number
//! of harmonics: on healthy windows it is a standard normal value, a fault raising both
//! harmonics counts twice. A stationary fault is there window after window, so the evidence
//! accumulates ([`EvidenceHistory`]): the mean over the last windows, in units of its own
//! standard deviation given how much the windows overlap. The health verdict
//! ([`crate::health::verdict`]) uses the accumulated evidence to confirm or overrule the
//! classifier.

use crate::bearing::FaultOrders;
use crate::config::RigConfig;
use crate::vocabulary::Condition;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Relative allowance around a kinematic order for rolling-element slip and speed error
/// (slip of 1-2 % is typical of rolling bearings; Randall & Antoni, MSSP 2011).
pub const SLIP: f64 = 0.02;

/// Fault families with their class labels, in the order [`FamilyEvidence`] keeps them.
pub const FAMILY_LABELS: [&str; 3] = Condition::FAULT_NAMES;

/// Mean and standard deviation of the largest of k independent standard normal values,
/// k = 1..=6 (order statistics; numerical integration).
const MAX_OF_NORMALS: [(f32, f32); 6] = [
    (0.0, 1.0),
    (0.564_19, 0.825_65),
    (0.846_28, 0.747_98),
    (1.029_38, 0.701_22),
    (1.162_96, 0.668_98),
    (1.267_21, 0.644_92),
];

/// z-score per fault family: how many standard deviations the family's strongest bin stands
/// above the machine's healthy level (negative: below it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FamilyEvidence {
    pub outer_race: f32,
    pub inner_race: f32,
    pub ball: f32,
}

impl FamilyEvidence {
    /// The evidence for a class label (None for labels that are no fault family).
    pub fn of(&self, label: &str) -> Option<f32> {
        match Condition::parse(label)? {
            Condition::OuterRace => Some(self.outer_race),
            Condition::InnerRace => Some(self.inner_race),
            Condition::Ball => Some(self.ball),
            Condition::Healthy => None,
        }
    }

    /// The family with the largest evidence at or above `z`, with that evidence (ties go to
    /// the first in [`FAMILY_LABELS`] order).
    pub fn strongest(&self, z: f32) -> Option<(&'static str, f32)> {
        FAMILY_LABELS
            .iter()
            .map(|&l| (l, self.of(l).unwrap_or(f32::NAN)))
            .filter(|&(_, v)| v >= z)
            .fold(None, |best, (l, v)| match best {
                Some((_, b)) if b >= v => best,
                _ => Some((l, v)),
            })
    }
}

/// What the healthy baseline's spread rests on (from an aligned model's
/// [`super::alignment::Alignment::spread`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaselineSpread {
    /// 1 / pooled standard deviation of the healthy windows' log ratios.
    pub inv_spread: f32,
    /// Healthy windows the baseline was fitted on.
    pub windows: usize,
}

/// The feature bins of each fault family, and the arithmetic from deviations to evidence.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyBins {
    /// Bin indices per family (in [`FAMILY_LABELS`] order) and harmonic (1, 2); a harmonic
    /// beyond the last bin has none.
    bins: [[Vec<usize>; 2]; 3],
    bin_width: f64,
    window_s: f64,
    hop_fraction: f64,
}

impl FamilyBins {
    /// The families of the rig's bearing in the rig's feature layout.
    pub fn for_rig(rig: &RigConfig) -> Self {
        let f = &rig.features;
        let mut bins = Self::new(
            &rig.bearing.fault_orders(),
            f.bin_width_order,
            f.n_bins(),
            f.window_s,
        );
        bins.hop_fraction = f.hop_s / f.window_s;
        bins
    }

    /// `hop_s / window_s` of the windows (0.5 unless made from a rig file).
    pub fn hop_fraction(&self) -> f64 {
        self.hop_fraction
    }

    /// Families at `orders` for `n_bins` bins `bin_width` orders wide (bin k covers
    /// `(k w, (k + 1) w]`), windows of `window_s` seconds.
    pub fn new(orders: &FaultOrders, bin_width: f64, n_bins: usize, window_s: f64) -> Self {
        let near = |order: f64| -> Vec<usize> {
            let (lo, hi) = (order * (1.0 - SLIP), order * (1.0 + SLIP));
            // bins (k w, (k+1) w] that overlap [lo, hi], at most as many as the table knows
            let first = (lo / bin_width).ceil().max(1.0) as usize - 1;
            let last = ((hi / bin_width).ceil() as usize).max(1) - 1;
            (first..=last)
                .filter(|&k| k < n_bins)
                .take(MAX_OF_NORMALS.len())
                .collect()
        };
        let family = |order: f64| [near(order), near(2.0 * order)];
        FamilyBins {
            bins: [
                family(orders.bpfo),
                family(orders.bpfi),
                family(orders.two_bsf),
            ],
            bin_width,
            window_s,
            hop_fraction: 0.5,
        }
    }

    /// The bins of each family (in [`FAMILY_LABELS`] order) at its first and second harmonic.
    pub fn bins(&self) -> &[[Vec<usize>; 2]; 3] {
        &self.bins
    }

    /// Evidence of one window from its bins' deviations (`baseline_deviation`, units of the
    /// pooled spread) at `rpm`.
    pub fn evidence(&self, deviation: &[f32], spread: BaselineSpread, rpm: f64) -> FamilyEvidence {
        let pooled = 1.0 / spread.inv_spread as f64;
        let n = spread.windows.max(2) as f64;
        let lines = self.bin_width * rpm.max(0.0) / 60.0 * self.window_s;
        let sd = (pooled * (n / (n - 1.0)).sqrt()).max(noise_sd(lines)) * (1.0 + 1.0 / n).sqrt();
        // deviation (pooled units) -> natural-log units -> the honest z
        let scale = (pooled / sd) as f32;
        let family = |harmonics: &[Vec<usize>; 2]| {
            let (mut sum, mut n) = (0.0f32, 0usize);
            for bins in harmonics.iter().filter(|b| !b.is_empty()) {
                let top = bins
                    .iter()
                    .filter_map(|&k| deviation.get(k))
                    .fold(f32::NEG_INFINITY, |m, &d| m.max(d * scale));
                let (mu, sigma) = MAX_OF_NORMALS[bins.len() - 1];
                sum += (top - mu) / sigma;
                n += 1;
            }
            if n == 0 {
                f32::NAN
            } else {
                sum / (n as f32).sqrt()
            }
        };
        FamilyEvidence {
            outer_race: family(&self.bins[0]),
            inner_race: family(&self.bins[1]),
            ball: family(&self.bins[2]),
        }
    }
}

/// The last windows' evidence, accumulated: a fault that is there window after window adds
/// up, noise averages out. The mean over the stored windows is divided by its own standard
/// deviation: windows that share samples are correlated (lag k shares
/// `max(0, 1 - k x hop / window)` of them, taken as their correlation), so m windows count as
/// `n_eff = m^2 / sum_ij rho_|i-j|` independent ones and the accumulated z is
/// `mean x sqrt(n_eff)`.
#[derive(Debug, Clone, PartialEq)]
pub struct EvidenceHistory {
    windows: VecDeque<FamilyEvidence>,
    capacity: usize,
    /// hop / window of the windows (0.5 by default: 1 s windows every 0.5 s).
    hop_fraction: f64,
}

impl EvidenceHistory {
    /// Keep the last `capacity` windows (at least 1).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        EvidenceHistory {
            windows: VecDeque::with_capacity(capacity + 1),
            capacity,
            hop_fraction: 0.5,
        }
    }

    /// Windows `hop_fraction` x their length apart (`hop_s / window_s`).
    pub fn set_hop_fraction(&mut self, hop_fraction: f64) {
        if hop_fraction.is_finite() && hop_fraction > 0.0 {
            self.hop_fraction = hop_fraction;
        }
    }

    /// Forget every window (another model, another machine).
    pub fn clear(&mut self) {
        self.windows.clear();
    }

    /// Add one window's evidence; returns the accumulated evidence.
    pub fn push(&mut self, e: FamilyEvidence) -> FamilyEvidence {
        if self.windows.len() >= self.capacity {
            self.windows.pop_front();
        }
        self.windows.push_back(e);
        let m = self.windows.len();
        let mut weight = 0.0;
        for i in 0..m {
            for j in 0..m {
                weight += (1.0 - i.abs_diff(j) as f64 * self.hop_fraction).max(0.0);
            }
        }
        let scale = ((m * m) as f64 / weight).sqrt() as f32 / m as f32;
        let sum = |f: fn(&FamilyEvidence) -> f32| self.windows.iter().map(f).sum::<f32>() * scale;
        FamilyEvidence {
            outer_race: sum(|e| e.outer_race),
            inner_race: sum(|e| e.inner_race),
            ball: sum(|e| e.ball),
        }
    }
}

/// Standard deviation of `ln RMS` of a band of `m` envelope-spectrum noise lines (each line's
/// power exponential, the band's power Gamma(m)): `0.5 sqrt(psi'(m))`; 0 when m is not
/// positive (no floor).
pub fn noise_sd(m: f64) -> f64 {
    if m.is_nan() || m <= 0.0 {
        return 0.0;
    }
    0.5 * trigamma(m).sqrt()
}

/// The trigamma function psi'(x) for x > 0 (recurrence up to 10, then the asymptotic series).
fn trigamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc += 1.0 / (x * x);
        x += 1.0;
    }
    let x2 = 1.0 / (x * x);
    acc + 1.0 / x + x2 / 2.0 + (1.0 / 6.0 - x2 * (1.0 / 30.0 - x2 / 42.0)) * x2 / x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orders() -> FaultOrders {
        crate::bearing::BearingGeometry {
            balls: 9,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 39.04,
            contact_angle_deg: 0.0,
        }
        .fault_orders()
    }

    #[test]
    fn family_bins_cover_the_orders_and_their_second_harmonics() {
        let f = FamilyBins::new(&orders(), 0.5, 100, 1.0);
        // BPFO 3.585 -> (3.5, 4.0] = bin 7; 2xBPFO 7.17 +-2 % = 7.03..7.31 -> bin 14
        assert_eq!(f.bins()[0], [vec![7], vec![14]]);
        // BPFI 5.415 +-2 % = 5.31..5.52 -> bins 10, 11; 2xBPFI 10.83 +-2 % -> 21, 22
        assert_eq!(f.bins()[1], [vec![10, 11], vec![21, 22]]);
        // 2xBSF 4.714 -> bin 9; 4xBSF 9.43 +-2 % = 9.24..9.62 -> 18, 19
        assert_eq!(f.bins()[2], [vec![9], vec![18, 19]]);
        // a short spectrum: the second harmonics fall beyond it
        let short = FamilyBins::new(&orders(), 0.5, 12, 1.0);
        assert_eq!(short.bins()[1], [vec![10, 11], vec![]]);
    }

    #[test]
    fn evidence_is_in_honest_standard_deviations() {
        let f = FamilyBins::new(&orders(), 0.5, 100, 1.0);
        let mut dev = vec![0.0f32; 100];
        // pooled spread 0.1 over 16 windows at 1800 rpm (15 lines per bin: noise sd 0.131)
        let spread = BaselineSpread {
            inv_spread: 10.0,
            windows: 16,
        };
        let sd = noise_sd(15.0) * (17.0f64 / 16.0).sqrt();
        // BPFI raised by 1.0 (natural log) in one of its two bins, 2xBPFI by 0.5 in one
        dev[10] = 10.0;
        dev[21] = 5.0;
        dev[7] = -3.0;
        let e = f.evidence(&dev, spread, 1800.0);
        let (mu, sigma) = MAX_OF_NORMALS[1];
        let want = ((1.0 / sd) as f32 - mu) / sigma + ((0.5 / sd) as f32 - mu) / sigma;
        let want = want / 2f32.sqrt();
        assert!((e.inner_race - want).abs() < 1e-4, "{e:?} vs {want}");
        // outer race: BPFO at -3 pooled units, 2xBPFO at 0 (one bin each: no correction)
        let want_or = ((-0.3 / sd) as f32 + 0.0) / 2f32.sqrt();
        assert!((e.outer_race - want_or).abs() < 1e-4, "{e:?}");
        assert_eq!(e.strongest(3.0).map(|s| s.0), Some("inner_race"));
        assert_eq!(e.strongest(9.0), None);
        // a wide pooled spread measured on few windows sets the scale instead
        let few = BaselineSpread {
            inv_spread: 2.0,
            windows: 4,
        };
        let e = f.evidence(&dev, few, 1800.0);
        let sd = 0.5 * (4.0f64 / 3.0).sqrt() * (1.25f64).sqrt();
        let want = ((5.0 / sd) as f32 - mu) / sigma + ((2.5 / sd) as f32 - mu) / sigma;
        assert!((e.inner_race - want / 2f32.sqrt()).abs() < 1e-4, "{e:?}");
    }

    #[test]
    fn healthy_windows_give_standard_normal_evidence() {
        // deviations drawn as the healthy windows' own scatter: the family evidence has mean
        // ~0 and standard deviation ~1 (the largest-of-two correction removes the bias)
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let f = FamilyBins::new(&orders(), 0.5, 100, 1.0);
        let spread = BaselineSpread {
            inv_spread: 10.0,
            windows: 1000,
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let normal = Normal::new(0.0f32, 1.0).unwrap();
        let z: Vec<f32> = (0..4000)
            .map(|_| {
                let dev: Vec<f32> = (0..100).map(|_| normal.sample(&mut rng)).collect();
                // a window at 6000 rpm: 50 lines per bin, the pooled spread rules
                f.evidence(&dev, spread, 6000.0).inner_race
            })
            .collect();
        let mean = z.iter().sum::<f32>() / z.len() as f32;
        let var = z.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / z.len() as f32;
        assert!(
            mean.abs() < 0.05 && (var.sqrt() - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }

    #[test]
    fn a_steady_fault_accumulates_and_noise_does_not() {
        let e = |v: f32| FamilyEvidence {
            outer_race: 0.0,
            inner_race: v,
            ball: -v,
        };
        let mut h = EvidenceHistory::new(5);
        // one window: itself
        assert_eq!(h.push(e(2.0)), e(2.0));
        for _ in 0..4 {
            h.push(e(2.0));
        }
        // five half-overlapping windows: sum rho = 5 + 2 x 4 x 0.5 = 9 -> n_eff 25/9
        let acc = h.push(e(2.0));
        assert!(
            (acc.inner_race - 2.0 * (25.0f32 / 9.0).sqrt()).abs() < 1e-5,
            "{acc:?}"
        );
        // windows that do not overlap count fully
        let mut apart = EvidenceHistory::new(4);
        apart.set_hop_fraction(1.0);
        for _ in 0..3 {
            apart.push(e(1.0));
        }
        assert!((apart.push(e(1.0)).inner_race - 2.0).abs() < 1e-6);
        // alternating noise cancels
        let mut noise = EvidenceHistory::new(4);
        apart.clear();
        for s in [1.0, -1.0, 1.0] {
            noise.push(e(s));
        }
        assert!(noise.push(e(-1.0)).inner_race.abs() < 1e-6);
    }

    #[test]
    fn noise_floor_follows_the_gamma_distribution() {
        // psi'(1) = pi^2 / 6; psi'(15) ~ 1/15 + 1/450
        assert!((trigamma(1.0) - std::f64::consts::PI.powi(2) / 6.0).abs() < 1e-9);
        assert!((trigamma(15.0) - 0.068_938_227_848).abs() < 1e-9);
        assert!(noise_sd(5.0) > noise_sd(15.0));
        assert_eq!(noise_sd(0.0), 0.0);
    }
}
