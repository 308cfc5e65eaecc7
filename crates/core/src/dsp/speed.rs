//! Shaft speed and angle versus time: [`SpeedTrack`]. Built from tacho edge times (with
//! missing/extra pulse repair), from an analog tacho, from a fixed rpm, from a speed profile
//! (the vibration-based estimate); which of these a rig asks for is decided in
//! `analysis::speed_source`. Angle is in revolutions; between pulses time-versus-angle
//! is a monotone cubic (Fritsch-Carlson), so speed is continuous and angle never runs backwards.

use crate::dsp::tacho;
use crate::vocabulary::SpeedSourceKind;
use anyhow::{bail, Context, Result};

/// A repair made to the tacho pulse train.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Repair {
    /// A pulse was missing here and was inserted (time in s).
    Inserted(f64),
    /// A spurious pulse at this time was removed.
    Removed(f64),
}

#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Constant {
        hz: f64,
    },
    /// Knots: time `t[i]` at angle `theta[i]` (rev), and dt/dtheta slopes `m[i]` (s/rev).
    Knots {
        t: Vec<f64>,
        theta: Vec<f64>,
        m: Vec<f64>,
    },
}

/// Shaft angle and speed over time, with the repairs made to build it.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedTrack {
    kind: Kind,
    source: SpeedSourceKind,
    repairs: Vec<Repair>,
}

impl SpeedTrack {
    /// Constant speed, e.g. `SpeedTrack::constant(1797.0, SpeedSourceKind::Recording)`.
    pub fn constant(rpm: f64, source: SpeedSourceKind) -> Result<SpeedTrack> {
        if !(rpm.is_finite() && rpm > 0.0) {
            bail!("speed {rpm} rpm: must be a positive number");
        }
        Ok(SpeedTrack {
            kind: Kind::Constant { hz: rpm / 60.0 },
            source,
            repairs: Vec::new(),
        })
    }

    /// A fixed, known speed (speed source "fixed").
    pub fn fixed(rpm: f64) -> Result<SpeedTrack> {
        Self::constant(rpm, SpeedSourceKind::Fixed)
    }

    /// From tacho edge times (s): missing pulses (an interval about k times the local median)
    /// are inserted, spurious ones (an interval under half the local median) removed; both are
    /// counted. Needs at least three edges.
    pub fn from_edges(
        times_s: &[f64],
        pulses_per_rev: u32,
        source: SpeedSourceKind,
    ) -> Result<SpeedTrack> {
        if pulses_per_rev == 0 {
            bail!("pulses_per_rev must be at least 1");
        }
        if let Some(i) = times_s.iter().position(|t| !t.is_finite()) {
            bail!("tacho edge {i} is not a finite time ({})", times_s[i]);
        }
        if let Some(i) = times_s.windows(2).position(|w| w[1] <= w[0]) {
            bail!(
                "tacho edge times must increase: edge {} at {} s follows {} s",
                i + 1,
                times_s[i + 1],
                times_s[i]
            );
        }
        if times_s.len() < 3 {
            bail!(
                "only {} tacho pulse(s) found; at least 3 are needed to measure speed (check the tacho threshold/hysteresis and that the shaft turns)",
                times_s.len()
            );
        }
        let (edges, repairs) = repair_pulses(times_s);
        let step = 1.0 / pulses_per_rev as f64;
        let theta: Vec<f64> = (0..edges.len()).map(|i| i as f64 * step).collect();
        Ok(Self::from_knots(edges, theta, source, repairs))
    }

    /// From an analog tacho channel (speed source "tacho").
    pub fn from_analog(
        samples: &[f32],
        sample_rate: f64,
        threshold: f64,
        hysteresis: f64,
        pulses_per_rev: u32,
    ) -> Result<SpeedTrack> {
        let edges = tacho::detect_edges(samples, sample_rate, threshold, hysteresis);
        Self::from_edges(&edges, pulses_per_rev, SpeedSourceKind::Tacho).with_context(|| {
            format!("analog tacho (threshold {threshold}, hysteresis {hysteresis})")
        })
    }

    /// From a speed profile: shaft frequency `hz[i]` at time `t[i]` (increasing times);
    /// angle is the trapezoidal integral, speed is held constant outside the profile.
    pub fn from_profile(t: &[f64], hz: &[f64], source: SpeedSourceKind) -> Result<SpeedTrack> {
        if t.len() != hz.len() || t.is_empty() {
            bail!("speed profile: need as many speeds as times, at least one");
        }
        if hz.iter().any(|f| !(f.is_finite() && *f > 0.0)) || t.windows(2).any(|w| w[1] <= w[0]) {
            bail!("speed profile: times must increase and speeds be positive");
        }
        if t.len() == 1 {
            return Self::constant(hz[0] * 60.0, source);
        }
        let mut theta = vec![0.0; t.len()];
        for i in 1..t.len() {
            theta[i] = theta[i - 1] + 0.5 * (hz[i] + hz[i - 1]) * (t[i] - t[i - 1]);
        }
        Ok(Self::from_knots(t.to_vec(), theta, source, Vec::new()))
    }

    fn from_knots(
        t: Vec<f64>,
        theta: Vec<f64>,
        source: SpeedSourceKind,
        repairs: Vec<Repair>,
    ) -> SpeedTrack {
        let m = monotone_slopes(&theta, &t);
        SpeedTrack {
            kind: Kind::Knots { t, theta, m },
            source,
            repairs,
        }
    }

    /// Where the speed came from.
    pub fn source(&self) -> SpeedSourceKind {
        self.source
    }

    /// Repairs made to the pulse train (empty for other sources).
    pub fn repairs(&self) -> &[Repair] {
        &self.repairs
    }

    /// (missing pulses inserted, extra pulses removed) with times in `[t0, t1)`.
    pub fn repairs_between(&self, t0: f64, t1: f64) -> (u32, u32) {
        let (mut ins, mut rem) = (0, 0);
        for r in &self.repairs {
            match *r {
                Repair::Inserted(t) if t >= t0 && t < t1 => ins += 1,
                Repair::Removed(t) if t >= t0 && t < t1 => rem += 1,
                _ => {}
            }
        }
        (ins, rem)
    }

    /// Time span covered by measured pulses (None for constant speed).
    pub fn span(&self) -> Option<(f64, f64)> {
        match &self.kind {
            Kind::Constant { .. } => None,
            Kind::Knots { t, .. } => Some((t[0], t[t.len() - 1])),
        }
    }

    /// True when `[t0, t1]` reaches more than 1.5 pulse intervals beyond the measured pulses.
    pub fn extrapolates(&self, t0: f64, t1: f64) -> bool {
        match &self.kind {
            Kind::Constant { .. } => false,
            Kind::Knots { t, .. } => {
                let n = t.len();
                t0 < t[0] - 1.5 * (t[1] - t[0]) || t1 > t[n - 1] + 1.5 * (t[n - 1] - t[n - 2])
            }
        }
    }

    /// Time (s) at shaft angle `theta` (revolutions, 0 at the first pulse or at t = 0).
    pub fn time_at(&self, theta: f64) -> f64 {
        match &self.kind {
            Kind::Constant { hz } => theta / hz,
            Kind::Knots { t, theta: th, m } => {
                let i = segment(th, theta);
                hermite(th, t, m, i, theta)
            }
        }
    }

    /// Shaft angle (revolutions) at time `t_s`.
    pub fn angle_at(&self, t_s: f64) -> f64 {
        match &self.kind {
            Kind::Constant { hz } => t_s * hz,
            Kind::Knots { t, theta, m } => {
                let i = segment(t, t_s);
                let n = t.len();
                if t_s <= t[0] {
                    return theta[0] + (t_s - t[0]) / m[0];
                }
                if t_s >= t[n - 1] {
                    return theta[n - 1] + (t_s - t[n - 1]) / m[n - 1];
                }
                // invert the monotone cubic t(theta) on segment i by bisection
                let (mut a, mut b) = (theta[i], theta[i + 1]);
                for _ in 0..60 {
                    let mid = 0.5 * (a + b);
                    if hermite(theta, t, m, i, mid) < t_s {
                        a = mid;
                    } else {
                        b = mid;
                    }
                }
                0.5 * (a + b)
            }
        }
    }

    /// Speed (rpm) at time `t_s`.
    pub fn rpm_at(&self, t_s: f64) -> f64 {
        match &self.kind {
            Kind::Constant { hz } => hz * 60.0,
            Kind::Knots { t, theta, m } => {
                let th = self.angle_at(t_s);
                let i = segment(theta, th);
                60.0 / hermite_slope(theta, t, m, i, th)
            }
        }
    }

    /// Mean speed (rpm) over `[t0, t1]`.
    pub fn mean_rpm(&self, t0: f64, t1: f64) -> f64 {
        60.0 * (self.angle_at(t1) - self.angle_at(t0)) / (t1 - t0)
    }

    /// Lowest and highest shaft frequency (Hz) over `[t0, t1]` (per pulse interval).
    pub fn speed_range_hz(&self, t0: f64, t1: f64) -> (f64, f64) {
        match &self.kind {
            Kind::Constant { hz } => (*hz, *hz),
            Kind::Knots { t, theta, m } => {
                let (th0, th1) = (self.angle_at(t0), self.angle_at(t1));
                let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
                let mut upd = |f: f64| {
                    lo = lo.min(f);
                    hi = hi.max(f);
                };
                upd(1.0 / hermite_slope(theta, t, m, segment(theta, th0), th0));
                upd(1.0 / hermite_slope(theta, t, m, segment(theta, th1), th1));
                let start = segment(theta, th0);
                let end = segment(theta, th1);
                for i in start..=end.min(theta.len() - 2) {
                    upd((theta[i + 1] - theta[i]) / (t[i + 1] - t[i]));
                    upd(1.0 / m[i]);
                }
                upd(1.0 / m[(end + 1).min(m.len() - 1)]);
                (lo, hi)
            }
        }
    }

    /// Times (s) at the angles `theta0 + j * dtheta`, j = 0..out.len() (hot path of order
    /// tracking: walks the knots once, no allocation).
    pub fn times_at_angles(&self, theta0: f64, dtheta: f64, out: &mut [f64]) {
        match &self.kind {
            Kind::Constant { hz } => {
                for (j, o) in out.iter_mut().enumerate() {
                    *o = (theta0 + j as f64 * dtheta) / hz;
                }
            }
            Kind::Knots { t, theta, m } => {
                let mut i = segment(theta, theta0);
                let last = theta.len() - 2;
                for (j, o) in out.iter_mut().enumerate() {
                    let th = theta0 + j as f64 * dtheta;
                    while i < last && th > theta[i + 1] {
                        i += 1;
                    }
                    *o = hermite(theta, t, m, i, th);
                }
            }
        }
    }
}

impl SpeedTrack {
    /// Angles (rev) at the times `t0 + j * dt`, j = 0..out.len(): [`Self::angle_at`] for a
    /// whole uniformly sampled signal (synchronous demodulation). Walks the knots once and
    /// inverts each segment's cubic by safeguarded Newton steps from the linear guess,
    /// where `angle_at` bisects 60 times per call; the two agree to ~1e-12 rev.
    pub fn angles_at_times(&self, t0: f64, dt: f64, out: &mut [f64]) {
        let Kind::Knots { t, theta, m } = &self.kind else {
            for (j, o) in out.iter_mut().enumerate() {
                *o = self.angle_at(t0 + j as f64 * dt);
            }
            return;
        };
        let n = t.len();
        let mut i = segment(t, t0);
        for (j, o) in out.iter_mut().enumerate() {
            let ts = t0 + j as f64 * dt;
            if ts <= t[0] || ts >= t[n - 1] {
                *o = self.angle_at(ts);
                continue;
            }
            while i < n - 2 && ts > t[i + 1] {
                i += 1;
            }
            let (mut a, mut b) = (theta[i], theta[i + 1]);
            let mut th = a + (b - a) * (ts - t[i]) / (t[i + 1] - t[i]);
            for _ in 0..60 {
                let f = hermite(theta, t, m, i, th) - ts;
                if f < 0.0 {
                    a = th;
                } else {
                    b = th;
                }
                let slope = hermite_slope(theta, t, m, i, th);
                let next = th - f / slope;
                // a Newton step outside the bracket (or no slope) bisects instead
                let next = if next > a && next < b {
                    next
                } else {
                    0.5 * (a + b)
                };
                let done = (next - th).abs() <= 1e-13 * (1.0 + th.abs());
                th = next;
                if done {
                    break;
                }
            }
            *o = th;
        }
    }
}

/// Index i of the segment [x[i], x[i+1]] holding v (clamped to the end segments).
fn segment(x: &[f64], v: f64) -> usize {
    let n = x.len();
    if n < 2 || v <= x[0] {
        return 0;
    }
    match x.binary_search_by(|p| p.total_cmp(&v)) {
        Ok(i) => i.min(n - 2),
        Err(i) => (i - 1).min(n - 2),
    }
}

/// Cubic Hermite y(x) on segment i; linear extrapolation with the end slopes outside.
fn hermite(x: &[f64], y: &[f64], m: &[f64], i: usize, v: f64) -> f64 {
    let n = x.len();
    if v <= x[0] {
        return y[0] + (v - x[0]) * m[0];
    }
    if v >= x[n - 1] {
        return y[n - 1] + (v - x[n - 1]) * m[n - 1];
    }
    let h = x[i + 1] - x[i];
    let s = (v - x[i]) / h;
    let (s2, s3) = (s * s, s * s * s);
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = s3 - 2.0 * s2 + s;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = s3 - s2;
    h00 * y[i] + h10 * h * m[i] + h01 * y[i + 1] + h11 * h * m[i + 1]
}

/// dy/dx of the Hermite cubic on segment i.
fn hermite_slope(x: &[f64], y: &[f64], m: &[f64], i: usize, v: f64) -> f64 {
    let n = x.len();
    if v <= x[0] {
        return m[0];
    }
    if v >= x[n - 1] {
        return m[n - 1];
    }
    let h = x[i + 1] - x[i];
    let s = (v - x[i]) / h;
    let d00 = (6.0 * s * s - 6.0 * s) / h;
    let d10 = 3.0 * s * s - 4.0 * s + 1.0;
    let d01 = (-6.0 * s * s + 6.0 * s) / h;
    let d11 = 3.0 * s * s - 2.0 * s;
    d00 * y[i] + d10 * m[i] + d01 * y[i + 1] + d11 * m[i + 1]
}

/// Fritsch-Carlson slopes for a monotone cubic through (x, y), both increasing.
fn monotone_slopes(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let d: Vec<f64> = (0..n - 1)
        .map(|i| (y[i + 1] - y[i]) / (x[i + 1] - x[i]))
        .collect();
    let mut m = vec![0.0; n];
    m[0] = d[0];
    m[n - 1] = d[n - 2];
    for i in 1..n - 1 {
        // harmonic mean of neighbouring secants (weighted by interval lengths)
        let (h0, h1) = (x[i] - x[i - 1], x[i + 1] - x[i]);
        let (w1, w2) = (2.0 * h1 + h0, h1 + 2.0 * h0);
        m[i] = (w1 + w2) / (w1 / d[i - 1] + w2 / d[i]);
    }
    m
}

/// Local reference interval: median of the raw intervals within +-4 of `i`.
fn local_median(d: &[f64], i: usize, buf: &mut Vec<f64>) -> f64 {
    let lo = i.saturating_sub(4);
    let hi = (i + 5).min(d.len());
    buf.clear();
    buf.extend_from_slice(&d[lo..hi]);
    buf.sort_unstable_by(|a, b| a.total_cmp(b));
    buf[buf.len() / 2]
}

/// Remove spurious pulses and insert missing ones; returns the cleaned edges and the repairs.
fn repair_pulses(raw: &[f64]) -> (Vec<f64>, Vec<Repair>) {
    let d: Vec<f64> = raw.windows(2).map(|w| w[1] - w[0]).collect();
    let mut buf = Vec::with_capacity(9);
    let mut repairs = Vec::new();
    // 1. spurious pulses: an interval shorter than half the local median
    let mut kept: Vec<f64> = vec![raw[0]];
    for (k, &t) in raw.iter().enumerate().skip(1) {
        let reference = local_median(&d, k - 1, &mut buf);
        let last = *kept.last().unwrap();
        if t - last < 0.5 * reference {
            // keep whichever of (last, t) sits closer to where the pulse was expected
            let expected = if kept.len() >= 2 {
                kept[kept.len() - 2] + reference
            } else {
                last
            };
            if kept.len() >= 2 && (t - expected).abs() < (last - expected).abs() {
                repairs.push(Repair::Removed(last));
                *kept.last_mut().unwrap() = t;
            } else {
                repairs.push(Repair::Removed(t));
            }
        } else {
            kept.push(t);
        }
    }
    // 2. missing pulses: an interval about k >= 2 times the local median
    let dk: Vec<f64> = kept.windows(2).map(|w| w[1] - w[0]).collect();
    let mut out = Vec::with_capacity(kept.len() + 8);
    out.push(kept[0]);
    for (i, &di) in dk.iter().enumerate() {
        let reference = local_median(&dk, i, &mut buf);
        let ratio = di / reference;
        if ratio > 1.5 {
            let k = ratio.round().max(2.0) as usize;
            // place the missing pulses on a cubic t(pulse) that joins the neighbouring
            // intervals smoothly (follows a speed ramp across the gap)
            let even = di / k as f64;
            let ok = |d: f64| (d / reference - 1.0).abs() < 0.5;
            let s0 = if i > 0 && ok(dk[i - 1]) {
                dk[i - 1]
            } else {
                even
            };
            let s1 = if i + 1 < dk.len() && ok(dk[i + 1]) {
                dk[i + 1]
            } else {
                even
            };
            for j in 1..k {
                let s = j as f64 / k as f64;
                let (s2, s3) = (s * s, s * s * s);
                let kk = k as f64;
                let t = (2.0 * s3 - 3.0 * s2 + 1.0) * kept[i]
                    + (s3 - 2.0 * s2 + s) * kk * s0
                    + (-2.0 * s3 + 3.0 * s2) * kept[i + 1]
                    + (s3 - s2) * kk * s1;
                out.push(t);
                repairs.push(Repair::Inserted(t));
            }
        }
        out.push(kept[i + 1]);
    }
    (out, repairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Edge times of a shaft whose speed ramps linearly from f0 to f1 Hz over `dur` s.
    fn ramp_edges(f0: f64, f1: f64, dur: f64) -> Vec<f64> {
        let a = (f1 - f0) / dur;
        // theta(t) = f0 t + a t^2 / 2 = k  ->  t = (-f0 + sqrt(f0^2 + 2 a k)) / a
        (0..)
            .map(|k| {
                if a.abs() < 1e-12 {
                    k as f64 / f0
                } else {
                    (-f0 + (f0 * f0 + 2.0 * a * k as f64).sqrt()) / a
                }
            })
            .take_while(|&t| t <= dur)
            .collect()
    }

    #[test]
    fn ramp_angle_and_speed_follow_the_truth() {
        let (f0, f1, dur) = (8.0, 12.0, 10.0);
        let tr =
            SpeedTrack::from_edges(&ramp_edges(f0, f1, dur), 1, SpeedSourceKind::Edges).unwrap();
        let a = (f1 - f0) / dur;
        for &t in &[0.3, 2.71, 5.0, 9.2] {
            let truth = f0 * t + 0.5 * a * t * t;
            assert!(
                (tr.angle_at(t) - truth).abs() < 2e-3,
                "angle at {t}: {} vs {truth}",
                tr.angle_at(t)
            );
            assert!(
                (tr.rpm_at(t) / 60.0 - (f0 + a * t)).abs() < 0.01,
                "speed at {t}"
            );
            assert!((tr.time_at(truth) - t).abs() < 2e-4);
        }
        let mut times = [0.0; 50];
        tr.times_at_angles(3.0, 0.1, &mut times);
        for (j, &t) in times.iter().enumerate() {
            assert!((t - tr.time_at(3.0 + 0.1 * j as f64)).abs() < 1e-12);
        }
        let (lo, hi) = tr.speed_range_hz(2.0, 3.0);
        assert!(lo > 8.7 && lo < 8.9 && hi > 9.1 && hi < 9.3, "{lo} {hi}");
        assert!(tr.repairs().is_empty());
    }

    #[test]
    fn batch_angles_match_angle_at() {
        let tr = SpeedTrack::from_edges(&ramp_edges(8.0, 12.0, 10.0), 1, SpeedSourceKind::Edges)
            .unwrap();
        let (t0, dt) = (-0.05, 1.0 / 997.0);
        let mut out = vec![0.0; 11_000];
        tr.angles_at_times(t0, dt, &mut out);
        for (j, &a) in out.iter().enumerate() {
            let want = tr.angle_at(t0 + j as f64 * dt);
            assert!((a - want).abs() < 1e-11, "sample {j}: {a} vs {want}");
        }
        let c = SpeedTrack::fixed(600.0).unwrap();
        let mut out = [0.0; 3];
        c.angles_at_times(1.0, 0.5, &mut out);
        assert_eq!(out, [10.0, 15.0, 20.0]);
    }

    #[test]
    fn missing_and_extra_pulses_are_repaired_and_counted() {
        let clean = ramp_edges(10.0, 12.0, 5.0);
        let mut bad = clean.clone();
        bad.remove(20); // one missing
        bad.remove(30); // another one
        bad.remove(30); // two in a row
        bad.insert(10, clean[9] + 0.013); // spurious, just after a real pulse
        bad.insert(41, clean[40] - 0.004); // spurious, just before a real pulse
        bad.sort_by(|a, b| a.total_cmp(b));
        let tr = SpeedTrack::from_edges(&bad, 1, SpeedSourceKind::Edges).unwrap();
        let (ins, rem) = tr.repairs_between(0.0, 10.0);
        assert_eq!((ins, rem), (3, 2), "{:?}", tr.repairs());
        // the repaired track matches the clean one closely
        let good = SpeedTrack::from_edges(&clean, 1, SpeedSourceKind::Edges).unwrap();
        for k in 0..400 {
            let t = k as f64 * 0.01;
            assert!((tr.angle_at(t) - good.angle_at(t)).abs() < 0.01, "t = {t}");
        }
    }

    #[test]
    fn constant_and_profile() {
        let c = SpeedTrack::fixed(600.0).unwrap();
        assert_eq!(c.angle_at(2.0), 20.0);
        assert_eq!(c.source(), SpeedSourceKind::Fixed);
        let p = SpeedTrack::from_profile(&[0.0, 10.0], &[10.0, 20.0], SpeedSourceKind::Estimate)
            .unwrap();
        assert!((p.angle_at(10.0) - 150.0).abs() < 1e-9);
        assert!((p.mean_rpm(0.0, 10.0) - 900.0).abs() < 1e-6);
        assert!(
            SpeedTrack::from_edges(&[0.1, 0.2], 1, SpeedSourceKind::Edges)
                .unwrap_err()
                .to_string()
                .contains("at least 3")
        );
    }
}
