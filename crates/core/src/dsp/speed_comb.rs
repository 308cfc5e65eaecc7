//! A comb of lines that is a bearing's impact train, not a shaft: the joint reading of the
//! shaft lines and the bearing's families for the streaming tracker ([`super::speed_tracker`]).
//!
//! An outer race at 588 rpm (BPFO 4.59 orders) puts a comb at 45, 90, 135 Hz into the
//! spectrum; read as a shaft series it is 1350 or 1800 rpm (or 2700). The same comb is
//! explained by a shaft at 9.8 Hz whose BPFO train it is. Of the two, the speed that explains
//! more is taken: a candidate c = m g / order (g the shaft lines' choice, m = 1-3, the order
//! of BPFO within the bearing's slip: [`train_orders`]) replaces g when
//! - c shows a shaft line of its own ([`own_lines`]: its harmonics off g's series; the
//!   tracker checks their clarity), or c is the line the tracker followed in the last
//!   windows (continuity: found there over a longer history, while the span searched now,
//!   a second while acquiring, is too short to resolve a weak 1x),
//! - the envelope shows c's train ([`train_support`], as strong as a fault family must be:
//!   [`FAMILY_PRESENT`]) with its fundamental where the comb's lines are, and
//! - the lines of g's series that c explains neither as its own harmonics nor as its train
//!   stay at noise ([`unexplained`]).
//!
//! A healthy machine shows no train in the envelope, so nothing changes there; a true shaft
//! comb has no line at g m / order below it.
//!
//! **A comb without its first line** ([`bare_comb`], issue 34 on the project's simulator):
//! where the slow shaft shows no line of its own at all (the simulator's outer race at 588
//! rpm: neither the raw spectrum nor the envelope has a line at 9.8 Hz or its harmonics,
//! 0.9x the median over the whole 8 s), the first condition cannot hold, and the comb's
//! reading as a 45 Hz shaft stood. A shaft at g shows its 1x: the line of a rotor's
//! unbalance, its strongest or near it in an accelerometer at that speed (CWRU's 6205 at
//! 1797 rpm: 10-110x the local median in every drive-end record). An impact train seen
//! below the structure's first mode is a comb whose lines rise with frequency (the
//! acceleration of a stiffness-controlled structure to a flat force comb grows as f^2), so
//! its fundamental may be lost in the floor while its harmonics stand (the simulator's
//! 45 Hz 1.3x the local median, 90 Hz 12.7x). When g's own fundamental is no line
//! ([`BARE_FUNDAMENTAL`]), the envelope shows c's train and nothing of g's series is left
//! unexplained, the comb is read as the train of c = m g / order exactly (the kinematic
//! order: no own line to place c within the slip; a real bearing's slip of 1-2 % then is
//! the speed's error).
//!
//! A candidate's own lines must be its own: the train's lines sit on g's series by
//! construction (order c = m g), and a harmonic of c may fall on g's line too (2xBSF = 4.71
//! orders, and a harmonic 5c lies within the slip of g: CWRU's 6205 at 1797 rpm, a healthy
//! shaft at 29.95 Hz, was read as a shaft at 6.0 Hz whose 5th harmonic was g's 1x and whose
//! "train" in the envelope was g's own 1x modulation). So c's evidence counts only the
//! lines g does not already explain.

use super::fault_family::{FAMILY_PRESENT, SLIP};
use super::harmonic_sum::{on_mains_harmonic, Whitened, HARMONICS, LONE_ALLOW};
use crate::bearing::FaultOrders;

/// Harmonics of a train scored in the envelope.
const TRAIN_HARMONICS: usize = 3;
/// Prominence the train's fundamental needs in the envelope (a noise bin's best over the
/// slip search reads about 1.3: [`super::fault_family`]).
const TRAIN_FUNDAMENTAL: f64 = 1.5;
/// Multiples of g a train's fundamental may sit on (the comb's own fundamental may be read
/// as the shaft's 1x, 2x or 3x).
const COMB_MULTIPLES: [f64; 3] = [1.0, 2.0, 3.0];

/// Orders of the trains read as a comb: BPFO only. An outer race under a fixed load is an
/// unmodulated train, a bare comb the shaft lines can mistake for a series. A BPFI or 2xBSF
/// train is modulated (1x, the cage's FTF): its lines come with sidebands c apart, which the
/// harmonic sum reads at c itself, and its family in the envelope settles the speed through
/// [`super::fault_family`]. As a comb, a train of c at one of these orders sits on a faster
/// shaft's own series by construction (order c = m g), and the envelope of a real machine
/// carries that shaft's 1x and its cage lines: CWRU's 6205 at 1797 rpm (shaft 29.95 Hz) was
/// read as a 6.2 Hz shaft whose 2xBSF train was the 1x (inner race 209_0) and as a 5.6 Hz
/// shaft whose BPFI train it was, the 1x sidebands falling on the cage's 2nd and 3rd
/// harmonics (outer race 130@6_0), for most of those records.
pub fn train_orders(o: &FaultOrders) -> [f64; 1] {
    [o.bpfo]
}

/// The prominence below which the comb's first line is no line ([`bare_comb`]): the
/// tracker's noise level for a harmonic series (`SCORE_NOISE`: the best of many candidates
/// on noise reads about 0.5).
pub const BARE_FUNDAMENTAL: f64 = 1.0;

/// g's comb has no line at its own fundamental (a shaft at g would show its 1x): the
/// prominence at g in the shaft spectrum `w` is under [`BARE_FUNDAMENTAL`], off the mains
/// lines, while g's series stands (`w.shaft(g)` above it).
pub fn bare_comb(w: &Whitened, g: f64) -> bool {
    !w.on_mains(g) && w.at(g) < BARE_FUNDAMENTAL && w.shaft(g) > BARE_FUNDAMENTAL
}

/// The speeds (Hz, with the train's order) whose train at its kinematic order puts its
/// fundamental on g's comb at g's 1x, 2x or 3x, inside [lo, hi].
pub fn comb_speeds(g: f64, o: &FaultOrders, lo: f64, hi: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for order in train_orders(o) {
        for m in COMB_MULTIPLES {
            let c = m * g / order;
            if (lo..=hi).contains(&c) {
                out.push((c, order));
            }
        }
    }
    out
}

/// The speeds (Hz, with the train's order) whose train would put its fundamental on g's
/// comb, the order scaled by the slip around it: each as (low, high, order), clipped to
/// [lo, hi]; empty spans are left out.
pub fn comb_spans(g: f64, o: &FaultOrders, lo: f64, hi: f64) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for order in train_orders(o) {
        for m in COMB_MULTIPLES {
            let c = m * g / order;
            let (a, b) = ((c * (1.0 - SLIP)).max(lo), (c * (1.0 + SLIP)).min(hi));
            if a < b {
                out.push((a, b, order));
            }
        }
    }
    out
}

/// The train of `order` at shaft speed `c` in the whitened envelope `env` (valid to `top`
/// Hz): the best over the slip of its harmonics' summed prominence over sqrt of their number,
/// where the fundamental stands [`TRAIN_FUNDAMENTAL`] out and leads its harmonics (an impact
/// train's envelope falls off with harmonic number); -inf when it never does.
pub fn train_support(env: &Whitened, order: f64, c: f64, top: f64) -> f64 {
    let mut best = f64::NEG_INFINITY;
    let f1 = order * c;
    if f1 * (1.0 + SLIP) * TRAIN_HARMONICS as f64 > top || f1 < 4.0 * env.df {
        return best;
    }
    let step = (env.df / (4.0 * f1 * TRAIN_HARMONICS as f64)).max(1e-5);
    let mut s = 1.0 - SLIP;
    while s <= 1.0 + SLIP {
        let p1 = env.at(f1 * s);
        if p1 >= TRAIN_FUNDAMENTAL && !on_mains_harmonic(f1 * s, 1.5 * env.df) {
            let lines = (1..=TRAIN_HARMONICS).map(|h| env.at(h as f64 * f1 * s));
            if lines.clone().all(|p| p1 >= p - std::f64::consts::LN_2) {
                best = best.max(lines.sum::<f64>() / (TRAIN_HARMONICS as f64).sqrt());
            }
        }
        s += step;
    }
    best
}

/// The train is present ([`FAMILY_PRESENT`]).
pub fn train_present(env: &Whitened, order: f64, c: f64, top: f64) -> bool {
    train_support(env, order, c, top) >= FAMILY_PRESENT
}

/// The evidence in the shaft spectrum `w` for a shaft at `c` from its own lines, the ones
/// g's series does not explain: the mean prominence of c's harmonics 1-[`HARMONICS`] off g's
/// series and off the mains lines, or (with `w.lone`) its fundamental alone less
/// [`LONE_ALLOW`] when that is more; -inf when every harmonic of c sits on g's series.
pub fn own_lines(w: &Whitened, c: f64, g: f64) -> f64 {
    let on_g = |f: f64| {
        let k = (f / g).round();
        k >= 1.0 && (f - k * g).abs() <= 0.005 * f + w.df
    };
    let (mut sum, mut n) = (0.0, 0);
    for k in 1..=HARMONICS {
        let f = k as f64 * c;
        if on_g(f) || on_mains_harmonic(f, 1.5 * w.df) {
            continue;
        }
        sum += w.at(f);
        n += 1;
    }
    if n == 0 {
        return f64::NEG_INFINITY;
    }
    let mean = sum / n as f64;
    if w.lone && !on_g(c) && !w.on_mains(c) {
        mean.max(w.at(c) - LONE_ALLOW)
    } else {
        mean
    }
}

/// The speed in [`lo`, `hi`] Hz whose own lines ([`own_lines`] against `g`) stand out most,
/// on the harmonic-sum search grid: (Hz, evidence).
pub fn best_own(w: &Whitened, g: f64, lo: f64, hi: f64) -> (f64, f64) {
    let step = w.df / (2 * HARMONICS) as f64;
    let mut best = (lo, f64::NEG_INFINITY);
    let mut f = lo;
    while f <= hi {
        let s = own_lines(w, f, g);
        if s > best.1 {
            best = (f, s);
        }
        f += step;
    }
    best
}

/// Mean prominence, in the shaft spectrum `w`, of the harmonics of `g` (1-[`HARMONICS`], off
/// the mains lines) that speed `c` explains neither as its own harmonics nor as harmonics of
/// its train of `order` (within the slip); None when c explains them all.
pub fn unexplained(w: &Whitened, g: f64, c: f64, order: f64) -> Option<f64> {
    let near = |f: f64, base: f64, tol: f64| {
        let k = (f / base).round();
        k >= 1.0 && (f - k * base).abs() <= tol
    };
    let (mut sum, mut n) = (0.0, 0);
    for k in 1..=HARMONICS {
        let f = k as f64 * g;
        if on_mains_harmonic(f, 1.5 * w.df)
            || near(f, c, 0.005 * f + w.df)
            || near(f, order * c, SLIP * f + w.df)
        {
            continue;
        }
        sum += w.at(f);
        n += 1;
    }
    (n > 0).then(|| sum / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bearing::BearingGeometry;

    fn lut() -> FaultOrders {
        BearingGeometry {
            balls: 11,
            ball_diameter_mm: 7.94,
            pitch_diameter_mm: 48.0,
            contact_angle_deg: 0.0,
        }
        .fault_orders()
    }

    fn spectrum(lines: &[f64], p: f64) -> Whitened {
        let df = 0.1;
        let mut w = Whitened {
            df,
            prom: vec![0.0; 4000],
            interpolate: true,
            ..Whitened::default()
        };
        for &f in lines {
            let i = (f / df).round() as usize;
            w.prom[i] = p;
        }
        w
    }

    /// A BPFO comb at 588 rpm is that speed's train; 9.8 Hz is among the comb's speeds, and
    /// 22.5 Hz (half the comb) leaves nothing unexplained by it.
    #[test]
    fn an_outer_race_comb_is_the_train_of_the_slow_shaft() {
        let o = lut();
        let c = 9.8;
        let comb: Vec<f64> = (1..=4).map(|h| h as f64 * o.bpfo * c).collect();
        let env = spectrum(&comb, 3.0);
        assert!(train_present(&env, o.bpfo, c, 300.0));
        assert!(!train_present(&env, o.bpfi, c, 300.0));
        let g = o.bpfo * c / 2.0;
        // a comb is read as a BPFO train only
        assert!(comb_spans(g, &o, 5.0, 60.0)
            .iter()
            .all(|&(_, _, order)| order == o.bpfo));
        assert!(comb_spans(g, &o, 5.0, 60.0)
            .iter()
            .any(|&(a, b, order)| order == o.bpfo && a <= c && c <= b));
        let raw = spectrum(&comb, 3.0);
        let u = unexplained(&raw, g, c, o.bpfo).unwrap();
        assert!(u < 0.5, "{u}");
    }

    /// A shaft at g whose 5th subharmonic c lies where a 2xBSF train would put g's comb has
    /// no evidence of its own at c: c's 5th harmonic is g's own line.
    #[test]
    fn a_subharmonic_borrows_no_evidence_from_the_shaft() {
        let g = 30.0;
        let mut raw = spectrum(&[g, 2.0 * g, 4.0 * g], 6.0);
        raw.lone = true;
        let c = g / 5.0;
        // read as a series, c scores a fifth of g's own line: above the tracker's noise (1.0)
        assert!(raw.shaft(c) > 1.0, "the borrowed series: {}", raw.shaft(c));
        assert!(own_lines(&raw, c, g) < 0.5, "{}", own_lines(&raw, c, g));
        // a real line at c is its own
        raw.prom[(c / raw.df).round() as usize] = 4.0;
        assert!(own_lines(&raw, c, g) > 3.0, "{}", own_lines(&raw, c, g));
    }

    #[test]
    fn no_envelope_lines_no_train() {
        let env = spectrum(&[], 0.0);
        assert!(!train_present(&env, lut().bpfo, 9.8, 300.0));
    }
}
