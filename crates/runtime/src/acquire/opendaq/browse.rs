//! Lists what an openDAQ LT streaming server offers (for `rigmon devices` and for the
//! source's sample rate at start-up): every available signal is subscribed once so the
//! server describes it, then the connection is closed.

use super::connection::Endpoint;
use super::protocol::Event;
use super::session::{Pumped, Session};
use super::signal::{Rule, SignalDescription};
use anyhow::Result;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// One signal as the server describes it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalInfo {
    /// Full signal id (what `[source.signals]` may name, or its last path segment).
    pub id: String,
    /// The server's name for it.
    pub name: String,
    /// `waveform` (explicit samples rigmon can read), `time` (a linear time domain), or
    /// `other` (rule/type rigmon does not read; see `data_type`).
    pub kind: String,
    pub data_type: String,
    /// Sample rate from the signal's time domain, Hz.
    pub sample_rate_hz: Option<f64>,
    pub unit: Option<String>,
    /// The time signal that stamps this signal.
    pub domain: Option<String>,
}

/// What [`list_signals`] found.
#[derive(Debug, Clone, Serialize)]
pub struct ServerSignals {
    pub connection: String,
    pub api_version: String,
    pub signals: Vec<SignalInfo>,
}

/// Connect, subscribe every available signal (or only `only`, with their domains), and
/// collect their descriptions; waits until all are described or `timeout` passes.
pub fn list_signals(
    endpoint: &Endpoint,
    only: Option<&[String]>,
    timeout: Duration,
) -> Result<ServerSignals> {
    let deadline = Instant::now() + timeout;
    let mut s = Session::start(endpoint, timeout)?;
    let ids: Vec<String> = match only {
        Some(o) => o.to_vec(),
        None => s.available.clone(),
    };
    let left = deadline
        .saturating_duration_since(Instant::now())
        .max(Duration::from_secs(1));
    s.subscribe(&ids, left)?;
    let mut described: BTreeMap<String, SignalDescription> = BTreeMap::new();
    let mut closed = None;
    let done = |d: &BTreeMap<String, SignalDescription>| {
        ids.iter().all(|id| {
            d.get(id).is_some_and(|x| {
                x.domain_id
                    .as_ref()
                    .is_none_or(|dom| dom == id || d.contains_key(dom))
            })
        })
    };
    while Instant::now() < deadline && !done(&described) {
        let mut new = Vec::new();
        match s.pump(Duration::from_millis(100), &mut |e| {
            if let Event::Described { signo } = e {
                new.push(signo);
            }
        }) {
            Pumped::Closed(why) => {
                closed = Some(why);
                break;
            }
            Pumped::Message | Pumped::Idle => {}
        }
        for signo in new {
            if let Some((id, Some(d))) = s.decoder.signal(signo) {
                described.insert(id.to_string(), d.clone());
            }
        }
    }
    if let Some(why) = closed {
        anyhow::bail!("{endpoint}: {why} while listing signals");
    }
    let connection = endpoint.to_string();
    let api_version = s.api_version.clone();
    s.conn.close();
    let mut signals: Vec<SignalInfo> = s_ids_in_order(&ids, &described)
        .into_iter()
        .map(|id| {
            let d = described.get(&id);
            let rate = d
                .and_then(|d| d.domain_id.as_ref())
                .and_then(|dom| described.get(dom))
                .and_then(SignalDescription::sample_rate);
            SignalInfo {
                name: d.map(|d| d.name.clone()).unwrap_or_default(),
                kind: match d {
                    Some(d) if d.is_waveform() => "waveform",
                    Some(d) if matches!(d.rule, Rule::Linear { .. }) => "time",
                    Some(_) => "other",
                    None => "not described",
                }
                .to_string(),
                data_type: d.map(|d| d.type_name.clone()).unwrap_or_default(),
                sample_rate_hz: rate.or_else(|| d.and_then(SignalDescription::sample_rate)),
                unit: d.and_then(|d| d.unit.clone()),
                domain: d.and_then(|d| d.domain_id.clone()).filter(|dom| dom != &id),
                id,
            }
        })
        .collect();
    signals.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(ServerSignals {
        connection,
        api_version,
        signals,
    })
}

/// Requested ids plus the domains the server described with them.
fn s_ids_in_order(ids: &[String], described: &BTreeMap<String, SignalDescription>) -> Vec<String> {
    let mut v: Vec<String> = ids.to_vec();
    for k in described.keys() {
        if !v.contains(k) {
            v.push(k.clone());
        }
    }
    v
}

impl ServerSignals {
    /// A table for people.
    pub fn table(&self) -> String {
        let mut out = format!(
            "{} (openDAQ LT streaming, protocol {})\n{:<44} {:<14} {:>12} {:<6} {:<9} {}\n",
            self.connection, self.api_version, "id", "name", "rate Hz", "unit", "kind", "type"
        );
        for s in &self.signals {
            out.push_str(&format!(
                "{:<44} {:<14} {:>12} {:<6} {:<9} {}\n",
                s.id,
                s.name,
                s.sample_rate_hz.map_or("-".to_string(), |r| format!("{r}")),
                s.unit.as_deref().unwrap_or("-"),
                s.kind,
                s.data_type
            ));
        }
        out
    }
}
