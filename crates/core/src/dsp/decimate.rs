//! A streaming decimator: a linear-phase FIR low-pass (Blackman-windowed sinc) evaluated only
//! at every `factor`-th input sample, fed in blocks of any size. The output does not depend on
//! how the input was cut into blocks, and nothing is allocated after construction. Used by
//! the speed tracker, which needs only the lowest few hundred hertz of a signal sampled at up
//! to tens of kilohertz.

/// Decimate by an integer factor with an anti-alias FIR.
#[derive(Debug, Clone)]
pub struct Decimator {
    factor: usize,
    taps: Vec<f32>,
    /// The last `taps.len()` inputs, twice over (a mirrored ring: a contiguous slice always
    /// holds the newest `taps.len()` samples).
    ring: Vec<f32>,
    pos: usize,
    /// Inputs seen since construction or reset.
    seen: u64,
}

impl Decimator {
    /// Decimate by `factor` (>= 1), keeping frequencies below `keep` times the output Nyquist
    /// (e.g. 0.8). `factor = 1` passes samples through.
    pub fn new(factor: usize, keep: f64) -> Decimator {
        let factor = factor.max(1);
        let taps = if factor == 1 {
            vec![1.0]
        } else {
            design(factor, keep)
        };
        let n = taps.len();
        Decimator {
            factor,
            taps,
            ring: vec![0.0; 2 * n],
            pos: 0,
            seen: 0,
        }
    }

    /// Delay of the filter in input samples ((taps - 1) / 2).
    pub fn delay(&self) -> f64 {
        (self.taps.len() - 1) as f64 / 2.0
    }

    /// Forget the past (a discontinuity in the input).
    pub fn reset(&mut self) {
        self.ring.fill(0.0);
        self.pos = 0;
        self.seen = 0;
    }

    /// Feed samples; each output sample is passed to `out` together with the index (since
    /// the last reset) of the input sample it was computed at. Outputs are produced at inputs
    /// `factor - 1, 2 factor - 1, ...`. Non-finite inputs count as 0.
    pub fn push(&mut self, x: &[f32], mut out: impl FnMut(u64, f32)) {
        let n = self.taps.len();
        for &v in x {
            let v = if v.is_finite() { v } else { 0.0 };
            self.ring[self.pos] = v;
            self.ring[self.pos + n] = v;
            self.pos = (self.pos + 1) % n;
            self.seen += 1;
            if self.seen % self.factor as u64 == 0 {
                // ring[pos..pos + n] holds the newest n samples, oldest first
                let newest = &self.ring[self.pos..self.pos + n];
                let acc: f32 = newest
                    .iter()
                    .zip(self.taps.iter().rev())
                    .map(|(a, b)| a * b)
                    .sum();
                out(self.seen - 1, acc);
            }
        }
    }
}

/// Blackman-windowed sinc, cut-off `keep / (2 factor)` cycles per input sample, unit DC gain.
fn design(factor: usize, keep: f64) -> Vec<f32> {
    let n = 8 * factor + 1;
    let fc = keep / (2.0 * factor as f64);
    let mid = (n - 1) as f64 / 2.0;
    let mut h: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 - mid;
            let sinc = if t == 0.0 {
                2.0 * fc
            } else {
                (2.0 * std::f64::consts::PI * fc * t).sin() / (std::f64::consts::PI * t)
            };
            let a = 2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64;
            sinc * (0.42 - 0.5 * a.cos() + 0.08 * (2.0 * a).cos())
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.iter_mut().for_each(|v| *v /= sum);
    h.into_iter().map(|v| v as f32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(d: &mut Decimator, x: &[f32], block: usize) -> Vec<(u64, f32)> {
        let mut out = Vec::new();
        for c in x.chunks(block) {
            d.push(c, |i, v| out.push((i, v)));
        }
        out
    }

    #[test]
    fn blocks_do_not_matter_and_passband_is_kept() {
        let fs = 10_000.0;
        let x: Vec<f32> = (0..20_000)
            .map(|i| {
                let t = i as f64 / fs;
                ((2.0 * std::f64::consts::PI * 40.0 * t).sin()
                    + (2.0 * std::f64::consts::PI * 3_000.0 * t).sin()) as f32
            })
            .collect();
        let whole = run(&mut Decimator::new(20, 0.8), &x, x.len());
        for b in [1, 7, 333] {
            assert_eq!(run(&mut Decimator::new(20, 0.8), &x, b), whole, "block {b}");
        }
        assert_eq!(whole.len(), 1000);
        // after the filter has filled: the 40 Hz tone passes with unit gain, 3 kHz is gone
        let d = Decimator::new(20, 0.8);
        let delay = d.delay();
        let mut worst = 0.0f64;
        for &(i, v) in &whole[20..] {
            let t = (i as f64 - delay) / fs;
            let want = (2.0 * std::f64::consts::PI * 40.0 * t).sin();
            worst = worst.max((v as f64 - want).abs());
        }
        assert!(worst < 0.01, "worst error {worst}");
    }
}
