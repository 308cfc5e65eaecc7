//! Bounded parameter search for one effect: coordinate-wise, each parameter by a coarse grid
//! over its bounds (linear or logarithmic; every value of a discrete choice) and then a
//! golden-section refinement between the grid neighbours of the best point.

use super::catalog::{Param, Range};

/// Grid points per continuous parameter.
pub const GRID: usize = 7;
/// Golden-section iterations after the grid.
pub const GOLDEN: usize = 6;

fn from_u(r: &Range, u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    match *r {
        Range::Linear(a, b) => a + u * (b - a),
        Range::Log(a, b) => (a.ln() + u * (b.ln() - a.ln())).exp(),
        Range::Choice(ref c) => c[0],
    }
}

/// Minimise `f` over the parameters, starting from `start`. Returns the best values, their
/// objective and the number of evaluations.
pub fn minimize(
    params: &[Param],
    start: &[f64],
    f: &mut dyn FnMut(&[f64]) -> f64,
) -> (Vec<f64>, f64, usize) {
    let mut x = start.to_vec();
    let mut evals = 0usize;
    let mut best = f64::INFINITY;
    for (i, p) in params.iter().enumerate() {
        let mut eval = |v: f64, x: &mut Vec<f64>| -> f64 {
            let old = x[i];
            x[i] = v;
            let e = f(x);
            x[i] = old;
            e
        };
        match &p.range {
            Range::Choice(values) => {
                let mut bi = (x[i], f64::INFINITY);
                for &v in values {
                    let e = eval(v, &mut x);
                    evals += 1;
                    if e < bi.1 {
                        bi = (v, e);
                    }
                }
                x[i] = bi.0;
                best = bi.1;
            }
            r => {
                let us: Vec<f64> = (0..GRID).map(|k| k as f64 / (GRID - 1) as f64).collect();
                let es: Vec<f64> = us
                    .iter()
                    .map(|&u| {
                        evals += 1;
                        eval(from_u(r, u), &mut x)
                    })
                    .collect();
                let k = (0..GRID)
                    .min_by(|a, b| es[*a].total_cmp(&es[*b]))
                    .unwrap_or(0);
                let (mut bu, mut be) = (us[k], es[k]);
                let (mut lo, mut hi) = (us[k.saturating_sub(1)], us[(k + 1).min(GRID - 1)]);
                let g = 0.618_033_988_75;
                let mut c = hi - g * (hi - lo);
                let mut d = lo + g * (hi - lo);
                let mut fc = eval(from_u(r, c), &mut x);
                let mut fd = eval(from_u(r, d), &mut x);
                evals += 2;
                for _ in 0..GOLDEN {
                    if fc < fd {
                        hi = d;
                        d = c;
                        fd = fc;
                        c = hi - g * (hi - lo);
                        fc = eval(from_u(r, c), &mut x);
                    } else {
                        lo = c;
                        c = d;
                        fc = fd;
                        d = lo + g * (hi - lo);
                        fd = eval(from_u(r, d), &mut x);
                    }
                    evals += 1;
                }
                for (u, e) in [(c, fc), (d, fd)] {
                    if e < be {
                        bu = u;
                        be = e;
                    }
                }
                x[i] = from_u(r, bu);
                best = be;
            }
        }
    }
    (x, best, evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_bounded_minimum() {
        let params = [
            Param {
                name: "a",
                range: Range::Linear(0.0, 1.0),
            },
            Param {
                name: "b",
                range: Range::Log(0.01, 10.0),
            },
        ];
        let mut f = |x: &[f64]| (x[0] - 0.37).powi(2) + (x[1].ln() - 2f64.ln()).powi(2);
        let (x, e, _) = minimize(&params, &[0.5, 1.0], &mut f);
        assert!((x[0] - 0.37).abs() < 0.02, "{x:?}");
        assert!((x[1] - 2.0).abs() < 0.15, "{x:?}");
        assert!(e < 1e-3);
    }
}
