//! The nonlinear test ball bearing: n balls on a cage, Hertzian contacts F = k delta^e with
//! the Adams IMPACT damping ramp (Paper A eq. 3-5), radial clearance or axial preload,
//! contact angle, cage kinematics with mean slip and random ball-position jitter, and the
//! localized defects of [`super::defects`].
//!
//! Angles are measured from the bottom of the bearing (6 o'clock) in the direction of
//! rotation; the unit vector to ball j is u = (-cos theta_j, sin theta_j) in (vertical,
//! horizontal). The inner loop works on phasors (cos, sin) rotated each step: no trig and
//! no allocation per ball per step.

use super::defects::{DefectSet, Slot};
use crate::bearing::BearingGeometry;
use crate::config::simulation::{BallBearingConfig, DefectConfig};
use rand::Rng;
use rand_distr::StandardNormal;
use std::f64::consts::TAU;

/// Static description plus per-ball state.
#[derive(Debug, Clone)]
pub struct BallBearing {
    pub n: usize,
    pub k: f64,
    pub expo: f64,
    pub c_max: f64,
    pub d_pen: f64,
    /// Clearance gap per side (m), 0 when preloaded.
    pub gap: f64,
    /// Normal approach from the axial preload (m).
    pub delta_pre: f64,
    pub preload_n: f64,
    pub cos_a: f64,
    pub sin_a: f64,
    /// Cage speed / shaft speed (with slip), ball spin / shaft speed (relative to the cage).
    pub cage_ratio: f64,
    pub spin_ratio: f64,
    pub slip_jitter: f64,
    pub defects: DefectSet,
    pub outer_slot: Slot,
    pub inner_slot: Slot,
    pub ball_slot_outer: Slot,
    pub ball_slot_inner: Slot,
    /// Outer-race defect position phasor.
    pub or_pos: (f64, f64),
    pub ir_phase: f64,
    /// Per-ball jitter offsets (rad) and their phasors (spacing included).
    pub jitter: Vec<f64>,
    pub offsets: Vec<(f64, f64)>,
    /// Nominal ball phasors on the cage (2 pi j / n).
    pub spacing: Vec<(f64, f64)>,
    pub drop_prev: Vec<f64>,
}

/// sin and cos of `x`: Taylor series to x^13 / x^12 for |x| <= 0.1 (truncation below
/// 1e-24, so within rounding of `sin_cos`), `sin_cos` beyond.
#[inline]
fn small_sin_cos(x: f64) -> (f64, f64) {
    const S: [f64; 6] = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
    ];
    const C: [f64; 6] = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
    ];
    if x.abs() > 0.1 {
        return x.sin_cos();
    }
    let x2 = x * x;
    let horner = |k: &[f64; 6]| k.iter().rev().fold(0.0, |acc, &c| acc * x2 + c);
    (x + x * x2 * horner(&S), 1.0 + x2 * horner(&C))
}

/// Forces of one step, on the shaft journal (radial) and on the housing (axial).
#[derive(Debug, Clone, Copy, Default)]
pub struct ContactForces {
    /// Elastic radial force on the shaft (vertical, horizontal), N.
    pub elastic: [f64; 2],
    /// Damping matrix (symmetric 2x2: cvv, cvh, chh) acting on the relative velocity.
    pub c: [f64; 3],
    /// Damping force from the defect-profile rate, on the shaft, N.
    pub b: [f64; 2],
    /// Axial force on the housing minus the static preload, N.
    pub axial: f64,
    /// Balls in contact.
    pub loaded: u32,
}

impl BallBearing {
    pub fn new(
        geom: &BearingGeometry,
        cfg: &BallBearingConfig,
        contact_angle_deg: f64,
        defect: &DefectConfig,
        defects: DefectSet,
    ) -> BallBearing {
        let n = geom.balls as usize;
        let alpha = contact_angle_deg.to_radians();
        let (sin_a, cos_a) = alpha.sin_cos();
        let expo = cfg.contact_exponent;
        // N/mm^e -> N/m^e
        let k = cfg.contact_stiffness_n_per_mm15 * 1000f64.powf(expo);
        let d = geom.ball_diameter_mm * 1e-3;
        let pd = geom.pitch_diameter_mm * 1e-3;
        let r = geom.ball_diameter_mm / geom.pitch_diameter_mm * cos_a;
        let cage_ratio = 0.5 * (1.0 - r) * (1.0 - cfg.slip);
        let spin_ratio = 0.5 * (pd / d) * (1.0 - r * r) * (1.0 - cfg.slip);
        let (gap, delta_pre) = if cfg.preload_n > 0.0 && sin_a > 1e-6 {
            (
                0.0,
                (cfg.preload_n / (n as f64 * k * sin_a)).powf(1.0 / expo),
            )
        } else {
            (0.5 * cfg.radial_clearance_mm * 1e-3, 0.0)
        };
        let rb = d / 2.0;
        let ro = pd / 2.0 + rb;
        let ri = pd / 2.0 - rb;
        let or_angle = defect.outer_race_position_deg.to_radians();
        let mut b = BallBearing {
            n,
            k,
            expo,
            c_max: cfg.contact_damping_ns_per_mm * 1e3,
            d_pen: cfg.penetration_mm * 1e-3,
            gap,
            delta_pre,
            preload_n: if delta_pre > 0.0 { cfg.preload_n } else { 0.0 },
            cos_a,
            sin_a,
            cage_ratio,
            spin_ratio,
            slip_jitter: cfg.slip_jitter,
            defects,
            // Balls roll over the races along the pitch circle (angle of the ball centre).
            outer_slot: Slot::new(defect, rb, ro, false, ro),
            inner_slot: Slot::new(defect, rb, ri, true, ri),
            ball_slot_outer: Slot::new(defect, rb, ro, false, rb),
            ball_slot_inner: Slot::new(defect, rb, ri, true, rb),
            or_pos: (or_angle.cos(), or_angle.sin()),
            ir_phase: defect.inner_race_position_deg.to_radians(),
            jitter: vec![0.0; n],
            offsets: vec![(1.0, 0.0); n],
            spacing: (0..n)
                .map(|j| {
                    let (s, c) = (TAU * j as f64 / n as f64).sin_cos();
                    (c, s)
                })
                .collect(),
            drop_prev: vec![0.0; n],
        };
        b.refresh_offsets();
        b
    }

    /// Random jitter: each ball wanders in its pocket (Ornstein-Uhlenbeck, correlation time
    /// `tau` s) with a standard deviation that makes successive ball passes vary by
    /// `slip_jitter` of the ball spacing. Call once per output sample.
    pub fn update_jitter<R: Rng>(&mut self, rng: &mut R, dt: f64, tau: f64) {
        if self.slip_jitter <= 0.0 {
            return;
        }
        let sigma = self.slip_jitter * TAU / self.n as f64 / std::f64::consts::SQRT_2;
        let a = (-dt / tau).exp();
        let s = sigma * (1.0 - a * a).sqrt();
        for j in &mut self.jitter {
            let z: f64 = rng.sample(StandardNormal);
            *j = a * *j + s * z;
        }
        self.refresh_offsets();
    }

    /// Draw the jitter from its stationary distribution (start of a run).
    pub fn randomize_jitter<R: Rng>(&mut self, rng: &mut R) {
        let sigma = self.slip_jitter * TAU / self.n as f64 / std::f64::consts::SQRT_2;
        for j in &mut self.jitter {
            let z: f64 = rng.sample(StandardNormal);
            *j = sigma * z;
        }
        self.refresh_offsets();
    }

    /// Ball j's position phasor: its nominal place on the cage (`spacing[j]`) turned by its
    /// jitter. The jitter is a small angle (a fraction of the ball spacing), whose sine and
    /// cosine a short series gives to double precision; a large one takes `sin_cos`.
    fn refresh_offsets(&mut self) {
        for ((o, &jit), &(bc, bs)) in self.offsets.iter_mut().zip(&self.jitter).zip(&self.spacing) {
            let (s, c) = small_sin_cos(jit);
            *o = (bc * c - bs * s, bs * c + bc * s);
        }
    }

    /// Normal contact law: elastic force and damping coefficient at approach `delta` > 0.
    #[inline]
    fn law(&self, delta: f64) -> (f64, f64) {
        let fe = if self.expo == 1.5 {
            self.k * delta * delta.sqrt()
        } else {
            self.k * delta.powf(self.expo)
        };
        let lam = delta / self.d_pen;
        let c = if lam >= 1.0 {
            self.c_max
        } else {
            self.c_max * lam * lam * (3.0 - 2.0 * lam)
        };
        (fe, c)
    }

    /// Contact forces for relative journal displacement `e` and velocity `ev` (journal minus
    /// housing; vertical, horizontal), cage phasor `cage`, inner-race defect phasor `ir`
    /// (shaft angle + defect position) and ball-spin phasor `spin` of ball 0. `inv_dt`
    /// converts drop changes into rates.
    #[inline]
    pub fn forces(
        &mut self,
        e: [f64; 2],
        ev: [f64; 2],
        cage: (f64, f64),
        ir: (f64, f64),
        spin: (f64, f64),
        inv_dt: f64,
    ) -> ContactForces {
        let mut out = ContactForces::default();
        let (cc, cs) = cage;
        let any_defect = self.defects.outer_race || self.defects.inner_race || self.defects.ball;
        let base = self.delta_pre - self.gap;
        for j in 0..self.n {
            let (oc, os) = self.offsets[j];
            // ball angle phasor = cage x offset
            let c = cc * oc - cs * os;
            let s = cs * oc + cc * os;
            let (uy, uz) = (-c, s);
            let mut drop = 0.0;
            if any_defect {
                if self.defects.outer_race {
                    let (pc, ps) = self.or_pos;
                    let cr = c * pc + s * ps;
                    if cr > 0.9 {
                        let sr = s * pc - c * ps;
                        drop += self.outer_slot.drop_at_phasor(sr, cr);
                    }
                }
                if self.defects.inner_race {
                    let (pc, ps) = ir;
                    let cr = c * pc + s * ps;
                    if cr > 0.9 {
                        let sr = s * pc - c * ps;
                        drop += self.inner_slot.drop_at_phasor(sr, cr);
                    }
                }
                if self.defects.ball && j == 0 {
                    // spin phasor: 0 = defect facing the outer race, pi = inner race
                    let (pc, ps) = spin;
                    if pc > 0.9 {
                        drop += self.ball_slot_outer.drop_at_phasor(ps, pc);
                    } else if pc < -0.9 {
                        drop += self.ball_slot_inner.drop_at_phasor(-ps, -pc);
                    }
                }
            }
            let ddrop = (drop - self.drop_prev[j]) * inv_dt;
            self.drop_prev[j] = drop;
            let radial = e[0] * uy + e[1] * uz;
            let delta = base + radial * self.cos_a - drop;
            if delta <= 0.0 {
                continue;
            }
            let (fe, cd) = self.law(delta);
            let rate = (ev[0] * uy + ev[1] * uz) * self.cos_a - ddrop;
            if fe + cd * rate <= 0.0 {
                continue; // separating faster than the contact can pull: no force
            }
            out.loaded += 1;
            let fr = fe * self.cos_a;
            out.elastic[0] -= fr * uy;
            out.elastic[1] -= fr * uz;
            let cr = cd * self.cos_a * self.cos_a;
            out.c[0] += cr * uy * uy;
            out.c[1] += cr * uy * uz;
            out.c[2] += cr * uz * uz;
            let bd = cd * self.cos_a * ddrop;
            out.b[0] += bd * uy;
            out.b[1] += bd * uz;
            out.axial += (fe + cd * rate) * self.sin_a;
        }
        out.axial -= self.preload_n;
        out
    }

    /// Static radial force on the shaft (vertical, horizontal) at displacement `e`, balls at
    /// nominal positions, no defects (for the static equilibrium and linearisation).
    pub fn static_force(&self, e: [f64; 2]) -> [f64; 2] {
        let mut f = [0.0; 2];
        let n = self.n as f64;
        for j in 0..self.n {
            let (s, c) = (TAU * j as f64 / n).sin_cos();
            let (uy, uz) = (-c, s);
            let delta = self.delta_pre - self.gap + (e[0] * uy + e[1] * uz) * self.cos_a;
            if delta > 0.0 {
                let fr = self.k * delta.powf(self.expo) * self.cos_a;
                f[0] -= fr * uy;
                f[1] -= fr * uz;
            }
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_small_angle_series_matches_sin_cos() {
        for k in -2000..=2000 {
            let x = k as f64 * 1e-4;
            let (s, c) = small_sin_cos(x);
            let (s0, c0) = x.sin_cos();
            assert!(
                (s - s0).abs() <= 2.0 * f64::EPSILON * s0.abs().max(1e-300),
                "sin {x}: {s} vs {s0}"
            );
            assert!((c - c0).abs() <= 2.0 * f64::EPSILON, "cos {x}: {c} vs {c0}");
        }
    }
}
