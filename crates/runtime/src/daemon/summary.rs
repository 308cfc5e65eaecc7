//! What happened during a run (printed at the end of `rigmon replay`, as text or JSON): the
//! final status message's counters plus the windows counted per state and the latency
//! quantiles.

use super::latency::LatencyHistogram;
use crate::wire::health::HealthMessage;
use crate::wire::status::{SinkStatus, StatusMessage};
use serde::Serialize;
use std::collections::BTreeMap;

/// What happened during a run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    pub source: String,
    pub windows: u64,
    /// Windows per smoothed state.
    pub states: BTreeMap<String, u64>,
    /// Windows per window state.
    pub window_states: BTreeMap<String, u64>,
    /// The finest and the coarsest order resolution of the windows' envelope order spectra
    /// (1 / revolutions in a window), orders.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order_resolution: Option<[f64; 2]>,
    pub final_state: Option<String>,
    pub samples_in: u64,
    pub samples_lost: u64,
    /// Captures read, when the source is a series of periodic captures (0 otherwise).
    #[serde(skip_serializing_if = "is_zero")]
    pub captures: u64,
    pub source_samples_lost: u64,
    pub bad_frames: u64,
    pub window_errors: u64,
    pub zenoh_dropped: u64,
    pub record_dropped: u64,
    pub reloads: u64,
    pub reloads_rejected: u64,
    pub latency_ms_max: f64,
    /// Per-window processing latency (last block in -> health out), median and 99th percentile.
    pub latency_ms_p50: f64,
    pub latency_ms_p99: f64,
    /// The most signal past a window's end that had arrived when it was analysed, ms (the
    /// analysis waits for none; see `status::WindowBudget`).
    pub after_end_ms_max: f64,
    pub source_error: Option<String>,
    pub wall_s: f64,
    /// What the replayed recording could not deliver: samples and seconds lost, where and why
    /// (gaps are also in `samples_lost`, on the sample clock).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file_losses: Option<crate::recording::LossReport>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Windows counted per state while the daemon runs.
#[derive(Debug, Clone, Default)]
pub struct StateCounts {
    /// Per smoothed state.
    pub states: BTreeMap<String, u64>,
    /// Per window state.
    pub window_states: BTreeMap<String, u64>,
    /// The finest and the coarsest order resolution a window had (1 / its revolutions).
    pub order_resolution: Option<[f64; 2]>,
}

impl StateCounts {
    pub fn count(&mut self, msg: &HealthMessage) {
        *self.states.entry(msg.state.clone()).or_default() += 1;
        *self
            .window_states
            .entry(msg.window_state.clone())
            .or_default() += 1;
        if let Some(r) = msg.order_resolution() {
            let [lo, hi] = self.order_resolution.get_or_insert([r, r]);
            *lo = lo.min(r);
            *hi = hi.max(r);
        }
    }
}

impl Summary {
    /// The summary of a run that ended with `last` (the final status message). `dropped`
    /// are the sinks' drop counts after `last` was handed to them.
    pub fn new(
        last: &StatusMessage,
        counts: StateCounts,
        latencies: &LatencyHistogram,
        dropped: SinkStatus,
        wall_s: f64,
    ) -> Summary {
        let (src, pipe, model) = (&last.source, &last.pipeline, &last.model);
        Summary {
            source: src.describe.clone(),
            windows: pipe.windows,
            states: counts.states,
            window_states: counts.window_states,
            order_resolution: counts.order_resolution,
            final_state: last.state.clone(),
            samples_in: pipe.samples_in,
            samples_lost: pipe.samples_lost,
            captures: pipe.captures,
            source_samples_lost: src.samples_lost,
            bad_frames: src.bad_frames,
            window_errors: pipe.window_errors,
            zenoh_dropped: dropped.zenoh_dropped,
            record_dropped: dropped.record_dropped,
            reloads: model.reloads,
            reloads_rejected: model.reloads_rejected,
            latency_ms_max: pipe.latency_ms_max,
            latency_ms_p50: latencies.quantile(0.5),
            latency_ms_p99: latencies.quantile(0.99),
            after_end_ms_max: pipe.after_end_ms_max,
            source_error: src.error.clone(),
            wall_s,
            file_losses: src.file_losses.clone(),
        }
    }

    /// A few lines for a terminal.
    pub fn text(&self) -> String {
        let states: Vec<String> = self
            .states
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let wstates: Vec<String> = self
            .window_states
            .iter()
            .map(|(k, v)| format!("{k} {v}"))
            .collect();
        let mut s = format!(
            "{} windows from {} in {:.1} s; final state: {}\n  smoothed states: {}\n  window states:   {}\n  samples: {} in, {} lost on the sample clock, {} dropped at the source; {} bad frames; {} window errors; sink drops: zenoh {}, recording {}",
            self.windows,
            self.source,
            self.wall_s,
            self.final_state.as_deref().unwrap_or("-"),
            states.join(", "),
            wstates.join(", "),
            self.samples_in,
            self.samples_lost,
            self.source_samples_lost,
            self.bad_frames,
            self.window_errors,
            self.zenoh_dropped,
            self.record_dropped
        );
        if let Some([lo, hi]) = self.order_resolution {
            s.push_str(&format!(
                "\n  order resolution: {lo:.3}-{hi:.3} orders (1 / revolutions per window; lines closer than that are not told apart)"
            ));
        }
        if self.captures > 0 {
            s.push_str(&format!(
                "\n  captures: {} (the time between them is not signal: neither lost nor a gap)",
                self.captures
            ));
        }
        if self.reloads + self.reloads_rejected > 0 {
            s.push_str(&format!(
                "\n  reloads: {} applied, {} rejected",
                self.reloads, self.reloads_rejected
            ));
        }
        if let Some(l) = &self.file_losses {
            s.push_str(&format!("\n  file damaged or cut: {}", l.summary));
        }
        if let Some(e) = &self.source_error {
            s.push_str(&format!("\n  source error: {e}"));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::status::{ModelStatus, Phase, PipelineStatus, SourceStatus};

    #[test]
    fn the_summary_takes_each_counter_from_its_place_in_the_last_status() {
        let last = StatusMessage {
            schema: crate::wire::status::SCHEMA.into(),
            schema_version: 1,
            rig: "r".into(),
            asset: "a".into(),
            point: "p".into(),
            time_ns: 1,
            uptime_s: 2.0,
            phase: Phase::Finished,
            software_version: "0".into(),
            source: SourceStatus {
                describe: "file x".into(),
                samples_lost: 3,
                bad_frames: 4,
                finished: true,
                error: Some("gone".into()),
                ..Default::default()
            },
            pipeline: PipelineStatus {
                windows: 5,
                samples_in: 6,
                samples_lost: 7,
                window_errors: 8,
                latency_ms_max: 9.5,
                after_end_ms_max: 15.0,
                ..Default::default()
            },
            model: ModelStatus {
                reloads: 10,
                reloads_rejected: 11,
                ..Default::default()
            },
            sinks: SinkStatus::default(),
            publish: None,
            recording: None,
            state: Some("healthy".into()),
        };
        let mut counts = StateCounts::default();
        counts.states.insert("healthy".into(), 5);
        let mut lat = LatencyHistogram::default();
        lat.record(2.0);
        let dropped = SinkStatus {
            zenoh_dropped: 12,
            record_dropped: 13,
        };
        let s = Summary::new(&last, counts, &lat, dropped, 14.0);
        let got = serde_json::to_value(&s).unwrap();
        let want = serde_json::json!({
            "source": "file x", "windows": 5, "states": {"healthy": 5}, "window_states": {},
            "final_state": "healthy", "samples_in": 6, "samples_lost": 7,
            "source_samples_lost": 3, "bad_frames": 4, "window_errors": 8,
            "zenoh_dropped": 12, "record_dropped": 13, "reloads": 10, "reloads_rejected": 11,
            "latency_ms_max": 9.5, "latency_ms_p50": lat.quantile(0.5),
            "latency_ms_p99": lat.quantile(0.99), "after_end_ms_max": 15.0, "source_error": "gone", "wall_s": 14.0,
        });
        assert_eq!(got, want);
        assert!(s.text().contains("source error: gone"), "{}", s.text());
    }
}
