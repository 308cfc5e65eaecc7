//! What the historian learns from a daemon's running config (its `<base>/config`
//! queryable) when it first sees a point: the ISO 20816-3 zone limits its velocity verdicts
//! use, so trends can draw them. No answer (an old daemon, access denied): the limits stay
//! unknown and `rigmon history` draws the standard's defaults, saying so.

use rigmon_core::health::iso20816::ZoneConfig;
use std::time::Duration;

/// The zone limits (A/B, B/C, C/D, mm/s) of the daemon publishing `<prefix>/<key>`.
pub async fn iso_limits(session: &zenoh::Session, prefix: &str, key: &str) -> Option<[f64; 3]> {
    let selector = format!("{prefix}/{key}/config");
    let replies = session
        .get(selector)
        // The reply must not be able to close a slow historian's transport (see recovery).
        .congestion_control(rigmon_runtime::publish::zenoh::FLEET_CONGESTION)
        .timeout(Duration::from_secs(5))
        .await
        .ok()?;
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else { continue };
        let v: serde_json::Value = serde_json::from_slice(&sample.payload().to_bytes()).ok()?;
        let zones = v.get("health").and_then(|h| h.get("iso20816")).cloned();
        let cfg: ZoneConfig = match zones {
            Some(z) => serde_json::from_value(z).ok()?,
            None => ZoneConfig::default(),
        };
        return Some(cfg.limits());
    }
    None
}
