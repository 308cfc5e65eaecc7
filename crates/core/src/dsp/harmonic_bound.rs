//! The harmonic sum's grid search without evaluating every grid point (issue 37 item 4): the
//! grid of [`Whitened::best_in`] is cut into cells of one spectral bin, each cell gets an upper
//! bound of the shaft evidence any of its points can reach (per harmonic the highest bin the
//! harmonic can touch over the cell, the mains lines taken either way where a cell straddles
//! one), and cells are evaluated point by point from the highest bound down until the best
//! point found beats every bound left. The result is bit for bit the full scan's (the same
//! points, the same order of ties), at a fraction of the cost: a clear line leaves a few cells
//! to evaluate, noise a few tens of the several hundred.

use super::harmonic_sum::{is_mains, on_mains_harmonic, Whitened, HARMONICS, LONE_ALLOW};

/// Grid points per cell: one spectral bin of the fundamental (the grid step is a tenth of it).
const CELL: usize = 2 * HARMONICS;
/// Margin on a bound against rounding in the interpolated prominence (log units, ~1e-15 off).
const MARGIN: f64 = 1e-9;

/// Whether a harmonic over a cell may be left out as a mains line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mains {
    /// Counted at every point of the cell.
    Never,
    /// Left out at every point of the cell.
    Always,
    /// Counted at some points, left out at others.
    Maybe,
}

impl Whitened {
    /// The best fundamental in [lo, hi] on the grid of [`Self::best_in_scan`], found by
    /// bounding cells of the grid (module doc): the same (Hz, score) as the full scan.
    pub fn best_in(&self, lo: f64, hi: f64) -> (f64, f64) {
        if self.scan {
            return self.best_in_scan(lo, hi);
        }
        let step = self.df / (2 * HARMONICS) as f64;
        // the grid is the scan's own (accumulated, so bit for bit the same points)
        let mut cells: Vec<(f64, f64, f64)> = Vec::new();
        let (mut f, mut j) = (lo, 0usize);
        let mut first = lo;
        while f <= hi {
            if j % CELL == 0 {
                first = f;
            }
            let last = f;
            f += step;
            j += 1;
            if j % CELL == 0 || f > hi {
                cells.push((self.cell_bound(first, last), first, last));
            }
        }
        let key = |b: f64| if b.is_nan() { f64::INFINITY } else { b };
        cells.sort_by(|a, b| key(b.0).total_cmp(&key(a.0)));
        let mut best = (lo, f64::NEG_INFINITY);
        for &(bound, first, last) in &cells {
            if bound < best.1 {
                break;
            }
            let mut f = first;
            loop {
                let s = self.shaft(f);
                if !is_mains(f) && (s > best.1 || (s == best.1 && f < best.0)) {
                    best = (f, s);
                }
                if f >= last {
                    break;
                }
                f += step;
            }
        }
        best
    }

    /// An upper bound of [`Self::shaft`] over the fundamentals in [a, b].
    fn cell_bound(&self, a: f64, b: f64) -> f64 {
        let tol = 1.5 * self.df;
        let (mut sure, mut n) = (0.0, 0usize);
        let mut maybe = [f64::NEG_INFINITY; HARMONICS];
        let mut first_line = f64::NEG_INFINITY;
        for k in 1..=HARMONICS {
            let (x, y) = (k as f64 * a, k as f64 * b);
            let top = self.max_between(x, y);
            if k == 1 {
                first_line = top;
            }
            let mains = if self.skip_mains {
                mains_over(x, y, tol)
            } else {
                Mains::Never
            };
            match mains {
                Mains::Never => {
                    sure += top;
                    n += 1;
                }
                Mains::Maybe => maybe[k - 1] = top,
                Mains::Always => {}
            }
        }
        // the highest mean over the harmonics always counted and any of the others
        maybe.sort_by(|p, q| q.total_cmp(p));
        for m in maybe.into_iter().filter(|m| *m > f64::NEG_INFINITY) {
            if n == 0 || m > sure / n as f64 {
                sure += m;
                n += 1;
            }
        }
        let full = if n == 0 {
            f64::NEG_INFINITY
        } else {
            sure / n as f64
        };
        let lone = if self.lone {
            first_line - LONE_ALLOW
        } else {
            f64::NEG_INFINITY
        };
        full.max(lone) + MARGIN
    }

    /// The highest prominence the spectrum can be read at between `x` and `y` Hz (the bins
    /// either side of each point, interpolated or nearest); -inf beyond the spectrum.
    fn max_between(&self, x: f64, y: f64) -> f64 {
        let i0 = (x / self.df).floor().max(0.0) as usize;
        let i1 =
            ((y / self.df).floor().max(0.0) as usize + 1).min(self.prom.len().saturating_sub(1));
        if i0 > i1 || self.prom.is_empty() {
            return f64::NEG_INFINITY;
        }
        let mut top = f64::NEG_INFINITY;
        for &p in &self.prom[i0..=i1] {
            if p.is_nan() {
                // no bound: the cell is evaluated
                return f64::INFINITY;
            }
            top = top.max(p);
        }
        top
    }
}

/// Whether the harmonic sum's mains rule ([`on_mains_harmonic`] within `tol`) holds at
/// none, all or some of the frequencies in [x, y] (a margin either way: undecided is Maybe).
fn mains_over(x: f64, y: f64, tol: f64) -> Mains {
    let (mut any, mut all) = (false, false);
    for m in [50.0f64, 60.0] {
        let k0 = ((x / m).floor() as i64).max(1);
        let k1 = (y / m).ceil() as i64 + 1;
        for k in k0..=k1 {
            let c = k as f64 * m;
            let t = tol.max(0.003 * c);
            if x - MARGIN <= c + t && y + MARGIN >= c - t {
                any = true;
            }
            if x - MARGIN >= c - t && y + MARGIN <= c + t {
                all = true;
            }
        }
    }
    // the rule itself, at both ends, guards the margins above
    let ends = [on_mains_harmonic(x, tol), on_mains_harmonic(y, tol)];
    if all && ends.iter().all(|e| *e) {
        Mains::Always
    } else if any || ends.iter().any(|e| *e) {
        Mains::Maybe
    } else {
        Mains::Never
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Spectra of noise with lines, mains among them, every mode the tracker uses: the
    /// bounded search returns exactly the full scan's point and score.
    #[test]
    fn the_bounded_search_is_the_full_scan_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(34);
        for trial in 0..60 {
            let df = [0.125, 0.1, 0.0625, 0.37][trial % 4];
            let mut prom: Vec<f64> = (0..3000).map(|_| rng.random_range(-2.0..1.2)).collect();
            let f0: f64 = rng.random_range(5.0..60.0);
            for k in 1..=5 {
                let i = (k as f64 * f0 / df).round() as usize;
                if i < prom.len() && rng.random_bool(0.7) {
                    prom[i] = rng.random_range(1.0..4.0);
                }
            }
            for m in [50.0, 100.0, 150.0, 60.0, 120.0] {
                let i = (m / df).round() as usize;
                if i < prom.len() {
                    prom[i] = 5.0;
                }
            }
            if trial % 7 == 0 {
                // coarse values: many exact ties
                prom.iter_mut().for_each(|p| *p = (*p * 2.0).round() / 2.0);
            }
            let w = Whitened {
                df,
                prom,
                skip_mains: trial % 3 != 0,
                interpolate: trial % 5 != 0,
                lone: trial % 2 == 0,
                lobe: 2.0 * df,
                ..Whitened::default()
            };
            for (lo, hi) in [(5.0, 60.0), (4.9, 50.2), (f0 * 0.97, f0 * 1.03), (9.0, 9.5)] {
                let scan = w.best_in_scan(lo, hi);
                let fast = w.best_in(lo, hi);
                assert!(
                    scan.0.to_bits() == fast.0.to_bits() && scan.1.to_bits() == fast.1.to_bits(),
                    "trial {trial} [{lo}, {hi}]: scan {scan:?} bounded {fast:?}"
                );
            }
        }
    }

    #[test]
    fn a_cell_straddling_a_mains_line_is_undecided() {
        assert_eq!(mains_over(49.0, 49.5, 0.1), Mains::Never);
        assert_eq!(mains_over(49.9, 50.05, 0.2), Mains::Always);
        assert_eq!(mains_over(49.7, 50.0, 0.1), Mains::Maybe);
        assert_eq!(mains_over(119.0, 121.0, 0.1), Mains::Maybe);
    }
}
