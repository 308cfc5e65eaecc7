//! Intake: two subscribers, `<prefix>/**/health` and `<prefix>/**/status`, whose callbacks
//! hand each sample to the buffer as it is (parsing waits for the writer), so the Zenoh
//! threads never wait for the database.

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
) -> Result<Vec<zenoh::pubsub::Subscriber<()>>> {
    let mut subs = Vec::new();
    for (suffix, kind) in [("health", Kind::Health), ("status", Kind::Status)] {
        let key = format!("{prefix}/**/{suffix}");
        let (buffer, counters) = (buffer.clone(), counters.clone());
        let sub = session
            .declare_subscriber(key.clone())
            .callback(move |s| {
                let c = match kind {
                    Kind::Health => &counters.received_health,
                    Kind::Status => &counters.received_status,
                };
                Counters::add(c, 1);
                buffer.push(Incoming {
                    kind,
                    key: s.key_expr().to_string(),
                    payload: s.payload().to_bytes().into_owned(),
                    recovered: false,
                });
            })
            .await
            .map_err(|e| anyhow!("cannot subscribe to {key}: {e}"))?;
        subs.push(sub);
    }
    Ok(subs)
}
