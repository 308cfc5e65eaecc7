//! Where a calibration spends its time: per stage, the summed time of every call (over all
//! threads, so the stages add up to about the CPU time, not the wall time) and the number of
//! calls. `rigmon bench calibrate` prints it; it costs two clock reads per call.

use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// The stages of a calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Views of the measured recordings (once per calibration).
    MeasuredViews,
    /// Engine runs of simulated twins (the mechanics).
    Engine,
    /// The sensor stage of a twin (noise, lines, shaft lines, tacho).
    Sensor,
    /// Views of a simulated twin.
    SimViews,
    /// Comparing measured and simulated views.
    Error,
}

const STAGES: [Stage; 5] = [
    Stage::MeasuredViews,
    Stage::Engine,
    Stage::Sensor,
    Stage::SimViews,
    Stage::Error,
];

impl Stage {
    pub fn name(&self) -> &'static str {
        match self {
            Stage::MeasuredViews => "measured_views",
            Stage::Engine => "engine",
            Stage::Sensor => "sensor",
            Stage::SimViews => "simulated_views",
            Stage::Error => "error",
        }
    }
}

/// Summed nanoseconds and calls per stage.
#[derive(Debug, Default)]
pub struct Timings {
    nanos: [AtomicU64; 5],
    calls: [AtomicU64; 5],
}

/// One stage's total.
#[derive(Debug, Clone, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
    pub calls: u64,
}

impl Timings {
    /// Run `f`, adding its time to `stage`.
    pub fn time<T>(&self, stage: Stage, f: impl FnOnce() -> T) -> T {
        let t0 = Instant::now();
        let out = f();
        let k = stage as usize;
        self.nanos[k].fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
        self.calls[k].fetch_add(1, Ordering::Relaxed);
        out
    }

    /// The totals, in stage order.
    pub fn totals(&self) -> Vec<StageTime> {
        STAGES
            .iter()
            .map(|s| StageTime {
                stage: s.name(),
                seconds: self.nanos[*s as usize].load(Ordering::Relaxed) as f64 * 1e-9,
                calls: self.calls[*s as usize].load(Ordering::Relaxed),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adds_time_and_calls_per_stage() {
        let t = Timings::default();
        let x = t.time(Stage::Engine, || {
            std::thread::sleep(std::time::Duration::from_millis(5));
            7
        });
        assert_eq!(x, 7);
        t.time(Stage::Engine, || ());
        let tot = t.totals();
        let e = tot.iter().find(|s| s.stage == "engine").unwrap();
        assert_eq!(e.calls, 2);
        assert!(e.seconds >= 0.005, "{e:?}");
        assert!(tot
            .iter()
            .filter(|s| s.stage != "engine")
            .all(|s| s.calls == 0 && s.seconds == 0.0));
    }
}
