//! Where a calibration spends its time: per stage, the summed time of every call (over all
//! threads, so the stages add up to about the CPU time, not the wall time) and the number of
//! calls, in all and per measured recording; and the wall time of each round and each
//! trial ([`RoundTime`]). `rigmon calibrate` prints it and writes it into the report; it
//! costs two clock reads per call.

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

/// Summed nanoseconds and calls per stage, in all and per measured recording.
#[derive(Debug, Default)]
pub struct Timings {
    nanos: [AtomicU64; 5],
    calls: [AtomicU64; 5],
    /// Per recording: summed nanoseconds per stage.
    per_op: Vec<[AtomicU64; 5]>,
}

/// One recording's summed time per stage, s (the stages of [`Stage`], in order).
#[derive(Debug, Clone, Serialize)]
pub struct RecordingTime {
    pub recording: String,
    pub measured_views_s: f64,
    pub engine_s: f64,
    pub sensor_s: f64,
    pub simulated_views_s: f64,
    pub error_s: f64,
}

/// Wall time of one round of trials and of each of its trials (a trial's time includes
/// waiting for the cores the other trials of its round hold).
#[derive(Debug, Clone, Serialize)]
pub struct RoundTime {
    pub round: usize,
    pub wall_s: f64,
    pub trials: Vec<(String, f64)>,
    /// Effects not tried in this round: the last round ruled them out.
    pub skipped: Vec<String>,
}

/// One stage's total.
#[derive(Debug, Clone, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
    pub calls: u64,
}

impl Timings {
    /// Counters for `recordings` measured recordings.
    pub fn for_recordings(recordings: usize) -> Timings {
        Timings {
            per_op: (0..recordings).map(|_| Default::default()).collect(),
            ..Timings::default()
        }
    }

    /// Run `f`, adding its time to `stage`.
    pub fn time<T>(&self, stage: Stage, f: impl FnOnce() -> T) -> T {
        self.time_op(stage, None, f)
    }

    /// Run `f` for recording `op` (if any), adding its time to `stage`.
    pub fn time_op<T>(&self, stage: Stage, op: Option<usize>, f: impl FnOnce() -> T) -> T {
        let t0 = Instant::now();
        let out = f();
        let k = stage as usize;
        let ns = t0.elapsed().as_nanos() as u64;
        self.nanos[k].fetch_add(ns, Ordering::Relaxed);
        self.calls[k].fetch_add(1, Ordering::Relaxed);
        if let Some(c) = op.and_then(|i| self.per_op.get(i)) {
            c[k].fetch_add(ns, Ordering::Relaxed);
        }
        out
    }

    /// Per recording (named by `names`, in order), the summed time per stage.
    pub fn per_recording(&self, names: &[String]) -> Vec<RecordingTime> {
        let s =
            |c: &[AtomicU64; 5], st: Stage| c[st as usize].load(Ordering::Relaxed) as f64 * 1e-9;
        self.per_op
            .iter()
            .zip(names)
            .map(|(c, n)| RecordingTime {
                recording: n.clone(),
                measured_views_s: s(c, Stage::MeasuredViews),
                engine_s: s(c, Stage::Engine),
                sensor_s: s(c, Stage::Sensor),
                simulated_views_s: s(c, Stage::SimViews),
                error_s: s(c, Stage::Error),
            })
            .collect()
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

    #[test]
    fn time_per_recording_adds_to_its_own_row_only() {
        let t = Timings::for_recordings(2);
        t.time_op(Stage::Sensor, Some(1), || {
            std::thread::sleep(std::time::Duration::from_millis(3))
        });
        t.time(Stage::Sensor, || ());
        let rows = t.per_recording(&["a".into(), "b".into()]);
        assert_eq!(rows[0].sensor_s, 0.0);
        assert!(rows[1].sensor_s >= 0.003, "{rows:?}");
        assert_eq!(rows[1].engine_s, 0.0);
        let all = t.totals();
        let sensor = all.iter().find(|s| s.stage == "sensor").unwrap();
        assert_eq!(sensor.calls, 2);
        assert!(sensor.seconds >= rows[1].sensor_s);
    }
}
