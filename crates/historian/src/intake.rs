//! Intake: two subscribers, `<prefix>/**/health` and `<prefix>/**/status`, whose callbacks
//! hand each sample to the buffer as it is (parsing waits for the writer), so the Zenoh
//! threads never wait for the database. A sample larger than `[intake] max_message_kb` is
//! refused here, before it is copied (counted as `too_large`, logged).

use super::admit::Refusal;
use super::buffer::{Buffer, Incoming, Kind};
use super::status::Counters;
use anyhow::{anyhow, Result};
use std::sync::Arc;

/// Subscribe; dropping the returned subscribers stops the intake.
pub async fn subscribe(
    session: &zenoh::Session,
    prefix: &str,
    buffer: Arc<Buffer>,
    counters: Arc<Counters>,
    max_bytes: usize,
) -> Result<Vec<zenoh::pubsub::Subscriber<()>>> {
    let mut subs = Vec::new();
    for (suffix, kind) in [("health", Kind::Health), ("status", Kind::Status)] {
        let key = format!("{prefix}/**/{suffix}");
        let (buffer, counters) = (buffer.clone(), counters.clone());
        let sub = session
            .declare_subscriber(key.clone())
            .callback(move |s| {
                let t0 = std::time::Instant::now();
                let c = match kind {
                    Kind::Health => &counters.received_health,
                    Kind::Status => &counters.received_status,
                };
                Counters::add(c, 1);
                let size = s.payload().len();
                if size > max_bytes {
                    let n = counters
                        .refused(Refusal::TooLarge)
                        .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
                        + 1;
                    if n <= 3 || n.is_power_of_two() {
                        tracing::warn!(
                            "message on {} refused ({n} so far): {size} bytes, more than [intake] max_message_kb = {} KB",
                            s.key_expr(),
                            max_bytes / 1024
                        );
                    }
                    return;
                }
                buffer.push(Incoming {
                    kind,
                    key: s.key_expr().to_string(),
                    payload: s.payload().to_bytes().into_owned(),
                    recovered: false,
                });
                Counters::time(&counters.intake_ns, t0);
            })
            .await
            .map_err(|e| anyhow!("cannot subscribe to {key}: {e}"))?;
        subs.push(sub);
    }
    Ok(subs)
}
