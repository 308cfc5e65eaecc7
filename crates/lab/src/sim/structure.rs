//! The high-frequency structural path: housing/sensor resonances (single-degree-of-freedom
//! modes) driven by the bearing forces on the housing, through which defect impacts ring.
//! Each mode has a participation vector (axial, vertical, horizontal) used both for the
//! drive (projected force) and the sensing (reciprocity). Integrated with the simulator's
//! internal step (semi-implicit Euler, frequency pre-warped so the discrete mode rings at
//! exactly the configured frequency).

use crate::config::simulation::ResonanceConfig;

#[derive(Debug, Clone)]
struct Mode {
    w2: f64,
    two_zw: f64,
    inv_m: f64,
    p: [f64; 3],
    q: f64,
    qd: f64,
}

/// All resonances of the structural path.
#[derive(Debug, Clone)]
pub struct Structure {
    modes: Vec<Mode>,
}

impl Structure {
    pub fn new(res: &[ResonanceConfig], dt: f64) -> Structure {
        let modes = res
            .iter()
            .map(|r| {
                let w = std::f64::consts::TAU * r.hz;
                // semi-implicit Euler rings at 2/dt asin(w' dt / 2): pre-warp w'
                let x = (w * dt / 2.0).min(1.0);
                let wp = 2.0 / dt * x.sin().min(0.999);
                Mode {
                    w2: wp * wp,
                    two_zw: 2.0 * r.damping * w,
                    inv_m: 1.0 / r.modal_mass_kg,
                    p: [r.axial, r.vertical, r.horizontal],
                    q: 0.0,
                    qd: 0.0,
                }
            })
            .collect();
        Structure { modes }
    }

    /// Advance one step with force `f` (axial, vertical, horizontal; N, on the housing) and
    /// return the acceleration each axis senses (m/s^2).
    #[inline]
    pub fn step(&mut self, f: [f64; 3], dt: f64) -> [f64; 3] {
        let mut a = [0.0; 3];
        for m in &mut self.modes {
            let drive = (m.p[0] * f[0] + m.p[1] * f[1] + m.p[2] * f[2]) * m.inv_m;
            let acc = drive - m.two_zw * m.qd - m.w2 * m.q;
            m.qd += dt * acc;
            m.q += dt * m.qd;
            a[0] += m.p[0] * acc;
            a[1] += m.p[1] * acc;
            a[2] += m.p[2] * acc;
        }
        a
    }
}

/// The mode a sensor on `axis` (`axial`, `vertical` or `horizontal` of the test-bearing
/// housing) sees most of, by its gain participation^2 / modal mass (drive and sensing along
/// the axis): its index in `res`. None for other signals or without resonances.
pub fn dominant_mode(res: &[ResonanceConfig], axis: &str) -> Option<usize> {
    let p = |r: &ResonanceConfig| match axis {
        "axial" => Some(r.axial),
        "vertical" => Some(r.vertical),
        "horizontal" => Some(r.horizontal),
        _ => None,
    };
    res.iter()
        .enumerate()
        .filter_map(|(i, r)| p(r).map(|p| (i, p * p / r.modal_mass_kg)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Ring-down after an impulse: the zero-crossing period matches the configured frequency.
    #[test]
    fn rings_at_its_frequency() {
        let dt = 1e-5;
        let r = ResonanceConfig {
            hz: 3000.0,
            damping: 0.01,
            modal_mass_kg: 0.1,
            axial: 0.0,
            vertical: 1.0,
            horizontal: 0.0,
        };
        let mut s = Structure::new(&[r], dt);
        let mut out = Vec::new();
        for i in 0..20000 {
            let f = if i == 0 { 1.0 / dt } else { 0.0 };
            out.push(s.step([0.0, f, 0.0], dt)[1]);
        }
        let crossings: Vec<usize> = (101..out.len())
            .filter(|&i| out[i - 1] < 0.0 && out[i] >= 0.0)
            .collect();
        let periods =
            (crossings.last().unwrap() - crossings[0]) as f64 / (crossings.len() - 1) as f64;
        let f = 1.0 / (periods * dt);
        assert!((f - 3000.0).abs() / 3000.0 < 0.003, "{f}");
    }
}
