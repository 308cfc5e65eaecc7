//! Wall and CPU time of each `rigmon adapt` step, with the machine's load average, for the
//! report: on a shared machine the wall time alone says little (CPU time is what the step
//! costs; the load average says how many others wanted the same cores).

use serde::Serialize;
use std::time::Instant;

/// One timed step.
#[derive(Debug, Clone, Serialize)]
pub struct StepTime {
    pub step: String,
    /// Wall-clock seconds.
    pub wall_s: f64,
    /// CPU seconds of this process (user + system, all threads).
    pub cpu_s: f64,
    /// 1-minute load average at the end of the step (`None` where the OS does not tell).
    pub load_1min: Option<f64>,
}

pub use crate::usage::{load_1min, process_cpu_s};

/// Times consecutive steps.
pub struct Stopwatch {
    wall: Instant,
    cpu: f64,
    pub steps: Vec<StepTime>,
}

impl Stopwatch {
    pub fn start() -> Stopwatch {
        Stopwatch {
            wall: Instant::now(),
            cpu: process_cpu_s(),
            steps: Vec::new(),
        }
    }

    /// Close the current step under `name` and start the next.
    pub fn lap(&mut self, name: &str) {
        let cpu = process_cpu_s();
        self.steps.push(StepTime {
            step: name.to_string(),
            wall_s: self.wall.elapsed().as_secs_f64(),
            cpu_s: cpu - self.cpu,
            load_1min: load_1min(),
        });
        self.wall = Instant::now();
        self.cpu = cpu;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_grows_with_work_and_laps_add_up() {
        let mut w = Stopwatch::start();
        let mut x = 0u64;
        for i in 0..30_000_000u64 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(i);
        }
        std::hint::black_box(x);
        w.lap("spin");
        w.lap("idle");
        assert_eq!(w.steps.len(), 2);
        assert!(w.steps[0].cpu_s > 0.0, "{:?}", w.steps);
        assert!(w.steps[0].wall_s > 0.0 && w.steps[1].wall_s < w.steps[0].wall_s + 1.0);
        assert!(w.steps[1].cpu_s >= 0.0);
    }
}
