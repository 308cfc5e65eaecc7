//! The linear part of the rig: a flexible shaft (Euler-Bernoulli beam elements with
//! consistent mass) with rigid discs, the drive-end coupling and bushing, and both bearing
//! housings on springs. The beam is Guyan-reduced onto the lateral displacement of the
//! bearing and disc nodes (static condensation keeps the stiffness exact; the first bending
//! modes stay within ~0.1 % of the full model). One plane for vertical, one for horizontal
//! motion (they differ in housing stiffness); the nonlinear test bearing couples the two
//! planes through its contact forces and is applied from outside ([`super::bearing_contact`]).
//!
//! DOF order per plane: DE journal, discs..., NDE journal, DE housing, NDE housing.

use super::linalg::{generalized_eigen, Mat};
use crate::config::simulation::SimulationConfig;
use anyhow::{bail, Context, Result};

/// Mass, stiffness and damping of one plane (reduced DOFs), plus handy products.
#[derive(Debug, Clone)]
pub struct Plane {
    pub m: Mat,
    pub k: Mat,
    pub c: Mat,
    pub minv: Mat,
    /// M^-1 K and M^-1 C, used every step.
    pub minv_k: Mat,
    pub minv_c: Mat,
}

/// The assembled linear rig.
#[derive(Debug, Clone)]
pub struct RotorModel {
    /// Number of DOFs per plane.
    pub n: usize,
    pub de: usize,
    pub nde: usize,
    pub discs: Vec<usize>,
    pub de_housing: usize,
    pub nde_housing: usize,
    /// [vertical, horizontal].
    pub planes: [Plane; 2],
    /// Gravity load in the vertical plane (N, negative = down), per DOF.
    pub gravity: Vec<f64>,
    /// Per disc: unbalance (kg m) and phase (rad).
    pub unbalance: Vec<(f64, f64)>,
    /// Axial housing DOF: mass, stiffness, damping.
    pub axial: (f64, f64, f64),
}

/// Consistent-mass Euler-Bernoulli element matrices (DOFs: w1, theta1, w2, theta2).
fn beam_element(ei: f64, rho_a: f64, le: f64) -> ([[f64; 4]; 4], [[f64; 4]; 4]) {
    let l = le;
    let kf = ei / (l * l * l);
    let k = [
        [12.0 * kf, 6.0 * l * kf, -12.0 * kf, 6.0 * l * kf],
        [
            6.0 * l * kf,
            4.0 * l * l * kf,
            -6.0 * l * kf,
            2.0 * l * l * kf,
        ],
        [-12.0 * kf, -6.0 * l * kf, 12.0 * kf, -6.0 * l * kf],
        [
            6.0 * l * kf,
            2.0 * l * l * kf,
            -6.0 * l * kf,
            4.0 * l * l * kf,
        ],
    ];
    let mf = rho_a * l / 420.0;
    let m = [
        [156.0 * mf, 22.0 * l * mf, 54.0 * mf, -13.0 * l * mf],
        [
            22.0 * l * mf,
            4.0 * l * l * mf,
            13.0 * l * mf,
            -3.0 * l * l * mf,
        ],
        [54.0 * mf, 13.0 * l * mf, 156.0 * mf, -22.0 * l * mf],
        [
            -13.0 * l * mf,
            -3.0 * l * l * mf,
            -22.0 * l * mf,
            4.0 * l * l * mf,
        ],
    ];
    (k, m)
}

/// The shaft (with discs, journal masses and coupling) Guyan-reduced onto the masters:
/// returns (K_r, M_r, gravity-load vector per unit g).
fn reduced_shaft(sim: &SimulationConfig, masters_m: &[f64]) -> Result<(Mat, Mat, Vec<f64>)> {
    let r = &sim.rotor;
    let len = r.shaft_length_mm * 1e-3;
    let d = r.shaft_diameter_mm * 1e-3;
    let area = std::f64::consts::PI * d * d / 4.0;
    let ei = r.youngs_modulus_gpa * 1e9 * std::f64::consts::PI * d.powi(4) / 64.0;
    let rho_a = r.density_kg_m3 * area;
    let key = |x: f64| (x * 1e7).round() as i64;
    let mut pts: Vec<f64> = (0..=r.elements)
        .map(|i| len * i as f64 / r.elements as f64)
        .collect();
    pts.extend(masters_m);
    pts.sort_by(f64::total_cmp);
    pts.dedup_by(|a, b| key(*a) == key(*b));
    let nn = pts.len();
    let nd = 2 * nn;
    let mut k = Mat::zeros(nd);
    let mut m = Mat::zeros(nd);
    for e in 0..nn - 1 {
        let (ke, me) = beam_element(ei, rho_a, pts[e + 1] - pts[e]);
        for a in 0..4 {
            for b in 0..4 {
                k[(2 * e + a, 2 * e + b)] += ke[a][b];
                m[(2 * e + a, 2 * e + b)] += me[a][b];
            }
        }
    }
    let node = |x: f64| {
        pts.iter()
            .position(|p| key(*p) == key(x))
            .expect("master node in mesh")
    };
    for disc in &r.discs {
        let j = node(disc.position_mm * 1e-3);
        let rad = disc.diameter_mm * 1e-3 / 2.0;
        let h = disc.thickness_mm * 1e-3;
        m[(2 * j, 2 * j)] += disc.mass_kg;
        m[(2 * j + 1, 2 * j + 1)] += disc.mass_kg * (3.0 * rad * rad + h * h) / 12.0;
    }
    for x in [r.de_bearing_mm, r.nde_bearing_mm] {
        let j = node(x * 1e-3);
        m[(2 * j, 2 * j)] += r.journal_mass_kg;
    }
    k[(0, 0)] += r.coupling_stiffness_n_per_m;
    k[(1, 1)] += r.coupling_tilt_stiffness_nm_per_rad;
    // Guyan reduction onto the master translations.
    let master: Vec<usize> = masters_m.iter().map(|&x| 2 * node(x)).collect();
    let slave: Vec<usize> = (0..nd).filter(|i| !master.contains(i)).collect();
    let ns = slave.len();
    let mut kss = Mat::zeros(ns);
    for (a, &i) in slave.iter().enumerate() {
        for (b, &j) in slave.iter().enumerate() {
            kss[(a, b)] = k[(i, j)];
        }
    }
    let nm = master.len();
    // T (nd x nm): masters map to themselves, slaves = -Kss^-1 Ksm.
    let mut t = vec![vec![0.0; nm]; nd];
    for (c, &mi) in master.iter().enumerate() {
        t[mi][c] = 1.0;
        let rhs: Vec<f64> = slave.iter().map(|&s| -k[(s, mi)]).collect();
        let col = kss
            .solve(&rhs)
            .context("the shaft is not held: add a coupling or bearing stiffness")?;
        for (a, &s) in slave.iter().enumerate() {
            t[s][c] = col[a];
        }
    }
    let project = |full: &Mat| {
        let mut out = Mat::zeros(nm);
        for a in 0..nm {
            for b in 0..nm {
                let mut s = 0.0;
                for i in 0..nd {
                    if t[i][a] == 0.0 {
                        continue;
                    }
                    for j in 0..nd {
                        s += t[i][a] * full[(i, j)] * t[j][b];
                    }
                }
                out[(a, b)] = s;
            }
        }
        out
    };
    let kr = project(&k);
    let mr = project(&m);
    // Gravity: consistent load of a rigid translation (w = 1, theta = 0).
    let rigid: Vec<f64> = (0..nd)
        .map(|i| if i % 2 == 0 { 1.0 } else { 0.0 })
        .collect();
    let mg = m.mul_vec(&rigid);
    let g: Vec<f64> = (0..nm)
        .map(|a| (0..nd).map(|i| t[i][a] * mg[i]).sum())
        .collect();
    Ok((kr, mr, g))
}

impl RotorModel {
    pub fn build(sim: &SimulationConfig) -> Result<RotorModel> {
        let r = &sim.rotor;
        let mut masters = vec![r.de_bearing_mm * 1e-3];
        masters.extend(r.discs.iter().map(|d| d.position_mm * 1e-3));
        masters.push(r.nde_bearing_mm * 1e-3);
        let mut sorted = masters.clone();
        sorted.sort_by(f64::total_cmp);
        if sorted.windows(2).any(|w| (w[1] - w[0]).abs() < 1e-4) {
            bail!("simulation.rotor: two of the bearing/disc positions coincide ({masters:?} m); move them apart");
        }
        let (ks, ms, g_shaft) = reduced_shaft(sim, &masters)?;
        let ns = masters.len();
        let n = ns + 2;
        let (de, nde, hde, hnde) = (0, ns - 1, ns, ns + 1);
        let discs: Vec<usize> = (1..ns - 1).collect();
        let h = &sim.housing;
        let kde = r.de_bushing_stiffness_n_per_mm * 1e3;
        let cde = r.de_bushing_damping_ns_per_mm * 1e3;
        // Shaft damping: stiffness-proportional, zeta at the first pinned-shaft mode.
        let (w1, _) = generalized_eigen(&ks, &ms).context("shaft eigen-analysis failed")?;
        let omega1 = w1[0].max(1.0).sqrt();
        let beta = 2.0 * r.shaft_damping_ratio / omega1.max(2.0 * std::f64::consts::PI * 10.0);
        let plane = |k_h: f64| -> Result<Plane> {
            let mut m = Mat::zeros(n);
            let mut k = Mat::zeros(n);
            let mut c = Mat::zeros(n);
            for a in 0..ns {
                for b in 0..ns {
                    m[(a, b)] = ms[(a, b)];
                    k[(a, b)] = ks[(a, b)];
                    c[(a, b)] = beta * ks[(a, b)];
                }
            }
            m[(hde, hde)] = h.mass_kg;
            m[(hnde, hnde)] = h.mass_kg;
            // DE bushing between DE journal and DE housing.
            for (kk, val) in [(&mut k, kde), (&mut c, cde)] {
                kk[(de, de)] += val;
                kk[(hde, hde)] += val;
                kk[(de, hde)] -= val;
                kk[(hde, de)] -= val;
            }
            let ch = 2.0 * h.damping_ratio * (k_h * h.mass_kg).sqrt();
            for hh in [hde, hnde] {
                k[(hh, hh)] += k_h;
                c[(hh, hh)] += ch;
            }
            let minv = m.inverse().context("singular mass matrix")?;
            let minv_k = minv.mul(&k);
            let minv_c = minv.mul(&c);
            Ok(Plane {
                m,
                k,
                c,
                minv,
                minv_k,
                minv_c,
            })
        };
        let planes = [
            plane(h.vertical_stiffness_n_per_m)?,
            plane(h.horizontal_stiffness_n_per_m)?,
        ];
        let mut gravity = vec![0.0; n];
        for a in 0..ns {
            gravity[a] = -sim.gravity_m_s2 * g_shaft[a];
        }
        gravity[hde] = -sim.gravity_m_s2 * h.mass_kg;
        gravity[hnde] = -sim.gravity_m_s2 * h.mass_kg;
        let unbalance = r
            .discs
            .iter()
            .map(|d| (d.unbalance_g_mm * 1e-6, d.unbalance_phase_deg.to_radians()))
            .collect();
        let ka = h.axial_stiffness_n_per_m;
        let axial = (
            h.mass_kg,
            ka,
            2.0 * h.damping_ratio * (ka * h.mass_kg).sqrt(),
        );
        Ok(RotorModel {
            n,
            de,
            nde,
            discs,
            de_housing: hde,
            nde_housing: hnde,
            planes,
            gravity,
            unbalance,
            axial,
        })
    }

    /// Natural frequencies (Hz, ascending) of one plane with the test bearing linearised
    /// to `bearing_stiffness` N/m between the NDE journal and the NDE housing.
    pub fn natural_frequencies(&self, plane: usize, bearing_stiffness: f64) -> Result<Vec<f64>> {
        let p = &self.planes[plane];
        let mut k = p.k.clone();
        let (a, b) = (self.nde, self.nde_housing);
        k[(a, a)] += bearing_stiffness;
        k[(b, b)] += bearing_stiffness;
        k[(a, b)] -= bearing_stiffness;
        k[(b, a)] -= bearing_stiffness;
        let (vals, _) = generalized_eigen(&k, &p.m).context("eigen-analysis failed")?;
        Ok(vals
            .iter()
            .map(|l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect())
    }
}
