//! Rolling-bearing kinematics: the characteristic fault orders (FTF, BPFO, BPFI, BSF, 2xBSF)
//! of a ball bearing with a stationary outer ring, as multiples of shaft speed and in Hz.

use serde::{Deserialize, Serialize};

/// Geometry that fixes the kinematic fault orders of a ball bearing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BearingGeometry {
    /// Number of rolling elements (balls).
    pub balls: u32,
    /// Ball diameter d in mm.
    pub ball_diameter_mm: f64,
    /// Pitch diameter D in mm.
    pub pitch_diameter_mm: f64,
    /// Contact angle alpha in degrees (0 for an unloaded deep-groove bearing).
    #[serde(default)]
    pub contact_angle_deg: f64,
}

/// Characteristic frequencies as orders (multiples of the shaft/inner-ring speed).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FaultOrders {
    /// Fundamental train (cage) frequency.
    pub ftf: f64,
    /// Ball-pass frequency, outer race.
    pub bpfo: f64,
    /// Ball-pass frequency, inner race.
    pub bpfi: f64,
    /// Ball spin frequency.
    pub bsf: f64,
    /// Twice the ball spin frequency (a ball defect strikes both races per spin).
    pub two_bsf: f64,
}

impl FaultOrders {
    /// The same frequencies in Hz at shaft speed `shaft_hz`.
    pub fn at_hz(&self, shaft_hz: f64) -> FaultOrders {
        FaultOrders {
            ftf: self.ftf * shaft_hz,
            bpfo: self.bpfo * shaft_hz,
            bpfi: self.bpfi * shaft_hz,
            bsf: self.bsf * shaft_hz,
            two_bsf: self.two_bsf * shaft_hz,
        }
    }

    /// (name, order) pairs in a fixed order, for markers and band tables.
    pub fn named(&self) -> [(&'static str, f64); 4] {
        [
            ("FTF", self.ftf),
            ("BPFO", self.bpfo),
            ("BPFI", self.bpfi),
            ("2xBSF", self.two_bsf),
        ]
    }
}

impl BearingGeometry {
    /// d/D * cos(alpha), the ratio that all fault orders are built from.
    fn ratio(&self) -> f64 {
        self.ball_diameter_mm / self.pitch_diameter_mm * self.contact_angle_deg.to_radians().cos()
    }

    /// The same bearing with another contact angle.
    pub fn with_contact_angle(&self, contact_angle_deg: f64) -> BearingGeometry {
        BearingGeometry {
            contact_angle_deg,
            ..*self
        }
    }

    /// Fault orders (thesis eq. 1.1, 1.2, Paper A eq. 8; Harris for BSF).
    pub fn fault_orders(&self) -> FaultOrders {
        let r = self.ratio();
        let n = self.balls as f64;
        let dd = self.pitch_diameter_mm / self.ball_diameter_mm;
        let bsf = 0.5 * dd * (1.0 - r * r);
        FaultOrders {
            ftf: 0.5 * (1.0 - r),
            bpfo: 0.5 * n * (1.0 - r),
            bpfi: 0.5 * n * (1.0 + r),
            bsf,
            two_bsf: 2.0 * bsf,
        }
    }

    /// Check the numbers make a bearing; the message says which value is wrong.
    pub fn validate(&self) -> Result<(), String> {
        if self.balls < 3 {
            return Err(format!(
                "bearing.balls = {} (a ball bearing has at least 3 balls)",
                self.balls
            ));
        }
        if !(self.ball_diameter_mm > 0.0 && self.pitch_diameter_mm > self.ball_diameter_mm) {
            return Err(format!(
                "bearing.ball_diameter_mm = {} and pitch_diameter_mm = {}: need 0 < d < D",
                self.ball_diameter_mm, self.pitch_diameter_mm
            ));
        }
        if !(0.0..90.0).contains(&self.contact_angle_deg) {
            return Err(format!(
                "bearing.contact_angle_deg = {} (must be in [0, 90))",
                self.contact_angle_deg
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn skf6007(alpha: f64) -> BearingGeometry {
        BearingGeometry {
            balls: 11,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 48.0,
            contact_angle_deg: alpha,
        }
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// Paper A Table 6, theoretical rows. The table's numbers follow from D = 48.5 mm, the mean
    /// of bore and outside diameter ((35 + 62) / 2), not from Table 1's pitch diameter of 48 mm:
    /// with 48.5 mm every row matches to the table's rounding (0.02 Hz).
    #[test]
    fn thesis_table6_theoretical_rows() {
        let b = |alpha| BearingGeometry {
            pitch_diameter_mm: 48.5,
            ..skf6007(alpha)
        };
        let f0 = b(0.0).fault_orders().at_hz(9.8);
        assert!(close(f0.bpfo, 45.08, 0.02), "{}", f0.bpfo);
        assert!(close(f0.bpfi, 62.72, 0.02), "{}", f0.bpfi);
        assert!(close(3.0 * f0.bpfi, 188.16, 0.05));
        let f28 = b(28.3).fault_orders().at_hz(9.8);
        assert!(close(f28.bpfo, 46.13, 0.02), "{}", f28.bpfo);
        assert!(close(f28.bpfi, 61.67, 0.02), "{}", f28.bpfi);
        let f19 = b(0.0).fault_orders().at_hz(19.8);
        assert!(close(f19.bpfo, 91.08, 0.02), "{}", f19.bpfo);
        assert!(close(f19.bpfi, 126.72, 0.02), "{}", f19.bpfi);
        let f2887 = b(28.87).fault_orders().at_hz(19.8);
        assert!(close(f2887.bpfo, 93.30, 0.03), "{}", f2887.bpfo);
        assert!(close(f2887.bpfi, 124.50, 0.03), "{}", f2887.bpfi);
    }

    /// With Table 1's D = 48 mm (the shipped rig file) the same rows agree within 0.25 %.
    #[test]
    fn table1_geometry_within_quarter_percent_of_table6() {
        for (alpha, fr, bpfo, bpfi) in [
            (0.0, 9.8, 45.08, 62.72),
            (28.3, 9.8, 46.13, 61.67),
            (0.0, 19.8, 91.08, 126.72),
        ] {
            let f = skf6007(alpha).fault_orders().at_hz(fr);
            assert!(
                (f.bpfo / bpfo - 1.0).abs() < 0.0025,
                "alpha {alpha}: {} vs {bpfo}",
                f.bpfo
            );
            assert!(
                (f.bpfi / bpfi - 1.0).abs() < 0.0025,
                "alpha {alpha}: {} vs {bpfi}",
                f.bpfi
            );
        }
    }

    /// Paper A Table 5: cage frequency at alpha = 0 and the average contact angle (D = 48.5 mm).
    #[test]
    fn thesis_table5_cage() {
        let b = |alpha| BearingGeometry {
            pitch_diameter_mm: 48.5,
            ..skf6007(alpha)
        };
        assert!(close(b(0.0).fault_orders().ftf * 9.8, 4.10, 0.01));
        assert!(close(b(28.38).fault_orders().ftf * 9.8, 4.20, 0.01));
        assert!(close(b(28.87).fault_orders().ftf * 19.8, 8.49, 0.01));
    }

    /// CWRU's published orders for the 6205-2RS drive-end bearing.
    #[test]
    fn cwru_published_orders() {
        let b = BearingGeometry {
            balls: 9,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 39.04,
            contact_angle_deg: 0.0,
        };
        let o = b.fault_orders();
        assert!(close(o.bpfi, 5.4152, 0.002), "{}", o.bpfi);
        assert!(close(o.bpfo, 3.5848, 0.002), "{}", o.bpfo);
        assert!(close(o.ftf, 0.39828, 0.0003), "{}", o.ftf);
        assert!(close(o.two_bsf, 4.7135, 0.003), "{}", o.two_bsf);
    }

    #[test]
    fn invalid_geometry_is_named() {
        let mut b = skf6007(0.0);
        b.pitch_diameter_mm = 5.0;
        assert!(b.validate().unwrap_err().contains("0 < d < D"));
    }
}
