//! Falling behind a live source: blocks keep waiting in the queue, so every receive returns
//! at once; past half the queue the source starts dropping (and counting) blocks. Reported as
//! `pipeline.behind` (held for 5 s after the backlog clears) and `pipeline.lag_s` (wall time
//! minus signal time since the first block). File replays are never behind.

use crate::acquire::SourceStats;
use crate::wire::status::PipelineStatus;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Tracks the backlog and the lag of a live source.
pub struct Backlog {
    live: bool,
    queue_blocks: usize,
    behind_since: Option<Instant>,
    /// Wall time and signal time of the first block's start.
    first_block: Option<(Instant, f64)>,
    /// Signal time of the newest sample received, s.
    newest_t: f64,
}

impl Backlog {
    /// `live`: the source runs in real time (not a file); `queue_blocks`: the block queue's size.
    pub fn new(live: bool, queue_blocks: usize) -> Self {
        Backlog {
            live,
            queue_blocks,
            behind_since: None,
            first_block: None,
            newest_t: 0.0,
        }
    }

    /// A block of `block_s` seconds arrived whose newest sample is at signal time `newest_t`.
    pub fn saw_block(&mut self, newest_t: f64, block_s: f64) {
        self.newest_t = newest_t;
        self.first_block
            .get_or_insert((Instant::now(), newest_t - block_s));
    }

    /// After each receive: `waiting` blocks were taken back to back from the queue.
    pub fn update(&mut self, waiting: usize, stats: &SourceStats, pipe: &mut PipelineStatus) {
        let behind_now = self.live && waiting >= (self.queue_blocks / 2).max(2);
        if behind_now {
            if self.behind_since.is_none() {
                tracing::warn!(
                    "processing is falling behind: {waiting} blocks waiting in a queue of {}; the source drops what does not fit (status: source.samples_lost = {})",
                    self.queue_blocks,
                    stats.samples_lost.load(Ordering::Relaxed)
                );
            }
            self.behind_since = Some(Instant::now());
        } else if self
            .behind_since
            .is_some_and(|t| t.elapsed() > Duration::from_secs(5))
        {
            tracing::info!("processing caught up");
            self.behind_since = None;
        }
        pipe.behind = self.behind_since.is_some();
        if let Some((t0_wall, t0_sig)) = self.first_block.filter(|_| self.live) {
            pipe.lag_s = (t0_wall.elapsed().as_secs_f64() - (self.newest_t - t0_sig)).max(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_live_source_is_behind_from_half_the_queue_and_a_file_never() {
        let stats = SourceStats::default();
        let mut pipe = PipelineStatus::default();
        let mut live = Backlog::new(true, 64);
        live.update(31, &stats, &mut pipe);
        assert!(!pipe.behind);
        live.update(32, &stats, &mut pipe);
        assert!(pipe.behind);
        // Held for 5 s after the queue empties.
        live.update(0, &stats, &mut pipe);
        assert!(pipe.behind);
        let mut file = Backlog::new(false, 64);
        let mut pipe = PipelineStatus::default();
        file.saw_block(10.0, 1.0);
        file.update(64, &stats, &mut pipe);
        assert!(!pipe.behind);
        assert_eq!(pipe.lag_s, 0.0);
    }

    #[test]
    fn lag_is_wall_time_minus_signal_time_since_the_first_block() {
        let stats = SourceStats::default();
        let mut pipe = PipelineStatus::default();
        let mut b = Backlog::new(true, 64);
        b.saw_block(0.1, 0.1);
        std::thread::sleep(Duration::from_millis(300));
        // 0.3 s of wall time for 0.1 s of signal: at least 0.2 s behind.
        b.update(0, &stats, &mut pipe);
        assert!(pipe.lag_s >= 0.2 - 1e-3, "{}", pipe.lag_s);
        // A source running ahead of the wall clock never gives a negative lag.
        b.saw_block(100.0, 0.1);
        b.update(0, &stats, &mut pipe);
        assert_eq!(pipe.lag_s, 0.0);
    }
}
