//! The status message's source part read from the source's live counters (the message
//! itself is [`crate::wire::status`], in the core).

use crate::acquire::SourceStats;
use crate::wire::status::SourceStatus;
use std::sync::atomic::Ordering;

/// The source's counters now; `finished` is how it ended, once it has.
pub fn source_status(
    describe: &str,
    stats: &SourceStats,
    finished: Option<&anyhow::Result<()>>,
) -> SourceStatus {
    SourceStatus {
        describe: describe.to_string(),
        connected: stats.connected.load(Ordering::Relaxed),
        blocks: stats.blocks.load(Ordering::Relaxed),
        samples: stats.samples.load(Ordering::Relaxed),
        bad_frames: stats.bad_frames.load(Ordering::Relaxed),
        sequence_gaps: stats.sequence_gaps.load(Ordering::Relaxed),
        samples_lost: stats.samples_lost.load(Ordering::Relaxed),
        reconnects: stats.reconnects.load(Ordering::Relaxed),
        finished: finished.is_some(),
        error: finished
            .and_then(|r| r.as_ref().err())
            .map(|e| format!("{e:#}")),
        file_losses: stats.losses.lock().ok().and_then(|l| l.clone()),
    }
}
