//! The start of an openDAQ LT streaming session, shared by the source and `rigmon devices`:
//! connect, wait for the `init` and `available` stream meta information, resolve the names
//! a user wrote to signal ids, and subscribe. Afterwards [`Session::pump`] feeds each
//! received message to the [`StreamDecoder`].

use super::connection::{Connection, Endpoint, Received};
use super::protocol::{Event, StreamDecoder};
use anyhow::{anyhow, bail, Result};
use std::time::{Duration, Instant};

/// An open stream with its decoder.
pub struct Session {
    pub conn: Connection,
    pub decoder: StreamDecoder,
    pub stream_id: String,
    pub http_port: u16,
    pub http_path: String,
    pub api_version: String,
    /// Signal ids the server offers.
    pub available: Vec<String>,
    pub endpoint: Endpoint,
}

/// What one [`Session::pump`] call saw.
pub enum Pumped {
    Message,
    Idle,
    Closed(String),
}

impl Session {
    /// Connect and read until the server has said `init` and `available` (within
    /// `timeout`).
    pub fn start(endpoint: &Endpoint, timeout: Duration) -> Result<Self> {
        let mut conn = Connection::open(endpoint, timeout)?;
        let mut decoder = StreamDecoder::new();
        let deadline = Instant::now() + timeout;
        let (mut init, mut available, mut version) = (None, None, String::new());
        let mut desync = None;
        while init.is_none() || available.is_none() {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!(
                    "{endpoint}: the server sent no {} within {timeout:?}; is this an openDAQ LT streaming port?",
                    if init.is_none() { "`init`" } else { "`available` signal list" }
                );
            }
            match conn.read(left.min(Duration::from_millis(200))) {
                Received::Binary(b) => decoder.feed(&b, &mut |e| match e {
                    Event::ApiVersion(v) => version = v,
                    Event::Init {
                        stream_id,
                        http_port,
                        http_path,
                    } => init = Some((stream_id, http_port, http_path)),
                    Event::Available(ids) => available.get_or_insert_with(Vec::new).extend(ids),
                    Event::Desync(why) => desync = Some(why),
                    _ => {}
                }),
                Received::Idle => {}
                Received::Closed(why) => bail!("{endpoint}: {why}"),
            }
            if let Some(why) = desync.take() {
                bail!("{endpoint}: not an openDAQ LT stream: {why}");
            }
        }
        let (stream_id, http_port, http_path) = init.unwrap_or_default();
        let http_port = http_port.ok_or_else(|| {
            anyhow!("{endpoint}: the server offers no `jsonrpc-http` command interface to subscribe signals")
        })?;
        Ok(Session {
            conn,
            decoder,
            stream_id,
            http_port,
            http_path,
            api_version: version,
            available: available.unwrap_or_default(),
            endpoint: endpoint.clone(),
        })
    }

    /// The signal id a user's name stands for: an exact id, or the one id whose last path
    /// segment is the name (`AI0` for `/RefDev0/IO/AI/RefCh0/Sig/AI0`).
    pub fn resolve(&self, name: &str) -> Result<String> {
        resolve(&self.available, name).map_err(|e| anyhow!("{}: {e}", self.endpoint))
    }

    pub fn subscribe(&mut self, ids: &[String], timeout: Duration) -> Result<()> {
        self.conn.command(
            &self.stream_id,
            self.http_port,
            &self.http_path,
            "subscribe",
            ids,
            timeout,
        )
    }

    /// Read one message (waiting at most `poll`) and decode it.
    pub fn pump(&mut self, poll: Duration, on: &mut dyn FnMut(Event<'_>)) -> Pumped {
        match self.conn.read(poll) {
            Received::Binary(b) => {
                self.decoder.feed(&b, on);
                Pumped::Message
            }
            Received::Idle => Pumped::Idle,
            Received::Closed(why) => Pumped::Closed(why),
        }
    }
}

/// See [`Session::resolve`].
pub fn resolve(available: &[String], name: &str) -> Result<String, String> {
    if available.iter().any(|a| a == name) {
        return Ok(name.to_string());
    }
    let hits: Vec<&String> = available
        .iter()
        .filter(|a| a.rsplit('/').next() == Some(name))
        .collect();
    match hits.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(format!(
            "no signal {name:?}; the server offers {} (run `rigmon devices` to list them)",
            available.join(", ")
        )),
        many => Err(format!(
            "{name:?} is ambiguous: {}; write the full id",
            many.iter()
                .map(|s| s.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_to_ids() {
        let a: Vec<String> = ["/Dev/AI/Sig/AI0", "/Dev/AI/Sig/AI0Time", "/A/x", "/B/x"]
            .map(String::from)
            .to_vec();
        assert_eq!(resolve(&a, "AI0").unwrap(), "/Dev/AI/Sig/AI0");
        assert_eq!(resolve(&a, "/A/x").unwrap(), "/A/x");
        assert!(resolve(&a, "x").unwrap_err().contains("ambiguous"));
        let e = resolve(&a, "AI9").unwrap_err();
        assert!(e.contains("AI0Time") && e.contains("rigmon devices"), "{e}");
    }
}
