//! Test signals with analytic answers: a bearing-like impulse train at a chosen order,
//! ringing a single resonance, under a linear speed ramp, with an analog tacho (finite rise
//! time, optional missing and extra pulses) and the exact tacho edge times. Used by the DSP
//! tests and `rigmon bench features`; not a rig model (that is `rigmon::sim`).

use rand::{Rng, SeedableRng};

/// Description of a synthetic run.
#[derive(Debug, Clone)]
pub struct Synthetic {
    pub sample_rate: f64,
    pub seconds: f64,
    /// Shaft frequency at t = 0 and at the end (linear ramp), Hz.
    pub f_start: f64,
    pub f_end: f64,
    /// Impulses per revolution (the "fault order").
    pub fault_order: f64,
    /// Resonance excited by each impulse, Hz, and its damping ratio.
    pub resonance_hz: f64,
    pub damping: f64,
    /// Standard deviation of white noise added to the vibration.
    pub noise: f64,
    /// Tacho pulses (revolution numbers) left out of the analog tacho.
    pub missing_pulses: Vec<usize>,
    /// Spurious tacho pulses added at these times, s.
    pub extra_pulses: Vec<f64>,
    pub seed: u64,
}

/// The generated signals.
#[derive(Debug, Clone)]
pub struct SyntheticRun {
    /// Vibration (impulse responses + noise).
    pub vibration: Vec<f32>,
    /// Analog tacho, 0/5 V, one pulse per revolution, 2 ms wide, 3-sample edges.
    pub tacho: Vec<f32>,
    /// True rising-edge (revolution) times, s.
    pub edges: Vec<f64>,
}

impl Default for Synthetic {
    fn default() -> Self {
        Synthetic {
            sample_rate: 10_000.0,
            seconds: 10.0,
            f_start: 8.0,
            f_end: 12.0,
            fault_order: 3.7,
            resonance_hz: 2500.0,
            damping: 0.05,
            noise: 0.05,
            missing_pulses: Vec::new(),
            extra_pulses: Vec::new(),
            seed: 7,
        }
    }
}

impl Synthetic {
    /// Shaft angle (revolutions) at time t.
    pub fn angle(&self, t: f64) -> f64 {
        let a = (self.f_end - self.f_start) / self.seconds;
        self.f_start * t + 0.5 * a * t * t
    }

    /// Time at which the shaft reaches `theta` revolutions.
    pub fn time_at(&self, theta: f64) -> f64 {
        let a = (self.f_end - self.f_start) / self.seconds;
        if a.abs() < 1e-12 {
            theta / self.f_start
        } else {
            (-self.f_start + (self.f_start * self.f_start + 2.0 * a * theta).sqrt()) / a
        }
    }

    pub fn generate(&self) -> SyntheticRun {
        let fs = self.sample_rate;
        let n = (self.seconds * fs).round() as usize;
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let mut vib: Vec<f32> = (0..n)
            .map(|_| (self.noise * (rng.random::<f64>() - 0.5) * 12f64.sqrt()) as f32)
            .collect();
        // impulse responses: e^{-zeta w t} sin(w_d t), 12 time constants long
        let w = 2.0 * std::f64::consts::PI * self.resonance_hz;
        let wd = w * (1.0 - self.damping * self.damping).sqrt();
        let tau = 1.0 / (self.damping * w);
        let ring = (12.0 * tau * fs).ceil() as usize;
        let total = self.angle(self.seconds);
        let mut k = 1;
        loop {
            let t0 = self.time_at(k as f64 / self.fault_order);
            if k as f64 / self.fault_order > total || t0 >= self.seconds {
                break;
            }
            let first = (t0 * fs).ceil() as usize;
            for i in first..(first + ring).min(n) {
                let dt = i as f64 / fs - t0;
                vib[i] += ((-dt / tau).exp() * (wd * dt).sin()) as f32;
            }
            k += 1;
        }
        // tacho
        let mut edges = Vec::new();
        let mut rev = 0;
        while self.time_at(rev as f64) < self.seconds - 0.003 {
            edges.push(self.time_at(rev as f64));
            rev += 1;
        }
        let mut pulses: Vec<f64> = edges
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.missing_pulses.contains(i))
            .map(|(_, &t)| t)
            .collect();
        pulses.extend(&self.extra_pulses);
        pulses.sort_by(|a, b| a.total_cmp(b));
        let mut tacho = vec![0.0f32; n];
        let rise = 3.0 / fs;
        for &e in &pulses {
            let lo = ((e - 2.0 * rise) * fs).floor().max(0.0) as usize;
            let hi = (((e + 0.002 + 2.0 * rise) * fs).ceil() as usize).min(n);
            for (i, v) in tacho.iter_mut().enumerate().take(hi).skip(lo) {
                let t = i as f64 / fs;
                let up = ((t - e) / rise + 0.5).clamp(0.0, 1.0);
                let down = ((t - e - 0.002) / rise + 0.5).clamp(0.0, 1.0);
                *v += (5.0 * (up - down)) as f32;
            }
        }
        SyntheticRun {
            vibration: vib,
            tacho,
            edges,
        }
    }
}
