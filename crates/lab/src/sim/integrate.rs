//! The time integrator: semi-implicit (symplectic) Euler at an internal step `oversampling`
//! times finer than the output step, with the stiff contact damping of the ball bearing
//! treated implicitly (a 2x2 solve per step on the journal-housing relative velocity), so
//! large Hertz damping never destabilises the explicit part. Starts from the static
//! equilibrium under gravity, ramps the unbalance in during the warm-up, and streams the
//! sensor signals through the anti-aliasing decimators. Deterministic for a given RNG state;
//! no allocation inside the step loop.

use super::bearing_contact::BallBearing;
use super::decimate::{design, Decimator};
use super::profile::SpeedProfile;
use super::rotor::RotorModel;
use super::structure::Structure;
use anyhow::{bail, Result};
use rand::rngs::StdRng;
use std::f64::consts::TAU;

/// Output of the integrator, before noise, units and tacho shaping.
#[derive(Debug, Clone)]
pub struct EngineOutput {
    /// One vector per requested signal (index into `config::simulation::SIGNALS`).
    pub signals: Vec<Vec<f64>>,
    /// Shaft angle (rad) at the boundaries between output samples: entry n is at
    /// t = (n - 1/2) / fs, so sample n spans entries n..n+1. Length = samples + 1.
    pub boundary_angles: Vec<f64>,
    /// Largest number of balls in contact at once.
    pub max_loaded: u32,
    /// Largest journal-housing relative displacement seen, m.
    pub max_excursion: f64,
    /// The signal index (`config::simulation::SIGNALS`) of each entry of `signals`.
    pub want: Vec<usize>,
    /// With [`Engine::record_forces`]: the force on the housing (axial, vertical,
    /// horizontal; N) at every internal step from the first warm-up step, and the number of
    /// warm-up steps; the structural path was left out of `signals`
    /// ([`super::split`] adds it).
    pub housing_forces: Option<(Vec<[f64; 3]>, i64)>,
}

/// Everything the step loop needs.
pub struct Engine {
    pub rotor: RotorModel,
    pub bearing: BallBearing,
    pub structure: Structure,
    pub profile: SpeedProfile,
    pub fs: f64,
    pub oversampling: usize,
    pub warmup_s: f64,
    /// Extra static load on the NDE journal, N (downwards positive).
    pub radial_load_n: f64,
    /// Keep the housing forces of every internal step in the output (for a later pass of
    /// the structural path alone, [`super::split`]); `structure` should then have no modes.
    pub record_forces: bool,
}

/// Static equilibrium of the vertical plane under gravity (+ extra load) with the nonlinear
/// bearing: returns the DOF displacements and the bearing's linearised radial stiffness
/// (vertical, horizontal), N/m.
pub fn static_equilibrium(
    rotor: &RotorModel,
    bearing: &BallBearing,
    radial_load_n: f64,
) -> Result<(Vec<f64>, [f64; 2])> {
    let p = &rotor.planes[0];
    let mut f = rotor.gravity.clone();
    f[rotor.nde] -= radial_load_n;
    let xg =
        p.k.solve(&f)
            .ok_or_else(|| anyhow::anyhow!("the rig model is not held (singular stiffness)"))?;
    let mut unit = vec![0.0; rotor.n];
    unit[rotor.nde] = 1.0;
    unit[rotor.nde_housing] = -1.0;
    let xs =
        p.k.solve(&unit)
            .ok_or_else(|| anyhow::anyhow!("singular stiffness"))?;
    let eg = xg[rotor.nde] - xg[rotor.nde_housing];
    let s = xs[rotor.nde] - xs[rotor.nde_housing];
    let g = |e: f64| e - eg - bearing.static_force([e, 0.0])[0] * s;
    let reach = bearing.gap + 1e-3;
    let (mut lo, mut hi) = (eg.min(-reach) - 1e-3, eg.max(reach) + 1e-3);
    if g(lo) > 0.0 || g(hi) < 0.0 {
        bail!("could not find the static equilibrium of the test bearing (load far outside the model's range)");
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let e = 0.5 * (lo + hi);
    let fb = bearing.static_force([e, 0.0])[0];
    let x: Vec<f64> = xg.iter().zip(&xs).map(|(a, b)| a + fb * b).collect();
    let h = 1e-8;
    let kv = -(bearing.static_force([e + h, 0.0])[0] - bearing.static_force([e - h, 0.0])[0])
        / (2.0 * h);
    let kh = -(bearing.static_force([e, h])[1] - bearing.static_force([e, -h])[1]) / (2.0 * h);
    Ok((x, [kv, kh]))
}

#[inline]
fn rot((c, s): (f64, f64), (dc, ds): (f64, f64)) -> (f64, f64) {
    (c * dc - s * ds, s * dc + c * ds)
}

/// Dot products of both planes at once: lane p of the result is the dot product of lane p
/// of `a` and `b`, on two independent accumulators per lane (even and odd entries).
#[inline]
fn dot2(a: &[[f64; 2]], b: &[[f64; 2]]) -> [f64; 2] {
    let (ca, cb) = (a.chunks_exact(2), b.chunks_exact(2));
    let mut tail = [0.0f64; 2];
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        for p in 0..2 {
            tail[p] += x[p] * y[p];
        }
    }
    let (mut even, mut odd) = ([0.0f64; 2], [0.0f64; 2]);
    for (x, y) in ca.zip(cb) {
        for p in 0..2 {
            even[p] += x[0][p] * y[0][p];
            odd[p] += x[1][p] * y[1][p];
        }
    }
    [0, 1].map(|p| even[p] + odd[p] + tail[p])
}

#[inline]
fn phasor(a: f64) -> (f64, f64) {
    let (s, c) = a.sin_cos();
    (c, s)
}

/// [M^-1 K | M^-1 C] row by row, both planes per entry, against the state [x | v]: one dot
/// product of 2n per row.
fn stacked_rows(rotor: &RotorModel) -> Vec<[f64; 2]> {
    let n = rotor.n;
    (0..n)
        .flat_map(|r| {
            (0..2 * n).map(move |j| {
                [0, 1].map(|p| {
                    let pl = &rotor.planes[p];
                    if j < n {
                        pl.minv_k.a[r * n + j]
                    } else {
                        pl.minv_c.a[r * n + j - n]
                    }
                })
            })
        })
        .collect()
}

impl Engine {
    /// Run for `n_out` output samples, producing the signals listed in `want`.
    pub fn run(&mut self, n_out: usize, want: &[usize], rng: &mut StdRng) -> Result<EngineOutput> {
        let k = self.oversampling;
        let dt = 1.0 / (self.fs * k as f64);
        let inv_dt = 1.0 / dt;
        let taps = design(k, 14);
        let d = (taps.len() / 2) as i64;
        let ki = k as i64;
        let half = ki / 2;
        let w_steps = ((self.warmup_s / dt).round() as i64).max(d + ki);
        let last = (n_out as i64 - 1) * ki + d;
        let mut decs: Vec<Decimator> = want.iter().map(|_| Decimator::new(taps.clone())).collect();
        let mut signals: Vec<Vec<f64>> = want.iter().map(|_| vec![0.0; n_out]).collect();
        let mut bounds = vec![0.0; n_out + 1];

        let rotor = &self.rotor;
        let n = rotor.n;
        let (nde, hn, hd) = (rotor.nde, rotor.nde_housing, rotor.de_housing);
        let (x0, _) = static_equilibrium(rotor, &self.bearing, self.radial_load_n)?;
        // Both planes side by side: entry [vertical, horizontal] of every DOF, so each
        // operation of the step runs on the two planes at once (two lanes).
        let mut x: Vec<[f64; 2]> = x0.iter().map(|&x| [x, 0.0]).collect();
        let mut v = vec![[0.0f64; 2]; n];
        // constant accelerations: gravity + radial load (vertical plane)
        let mut fg = rotor.gravity.clone();
        fg[nde] -= self.radial_load_n;
        let g_acc = rotor.planes[0].minv.mul_vec(&fg);
        let g_acc: Vec<[f64; 2]> = g_acc.iter().map(|&g| [g, 0.0]).collect();
        let lanes = |f: &dyn Fn(usize, usize) -> f64| -> Vec<[f64; 2]> {
            (0..n).map(|i| [f(0, i), f(1, i)]).collect()
        };
        let bcol = lanes(&|p, i| rotor.planes[p].minv[(i, nde)] - rotor.planes[p].minv[(i, hn)]);
        let disc_cols: Vec<Vec<[f64; 2]>> = rotor
            .discs
            .iter()
            .map(|&dj| lanes(&|p, i| rotor.planes[p].minv[(i, dj)]))
            .collect();
        let mu = rotor.planes[0].minv[(nde, nde)] + rotor.planes[0].minv[(hn, hn)]
            - 2.0 * rotor.planes[0].minv[(nde, hn)];
        let kc = stacked_rows(rotor);
        let mut state = vec![[0.0f64; 2]; 2 * n];
        let disc_phase: Vec<(f64, f64)> =
            rotor.unbalance.iter().map(|&(_, ph)| phasor(ph)).collect();
        let (m_ax, k_ax, c_ax) = rotor.axial;
        let (mut xa, mut va) = (0.0f64, 0.0f64);
        let mut acc = vec![[0.0f64; 2]; n];
        let mut unb = vec![[0.0f64; 2]; rotor.discs.len()];
        self.bearing.randomize_jitter(rng);

        let (mut th_s, mut th_c, mut psi) = (0.0f64, 0.0f64, 0.0f64);
        let (mut ps, mut pc, mut pp) = ((1.0, 0.0), (1.0, 0.0), (1.0, 0.0));
        let (mut ds, mut dc, mut dp) = ((1.0, 0.0), (1.0, 0.0), (1.0, 0.0));
        let (mut inc_s, mut inc_c, mut inc_p) = (0.0f64, 0.0f64, 0.0f64);
        let mut pir = (1.0, 0.0);
        let mut unb_amp = vec![0.0; rotor.discs.len()];
        let mut max_loaded = 0u32;
        let mut max_exc = 0.0f64;
        let mut sig = [0.0f64; 5];
        let mut forces: Option<Vec<[f64; 3]>> = self
            .record_forces
            .then(|| Vec::with_capacity((last + w_steps + 1).max(0) as usize));

        let mut i = -w_steps;
        // i mod k, kept by counting (no integer division per step): the output-sample
        // boundaries, the half-step angle boundaries and the decimator's output instants
        let mut phase = i.rem_euclid(ki);
        let boundary_phase = (ki - half).rem_euclid(ki);
        let output_phase = d.rem_euclid(ki);
        while i <= last {
            if phase == 0 {
                let t = i as f64 * dt;
                let ws = self.profile.rpm_at(t) * TAU / 60.0;
                let wc = ws * self.bearing.cage_ratio;
                let wsp = ws * self.bearing.spin_ratio;
                ps = phasor(th_s);
                pc = phasor(th_c);
                pp = phasor(psi);
                pir = phasor(th_s + self.bearing.ir_phase);
                // the step rotations change only with the speed
                if (ws * dt, wc * dt, wsp * dt) != (inc_s, inc_c, inc_p) {
                    (inc_s, inc_c, inc_p) = (ws * dt, wc * dt, wsp * dt);
                    ds = phasor(inc_s);
                    dc = phasor(inc_c);
                    dp = phasor(inc_p);
                }
                let ramp = if i >= 0 {
                    1.0
                } else {
                    0.5 - 0.5 * (std::f64::consts::PI * (i + w_steps) as f64 / w_steps as f64).cos()
                };
                for (a, &(me, _)) in unb_amp.iter_mut().zip(&rotor.unbalance) {
                    *a = me * ws * ws * ramp;
                }
                let tau = if wc > 0.0 { TAU / wc } else { 1.0 };
                self.bearing.update_jitter(rng, k as f64 * dt, tau);
                // divergence guard
                let e = ((x[nde][0] - x[hn][0]).powi(2) + (x[nde][1] - x[hn][1]).powi(2)).sqrt();
                if !e.is_finite() || e > 1e-2 {
                    bail!("the simulation diverged at t = {t:.4} s (journal excursion {e:.3e} m); check the [simulation] stiffness/damping values or raise oversampling");
                }
                max_exc = max_exc.max(e);
            }
            if phase == boundary_phase {
                let b = (i + half) / ki;
                if b >= 0 && (b as usize) <= n_out {
                    bounds[b as usize] = th_s;
                }
            }

            // --- bearing forces
            let e = [x[nde][0] - x[hn][0], x[nde][1] - x[hn][1]];
            let ev = [v[nde][0] - v[hn][0], v[nde][1] - v[hn][1]];
            let cf = self.bearing.forces(e, ev, pc, pir, pp, inv_dt);
            max_loaded = max_loaded.max(cf.loaded);
            for (u, (&a, &dph)) in unb.iter_mut().zip(unb_amp.iter().zip(&disc_phase)) {
                let (c, s) = rot(ps, dph);
                *u = [-a * c, a * s];
            }
            // --- explicit part, both planes at once
            state[..n].copy_from_slice(&x);
            state[n..].copy_from_slice(&v);
            let fb = cf.elastic;
            for (r, row) in kc.chunks_exact(2 * n).enumerate() {
                let s = dot2(row, &state);
                let mut a = [0.0; 2];
                for p in 0..2 {
                    a[p] = g_acc[r][p] + bcol[r][p] * fb[p];
                    a[p] -= s[p];
                }
                for (dc_, u) in disc_cols.iter().zip(&unb) {
                    for p in 0..2 {
                        a[p] += dc_[r][p] * u[p];
                    }
                }
                acc[r] = a;
            }
            for (vr, ar) in v.iter_mut().zip(&acc) {
                for p in 0..2 {
                    vr[p] += dt * ar[p];
                }
            }
            // pre-implicit housing velocities (state holds them), for the accelerations
            let (hd_old, hn_old) = (state[n + hd], state[n + hn]);
            // --- implicit contact damping on the relative velocity
            let vr = [v[nde][0] - v[hn][0], v[nde][1] - v[hn][1]];
            let h = dt * mu;
            let (a11, a12, a22) = (1.0 + h * cf.c[0], h * cf.c[1], 1.0 + h * cf.c[2]);
            let r1 = vr[0] + h * cf.b[0];
            let r2 = vr[1] + h * cf.b[1];
            let det = a11 * a22 - a12 * a12;
            let vn = [(r1 * a22 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det];
            let fd = [
                -(cf.c[0] * vn[0] + cf.c[1] * vn[1]) + cf.b[0],
                -(cf.c[1] * vn[0] + cf.c[2] * vn[1]) + cf.b[1],
            ];
            for ((vr, xr), b) in v.iter_mut().zip(x.iter_mut()).zip(&bcol) {
                for p in 0..2 {
                    vr[p] += dt * b[p] * fd[p];
                    xr[p] += dt * vr[p];
                }
            }
            let mut hd_acc = [0.0; 2];
            let mut hn_acc = [0.0; 2];
            for p in 0..2 {
                hd_acc[p] = (v[hd][p] - hd_old[p]) * inv_dt;
                hn_acc[p] = (v[hn][p] - hn_old[p]) * inv_dt;
            }
            // --- axial housing DOF
            let aa = (cf.axial - k_ax * xa - c_ax * va) / m_ax;
            va += dt * aa;
            xa += dt * va;
            // --- structural path: force on the housing = -(force on the journal)
            let fh = [cf.axial, -(cf.elastic[0] + fd[0]), -(cf.elastic[1] + fd[1])];
            let ar = self.structure.step(fh, dt);
            if let Some(f) = forces.as_mut() {
                f.push(fh);
            }
            sig[0] = aa + ar[0];
            sig[1] = hn_acc[0] + ar[1];
            sig[2] = hn_acc[1] + ar[2];
            sig[3] = hd_acc[0];
            sig[4] = hd_acc[1];
            if i >= -d {
                for (dec, &w) in decs.iter_mut().zip(want) {
                    dec.push(sig[w]);
                }
                let j = i - d;
                if j >= 0 && phase == output_phase {
                    let o = (j / ki) as usize;
                    if o < n_out {
                        for (dec, s) in decs.iter().zip(signals.iter_mut()) {
                            s[o] = dec.output();
                        }
                    }
                }
            }
            // --- kinematics
            th_s += inc_s;
            th_c += inc_c;
            psi += inc_p;
            ps = rot(ps, ds);
            pc = rot(pc, dc);
            pp = rot(pp, dp);
            pir = rot(pir, ds);
            i += 1;
            phase += 1;
            if phase == ki {
                phase = 0;
            }
        }
        Ok(EngineOutput {
            signals,
            boundary_angles: bounds,
            max_loaded,
            max_excursion: max_exc,
            want: want.to_vec(),
            housing_forces: forces.map(|f| (f, w_steps)),
        })
    }
}
