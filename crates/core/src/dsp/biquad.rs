//! A second-order IIR section (biquad, transposed direct form II) with Butterworth high- and
//! low-pass designs (bilinear transform, the RBJ audio-EQ cookbook formulas). Streaming, one
//! sample at a time, no allocation; cascade two high-pass sections with
//! [`BUTTERWORTH_4_Q`] for a fourth-order Butterworth. Used to pick the carrier band of the
//! speed tracker's envelope ([`super::fault_family`]).

/// Q of the two sections of a fourth-order Butterworth filter (1 / (2 cos(pi/8)),
/// 1 / (2 cos(3 pi/8))).
pub const BUTTERWORTH_4_Q: [f64; 2] = [0.541_196_1, 1.306_563];
/// Q of a second-order Butterworth section (1 / sqrt 2).
pub const BUTTERWORTH_2_Q: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// One biquad section: coefficients normalised by a0, and its two state variables.
#[derive(Debug, Clone, Copy)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    z: [f64; 2],
}

impl Biquad {
    /// High-pass at `hz` (the -3 dB point for Q = 1/sqrt 2) for a signal sampled at `fs`.
    pub fn highpass(hz: f64, fs: f64, q: f64) -> Biquad {
        let (cos, alpha) = Self::prewarp(hz, fs, q);
        let b0 = (1.0 + cos) / 2.0;
        Self::normalised(
            [b0, -(1.0 + cos), b0],
            [1.0 + alpha, -2.0 * cos, 1.0 - alpha],
        )
    }

    /// Low-pass at `hz` for a signal sampled at `fs`.
    pub fn lowpass(hz: f64, fs: f64, q: f64) -> Biquad {
        let (cos, alpha) = Self::prewarp(hz, fs, q);
        let b0 = (1.0 - cos) / 2.0;
        Self::normalised([b0, 1.0 - cos, b0], [1.0 + alpha, -2.0 * cos, 1.0 - alpha])
    }

    fn prewarp(hz: f64, fs: f64, q: f64) -> (f64, f64) {
        let w0 = std::f64::consts::TAU * hz / fs;
        (w0.cos(), w0.sin() / (2.0 * q))
    }

    fn normalised(b: [f64; 3], a: [f64; 3]) -> Biquad {
        Biquad {
            b: [b[0] / a[0], b[1] / a[0], b[2] / a[0]],
            a: [a[1] / a[0], a[2] / a[0]],
            z: [0.0; 2],
        }
    }

    /// Filter one sample.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let y = self.b[0] * x + self.z[0];
        self.z[0] = self.b[1] * x - self.a[0] * y + self.z[1];
        self.z[1] = self.b[2] * x - self.a[1] * y;
        y
    }

    /// Forget the past.
    pub fn reset(&mut self) {
        self.z = [0.0; 2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steady-state gain of a cascade at `hz` (a sine through it, the last second's RMS).
    fn gain(sections: &mut [Biquad], hz: f64, fs: f64) -> f64 {
        let n = (2.0 * fs) as usize;
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..n {
            let x = (std::f64::consts::TAU * hz * i as f64 / fs).sin();
            let y = sections.iter_mut().fold(x, |v, s| s.step(v));
            if i >= n / 2 {
                num += y * y;
                den += x * x;
            }
        }
        (num / den).sqrt()
    }

    #[test]
    fn fourth_order_butterworth_high_pass() {
        let fs = 51_200.0;
        let make = || BUTTERWORTH_4_Q.map(|q| Biquad::highpass(1000.0, fs, q));
        // -3 dB at the corner, 24 dB per octave below it (-48 dB two octaves down), flat above
        assert!((gain(&mut make(), 1000.0, fs) - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.01);
        assert!(gain(&mut make(), 250.0, fs) < 0.005);
        assert!((gain(&mut make(), 8000.0, fs) - 1.0).abs() < 0.01);
    }

    #[test]
    fn second_order_butterworth_low_pass() {
        let fs = 51_200.0;
        let mut lp = [Biquad::lowpass(4000.0, fs, BUTTERWORTH_2_Q)];
        assert!((gain(&mut lp, 4000.0, fs) - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.01);
        let mut lp = [Biquad::lowpass(4000.0, fs, BUTTERWORTH_2_Q)];
        assert!((gain(&mut lp, 100.0, fs) - 1.0).abs() < 0.01);
    }
}
