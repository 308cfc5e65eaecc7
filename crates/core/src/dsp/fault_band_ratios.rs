//! Fault-family band ratios of an envelope order spectrum: the RMS of a band
//! [`BAND_WIDTH_ORDER`] wide centred on each bearing fault-family order and on its second
//! harmonic (BPFO, BPFI, 2xBSF), over the median RMS of the bands of that width tiling
//! `0..max_order`. A line at a fault order stands out of the window's own floor by this ratio.
//! The analysis stage measures it on every window's classifier channel, from the lines the
//! feature bins are summed from, so the rule baseline (`model::rule`) judges the very
//! windows the model sees. The band buffer is made once.

use serde::Serialize;

/// Width of every band, orders (the thesis' bin width). A band is centred on its kinematic
/// order, so +-0.25 order covers slip and speed error (+-7 % at BPFO 3.58, +-2.3 % at
/// 2xBPFI 10.8).
pub const BAND_WIDTH_ORDER: f64 = 0.5;

/// Band ratios at BPFO, 2xBPFO, BPFI, 2xBPFI, 2xBSF and 4xBSF (in this order); 0 when the
/// median band is 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FaultBandRatios(pub [f64; 6]);

impl FaultBandRatios {
    /// The outer-race family: the larger of the bands at BPFO and 2xBPFO.
    pub fn outer_race(&self) -> f64 {
        self.0[0].max(self.0[1])
    }

    /// The inner-race family: BPFI and 2xBPFI.
    pub fn inner_race(&self) -> f64 {
        self.0[2].max(self.0[3])
    }

    /// The ball family: 2xBSF (a ball defect strikes both races once per ball spin) and 4xBSF.
    pub fn ball(&self) -> f64 {
        self.0[4].max(self.0[5])
    }
}

/// Measures [`FaultBandRatios`] at one bearing's orders.
#[derive(Debug, Clone)]
pub struct FaultBandMeter {
    centres: [f64; 6],
    max_order: f64,
    bands: Vec<f32>,
}

impl FaultBandMeter {
    /// At the fault orders `bpfo`, `bpfi` and `two_bsf`, the median over `0..max_order`.
    pub fn new(bpfo: f64, bpfi: f64, two_bsf: f64, max_order: f64) -> Self {
        let n_bands = ((max_order / BAND_WIDTH_ORDER).round() as usize).max(1);
        FaultBandMeter {
            centres: [bpfo, 2.0 * bpfo, bpfi, 2.0 * bpfi, two_bsf, 2.0 * two_bsf],
            max_order,
            bands: vec![0.0; n_bands],
        }
    }

    /// The ratios of one envelope order spectrum given as power lines `order_step` apart
    /// (line 0 at order 0).
    pub fn measure(&mut self, order_step: f64, power: &[f32]) -> FaultBandRatios {
        let mut out = [0.0; 6];
        let centres = self.centres;
        self.ratios_at(order_step, power, &centres, &mut out);
        FaultBandRatios(out)
    }

    /// The same statistic at any orders: RMS of the band centred at each of `centres` over
    /// the median band, into `out` (0 when the median is 0).
    pub fn ratios_at(&mut self, order_step: f64, power: &[f32], centres: &[f64], out: &mut [f64]) {
        let w = BAND_WIDTH_ORDER;
        crate::dsp::features::band_rms(power, order_step, w, &mut self.bands);
        let mid = self.bands.len() / 2;
        let median = *self.bands.select_nth_unstable_by(mid, f32::total_cmp).1 as f64;
        // RMS of the lines in (centre - w/2, centre + w/2]
        let band_at = |centre: f64| {
            let lo = (((centre - 0.5 * w) / order_step + 1e-9).floor() as usize) + 1;
            let hi = (((centre + 0.5 * w) / order_step + 1e-9).floor() as usize)
                .min(power.len().saturating_sub(1));
            (lo..=hi)
                .map(|j| power[j].max(0.0) as f64)
                .sum::<f64>()
                .sqrt()
        };
        for (r, &t) in out.iter_mut().zip(centres) {
            *r = if median > 0.0 {
                band_at(t) / median
            } else {
                0.0
            };
        }
    }

    /// Highest order of the spectrum the median is taken over.
    pub fn max_order(&self) -> f64 {
        self.max_order
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_at_a_family_order_stands_out_of_a_flat_floor() {
        // flat floor: power 1 per line, 50 lines per 0.5-order band -> band RMS sqrt(50)
        let step = 0.01;
        let mut p = vec![1.0f32; 5001];
        let (bpfo, bpfi, two_bsf) = (3.585f64, 5.415f64, 4.714f64);
        p[(bpfi / step).round() as usize] = 450.0;
        let mut m = FaultBandMeter::new(bpfo, bpfi, two_bsf, 50.0);
        let r = m.measure(step, &p);
        assert!(
            (r.inner_race() - (499.0f64 / 50.0).sqrt()).abs() < 1e-3,
            "{r:?}"
        );
        assert!((r.outer_race() - 1.0).abs() < 1e-3, "{r:?}");
        assert!((r.ball() - 1.0).abs() < 1e-3, "{r:?}");
        assert_eq!(m.max_order(), 50.0);
        // the same meter, called again, gives the same (no state kept between windows)
        assert_eq!(m.measure(step, &p), r);
    }
}
