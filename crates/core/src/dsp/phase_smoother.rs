//! The shaft's phase over the tracker's history smoothed by a Kalman filter and a
//! Rauch-Tung-Striebel smoother (issue 34): the state is the shaft angle's departure from the
//! reference speed (cycles) and the speed's departure (Hz), the speed wandering as a random
//! walk. How fast it may wander (the walk's intensity) is not a setting, and neither is the
//! phases' noise level: every intensity of a grid is weighed by the likelihood of the blocks'
//! phases themselves (the noise level, which a block's SNR only estimates, fitted for each),
//! with a steady speed (no walk) holding half the prior and the wandering intensities the other
//! half, uniform on the grid's log scale. The law read is the average of every intensity's
//! law by its posterior weight (Bayesian model averaging): a steady shaft is read as one
//! straight phase line, a fluctuating one gets the freedom its phases show, and a stretch of
//! noise that a walk happens to fit a little better does not swing the reading. Each speed
//! is read from the phases on both sides of it (the smoother), the newest from the newest
//! blocks and the walk's continuity.

/// Relative walk intensities tried (per square-root second, times the reference speed, for
/// the noise level the blocks' SNR gives): from a speed steady to a part in 10^4 over a second
/// to one wandering by a third; 0 is the steady speed.
const WALK_GRID: [f64; 14] = [
    0.0, 1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3,
];
/// Prior probability of a steady speed; the wandering intensities share the rest equally
/// (even odds between the two explanations: no preference stated by the data's absence).
const STEADY_PRIOR: f64 = 0.5;
/// Prior spread of the first phase (cycles) and speed departure (Hz): no prior.
const DIFFUSE: f64 = 1e4;

/// The smoothed departures at the blocks' centres.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed {
    /// Speed departure from the reference at each block centre, Hz: every intensity's law
    /// averaged by its posterior weight.
    pub hz: Vec<f64>,
    /// Phase departure at each block centre, cycles (averaged the same way).
    pub cycles: Vec<f64>,
    /// Posterior probability that the speed wanders (1 less that of a steady speed).
    pub wander: f64,
    /// Speed departure at each block centre under the wandering intensities alone (their
    /// laws averaged by their posterior weights), Hz.
    pub wander_hz: Vec<f64>,
}

/// Smooth the phases `y` (cycles, unwrapped) with variances `var` (cycles^2; their level is
/// fitted, their ratios kept) at block centres `t` (s, equally spaced), reference speed `hz`.
/// None with fewer than three blocks.
pub fn smooth(t: &[f64], y: &[f64], var: &[f64], hz: f64) -> Option<Smoothed> {
    let n = t.len();
    if n < 3 || y.len() != n || var.len() != n {
        return None;
    }
    let dt = t[1] - t[0];
    let level = var.iter().sum::<f64>() / n as f64;
    if !(level > 0.0 && level.is_finite()) {
        return None;
    }
    let rel: Vec<f64> = var.iter().map(|v| v / level).collect();
    let laws: Vec<Law> = WALK_GRID
        .iter()
        .map(|&rho| {
            let pass = filter(y, &rel, dt, (rho * hz).powi(2) / level);
            let (cycles, hz) = rts(&pass, dt);
            Law {
                loglik: pass.loglik,
                cycles,
                hz,
            }
        })
        .collect();
    let top = laws
        .iter()
        .map(|l| l.loglik)
        .fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return None;
    }
    let walks = (WALK_GRID.len() - 1) as f64;
    let weights: Vec<f64> = laws
        .iter()
        .zip(WALK_GRID)
        .map(|(l, rho)| {
            let prior = if rho == 0.0 {
                STEADY_PRIOR
            } else {
                (1.0 - STEADY_PRIOR) / walks
            };
            prior * (l.loglik - top).exp()
        })
        .collect();
    let total: f64 = weights.iter().sum();
    let wander_total = total - weights[0];
    // the laws from `from` on averaged by their weights (summing to `sum`)
    let average = |pick: fn(&Law) -> &[f64], from: usize, sum: f64| {
        let mut out = vec![0.0; n];
        for (l, w) in laws.iter().zip(&weights).skip(from) {
            for (o, v) in out.iter_mut().zip(pick(l)) {
                *o += w / sum * v;
            }
        }
        out
    };
    Some(Smoothed {
        hz: average(|l| &l.hz, 0, total),
        cycles: average(|l| &l.cycles, 0, total),
        wander: wander_total / total,
        wander_hz: if wander_total > 0.0 {
            average(|l| &l.hz, 1, wander_total)
        } else {
            laws[0].hz.clone()
        },
    })
}

/// One walk intensity's reading: its log-likelihood and smoothed departures.
struct Law {
    loglik: f64,
    cycles: Vec<f64>,
    hz: Vec<f64>,
}

/// One forward pass with the phases' variances `rel` known up to a common level: filtered and
/// predicted states and covariances (for level 1), and the log-likelihood of the innovations
/// after the first two (which only fix the diffuse start) at the level that maximises it.
struct Pass {
    xf: Vec<[f64; 2]>,
    pf: Vec<[[f64; 2]; 2]>,
    xp: Vec<[f64; 2]>,
    pp: Vec<[[f64; 2]; 2]>,
    loglik: f64,
}

fn filter(y: &[f64], rel: &[f64], dt: f64, q: f64) -> Pass {
    let n = y.len();
    let mut pass = Pass {
        xf: Vec::with_capacity(n),
        pf: Vec::with_capacity(n),
        xp: Vec::with_capacity(n),
        pp: Vec::with_capacity(n),
        loglik: 0.0,
    };
    let mut x = [y[0], 0.0];
    let mut p = [[DIFFUSE, 0.0], [0.0, DIFFUSE]];
    let (mut scaled, mut log_s, mut m) = (0.0, 0.0, 0.0f64);
    for (i, (&yi, &r)) in y.iter().zip(rel).enumerate() {
        if i > 0 {
            (x, p) = predict(x, p, dt, q);
        }
        pass.xp.push(x);
        pass.pp.push(p);
        let s = p[0][0] + r;
        let innov = yi - x[0];
        let k = [p[0][0] / s, p[1][0] / s];
        x = [x[0] + k[0] * innov, x[1] + k[1] * innov];
        p = [
            [p[0][0] - k[0] * p[0][0], p[0][1] - k[0] * p[0][1]],
            [p[1][0] - k[1] * p[0][0], p[1][1] - k[1] * p[0][1]],
        ];
        if i >= 2 {
            scaled += innov * innov / s;
            log_s += s.ln();
            m += 1.0;
        }
        pass.xf.push(x);
        pass.pf.push(p);
    }
    // the level that maximises the likelihood is the innovations' mean scaled square
    let level = (scaled / m.max(1.0)).max(1e-300);
    pass.loglik = -0.5 * (m * level.ln() + log_s + m);
    pass
}

/// The state a block later: the phase advances by the speed departure, the speed walks.
fn predict(x: [f64; 2], p: [[f64; 2]; 2], dt: f64, q: f64) -> ([f64; 2], [[f64; 2]; 2]) {
    let x = [x[0] + dt * x[1], x[1]];
    // F P F' + Q for F = [[1, dt], [0, 1]], Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]
    let a = p[0][0] + dt * (p[1][0] + p[0][1]) + dt * dt * p[1][1];
    let b = p[0][1] + dt * p[1][1];
    let c = p[1][0] + dt * p[1][1];
    let p = [
        [a + q * dt.powi(3) / 3.0, b + q * dt * dt / 2.0],
        [c + q * dt * dt / 2.0, p[1][1] + q * dt],
    ];
    (x, p)
}

/// Rauch-Tung-Striebel: every block's state from all the blocks.
fn rts(pass: &Pass, dt: f64) -> (Vec<f64>, Vec<f64>) {
    let n = pass.xf.len();
    let mut xs = pass.xf.clone();
    for i in (0..n - 1).rev() {
        let pf = pass.pf[i];
        // C = Pf F' Pp^-1
        let fpt = [
            [pf[0][0] + dt * pf[0][1], pf[0][1]],
            [pf[1][0] + dt * pf[1][1], pf[1][1]],
        ];
        let pp = pass.pp[i + 1];
        let det = pp[0][0] * pp[1][1] - pp[0][1] * pp[1][0];
        if det.abs() < 1e-300 {
            continue;
        }
        let inv = [
            [pp[1][1] / det, -pp[0][1] / det],
            [-pp[1][0] / det, pp[0][0] / det],
        ];
        let c = [
            [
                fpt[0][0] * inv[0][0] + fpt[0][1] * inv[1][0],
                fpt[0][0] * inv[0][1] + fpt[0][1] * inv[1][1],
            ],
            [
                fpt[1][0] * inv[0][0] + fpt[1][1] * inv[1][0],
                fpt[1][0] * inv[0][1] + fpt[1][1] * inv[1][1],
            ],
        ];
        let d = [
            xs[i + 1][0] - pass.xp[i + 1][0],
            xs[i + 1][1] - pass.xp[i + 1][1],
        ];
        xs[i] = [
            pass.xf[i][0] + c[0][0] * d[0] + c[0][1] * d[1],
            pass.xf[i][1] + c[1][0] * d[0] + c[1][1] * d[1],
        ];
    }
    xs.iter().map(|x| (x[0], x[1])).unzip()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// Phases of a speed departure `dev(t)` (Hz) sampled at 0.2 s blocks over 4 s, with
    /// Gaussian scatter of `sd` cycles (a fixed generator, so the test is repeatable).
    fn phases(dev: impl Fn(f64) -> f64, sd: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let t: Vec<f64> = (0..20).map(|b| -3.9 + 0.2 * b as f64).collect();
        // the phase is the departure integrated from the first block
        let mut cyc = 0.0;
        let y = t
            .iter()
            .enumerate()
            .map(|(i, &ti)| {
                if i > 0 {
                    cyc += 0.2 * dev(ti - 0.1);
                }
                let g = (-2.0 * uniform().ln()).sqrt() * (TAU * uniform()).cos();
                cyc + sd * g
            })
            .collect();
        (t, y)
    }

    #[test]
    fn a_steady_speed_is_read_as_one_straight_phase_line() {
        // 0.05 Hz above the reference, phases scattering 0.08 cycles (0.5 rad) per block
        let (t, y) = phases(|_| 0.05, 0.08, 7);
        let s = smooth(&t, &y, &[0.08 * 0.08; 20], 9.8).unwrap();
        assert!(s.wander < 0.5, "a steady speed needs no walk: {}", s.wander);
        let spread = s.hz.iter().fold(0.0f64, |m, v| m.max((v - s.hz[0]).abs()));
        assert!(
            spread < 0.01,
            "one speed over the history: spread {spread} Hz"
        );
        assert!((s.hz[0] - 0.05).abs() < 0.02, "speed departure {}", s.hz[0]);
    }

    #[test]
    fn a_fluctuating_speed_is_followed_closer_than_a_steady_reading() {
        // +-2 % of 9.8 Hz at 0.3 Hz: the departure the smoother must follow
        let dev = |t: f64| 0.196 * (TAU * 0.3 * t).sin();
        let (mut err_smooth, mut err_steady) = (0.0, 0.0);
        for seed in 1..=10 {
            let (t, y) = phases(dev, 0.04, seed);
            let s = smooth(&t, &y, &[0.04 * 0.04; 20], 9.8).unwrap();
            assert!(
                s.wander > 0.5,
                "seed {seed}: the phases show the speed wander ({})",
                s.wander
            );
            // the newest second's mean speed: smoothed phases at its ends against the truth
            let i = t.len() - 6;
            let read = (s.cycles[t.len() - 1] - s.cycles[i]) / (t[t.len() - 1] - t[i]);
            let truth = (0..100)
                .map(|j| dev(t[i] + (t[t.len() - 1] - t[i]) * (j as f64 + 0.5) / 100.0))
                .sum::<f64>()
                / 100.0;
            err_smooth += (read - truth).abs();
            let mean = (y[y.len() - 1] - y[0]) / (t[t.len() - 1] - t[0]);
            err_steady += (mean - truth).abs();
        }
        assert!(
            err_smooth < 0.5 * err_steady,
            "smoothed {err_smooth:.3} Hz against steady {err_steady:.3} Hz over 10 seeds"
        );
    }

    #[test]
    fn too_few_blocks_are_no_reading() {
        assert!(smooth(&[0.0, 0.2], &[0.0, 0.0], &[1.0, 1.0], 10.0).is_none());
    }
}
