//! The median of a window that slides forward along a sequence (the whitened spectrum's
//! background, [`super::harmonic_sum`]): the window's values are kept sorted, so a step costs
//! the values that leave and enter the window rather than a selection over all of it. The
//! value is exactly the one `select_nth_unstable_by(len / 2, f64::total_cmp)` picks from the
//! same window (element `len / 2` in `total_cmp` order).

/// The sorted values of `v[start..end]` of the sequence last passed to [`Self::median`].
#[derive(Debug, Default, Clone)]
pub struct SlidingMedian {
    sorted: Vec<f64>,
    start: usize,
    end: usize,
}

impl SlidingMedian {
    /// Forget the window (call before the first window of a new or changed sequence).
    pub fn reset(&mut self) {
        self.sorted.clear();
        self.start = 0;
        self.end = 0;
    }

    /// Element `len / 2` (in `f64::total_cmp` order) of `v[start..end]`; NaN for an empty
    /// window. `v` must be the sequence of the previous call since [`Self::reset`]; a window
    /// that moves forward (neither bound smaller) is updated by what left and entered it,
    /// any other is sorted afresh.
    pub fn median(&mut self, v: &[f64], start: usize, end: usize) -> f64 {
        if start >= end {
            self.reset();
            return f64::NAN;
        }
        if start < self.start || end < self.end || start >= self.end {
            self.sorted.clear();
            self.sorted.extend_from_slice(&v[start..end]);
            self.sorted.sort_unstable_by(f64::total_cmp);
        } else {
            for x in &v[self.start..start] {
                if let Ok(i) = self.sorted.binary_search_by(|p| p.total_cmp(x)) {
                    self.sorted.remove(i);
                }
            }
            for x in &v[self.end..end] {
                let (Ok(i) | Err(i)) = self.sorted.binary_search_by(|p| p.total_cmp(x));
                self.sorted.insert(i, *x);
            }
        }
        self.start = start;
        self.end = end;
        self.sorted[self.sorted.len() / 2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The selection the whitened spectrum used before (one per window).
    fn selected(v: &[f64]) -> f64 {
        let mut w = v.to_vec();
        let mid = w.len() / 2;
        *w.select_nth_unstable_by(mid, f64::total_cmp).1
    }

    #[test]
    fn it_equals_a_selection_over_every_window_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        // values with many repeats (coarse), signed zeros and infinities among them
        let mut v: Vec<f64> = (0..3000)
            .map(|_| (rng.random_range(-40.0..40.0f64) / 4.0).round() * 0.25)
            .collect();
        v[17] = -0.0;
        v[18] = 0.0;
        v[400] = f64::NEG_INFINITY;
        v[900] = f64::INFINITY;
        for (half, stride) in [(2usize, 1usize), (5, 4), (38, 4), (40, 1), (3, 9)] {
            let mut m = SlidingMedian::default();
            for i in (0..v.len()).step_by(stride) {
                let c = (i + stride / 2).min(v.len() - 1);
                let (a, b) = (c.saturating_sub(half), (c + half + 1).min(v.len()));
                let got = m.median(&v, a, b);
                let want = selected(&v[a..b]);
                assert_eq!(got.to_bits(), want.to_bits(), "window {a}..{b}");
            }
        }
    }

    #[test]
    fn a_window_moving_back_or_empty_is_taken_afresh() {
        let v = [5.0, 1.0, 4.0, 2.0, 3.0, 9.0];
        let mut m = SlidingMedian::default();
        assert_eq!(m.median(&v, 2, 6), 4.0);
        assert_eq!(m.median(&v, 0, 3), 4.0);
        assert_eq!(m.median(&v, 1, 4), 2.0);
        assert!(m.median(&v, 3, 3).is_nan());
        assert_eq!(m.median(&v, 0, 6), 4.0);
    }
}
