//! One connection to an openDAQ LT streaming server: the WebSocket stream (server to
//! client: protocol packets in binary messages) and the JSON-RPC over HTTP command
//! interface that subscribes signals to that stream.
//!
//! From the openDAQ Stream Protocol Specification 1.3.0 ("Init Meta", "Command Interface")
//! and the SDK's client (`lib/ProtocolHandler.cpp`, `Controller`): the `init` meta
//! information names the stream id and the `jsonrpc-http` command interface (`port`,
//! `httpPath`); subscribing is an HTTP/1.1 POST of
//! `{"jsonrpc": "2.0", "method": "<streamId>.subscribe", "params": [<signal ids>], "id": n}`
//! to the streaming host on that port. The reference server (openDAQ 3.40) answers
//! `200 Succeeded`. Default ports: 7414 (WebSocket streaming), 7438 (control).

use anyhow::{anyhow, bail, Context, Result};
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};
use tungstenite::{HandshakeError, Message, WebSocket};

/// Default WebSocket streaming port of openDAQ LT streaming servers.
pub const DEFAULT_PORT: u16 = 7414;

/// Where a server is: parsed from `daq.lt://host[:port][/path]` (also `ws://...`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoint {
    pub host: String,
    pub port: u16,
    pub path: String,
}

impl Endpoint {
    /// Parse a connection string. The error says what form is expected.
    pub fn parse(s: &str) -> Result<Self> {
        let rest = s
            .strip_prefix("daq.lt://")
            .or_else(|| s.strip_prefix("ws://"))
            .ok_or_else(|| {
                anyhow!(
                    "openDAQ connection {s:?}: expected daq.lt://HOST[:PORT][/PATH] (LT streaming, default port {DEFAULT_PORT}), e.g. daq.lt://192.168.1.50:7414"
                )
            })?;
        let (authority, path) = match rest.find('/') {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, "/"),
        };
        let (host, port) = if let Some(v6) = authority.strip_prefix('[') {
            let end = v6
                .find(']')
                .ok_or_else(|| anyhow!("openDAQ connection {s:?}: unclosed [ in the host"))?;
            let port = v6[end + 1..].strip_prefix(':');
            (v6[..end].to_string(), port)
        } else {
            match authority.rsplit_once(':') {
                Some((h, p)) => (h.to_string(), Some(p)),
                None => (authority.to_string(), None),
            }
        };
        if host.is_empty() {
            bail!("openDAQ connection {s:?}: no host; expected daq.lt://HOST[:PORT]");
        }
        let port = match port {
            Some(p) => p.parse::<u16>().ok().filter(|&p| p > 0).ok_or_else(|| {
                anyhow!("openDAQ connection {s:?}: port {p:?} is not a number from 1 to 65535")
            })?,
            None => DEFAULT_PORT,
        };
        Ok(Endpoint {
            host,
            port,
            path: path.to_string(),
        })
    }

    fn host_for_url(&self) -> String {
        if self.host.contains(':') {
            format!("[{}]", self.host)
        } else {
            self.host.clone()
        }
    }

    fn addr(&self, port: u16) -> Result<SocketAddr> {
        (self.host.as_str(), port)
            .to_socket_addrs()
            .with_context(|| format!("cannot resolve openDAQ host {:?}", self.host))?
            .next()
            .ok_or_else(|| anyhow!("openDAQ host {:?} has no address", self.host))
    }
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "daq.lt://{}:{}{}",
            self.host_for_url(),
            self.port,
            if self.path == "/" { "" } else { &self.path }
        )
    }
}

/// A connected streaming socket.
pub struct Connection {
    ws: WebSocket<TcpStream>,
    endpoint: Endpoint,
    next_id: u64,
    poll: Option<Duration>,
}

/// What one read returned.
pub enum Received {
    /// A binary message (protocol packets).
    Binary(tungstenite::Bytes),
    /// Nothing within the poll interval.
    Idle,
    /// The server closed the stream, or the socket failed (the reason).
    Closed(String),
}

impl Connection {
    /// Connect and do the WebSocket handshake within `timeout`.
    pub fn open(endpoint: &Endpoint, timeout: Duration) -> Result<Self> {
        let addr = endpoint.addr(endpoint.port)?;
        let tcp = TcpStream::connect_timeout(&addr, timeout)
            .with_context(|| format!("cannot connect to {endpoint} ({addr})"))?;
        tcp.set_nodelay(true)?;
        tcp.set_read_timeout(Some(timeout))?;
        tcp.set_write_timeout(Some(timeout))?;
        let url = format!(
            "ws://{}:{}{}",
            endpoint.host_for_url(),
            endpoint.port,
            endpoint.path
        );
        let ws = match tungstenite::client(url.as_str(), tcp) {
            Ok((ws, _)) => ws,
            Err(HandshakeError::Failure(e)) => {
                bail!("{endpoint}: WebSocket handshake failed: {e}")
            }
            Err(HandshakeError::Interrupted(_)) => {
                bail!("{endpoint}: no WebSocket handshake answer within {timeout:?}")
            }
        };
        Ok(Connection {
            ws,
            endpoint: endpoint.clone(),
            next_id: 1,
            poll: None,
        })
    }

    /// Wait at most `poll` for the next message.
    pub fn read(&mut self, poll: Duration) -> Received {
        if self.poll != Some(poll) {
            let _ = self.ws.get_ref().set_read_timeout(Some(poll));
            self.poll = Some(poll);
        }
        loop {
            match self.ws.read() {
                Ok(Message::Binary(b)) => return Received::Binary(b),
                Ok(Message::Close(f)) => {
                    return Received::Closed(format!(
                        "the server closed the stream{}",
                        f.map(|f| format!(" ({})", f.reason)).unwrap_or_default()
                    ))
                }
                // Text, ping and pong carry no protocol packets (pongs are answered inside).
                Ok(_) => continue,
                Err(tungstenite::Error::Io(e))
                    if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) =>
                {
                    return Received::Idle
                }
                Err(e) => return Received::Closed(e.to_string()),
            }
        }
    }

    /// Subscribe (or unsubscribe) signals through the HTTP JSON-RPC command interface.
    pub fn command(
        &mut self,
        stream_id: &str,
        http_port: u16,
        http_path: &str,
        method: &str,
        ids: &[String],
        timeout: Duration,
    ) -> Result<()> {
        let id = self.next_id;
        self.next_id += 1;
        let body = serde_json::json!({
            "jsonrpc": "2.0",
            "method": format!("{stream_id}.{method}"),
            "params": ids,
            "id": id,
        })
        .to_string();
        http_post(&self.endpoint, http_port, http_path, &body, timeout)
            .with_context(|| format!("{} {method} {ids:?}", self.endpoint))
    }

    /// Close politely (best effort).
    pub fn close(mut self) {
        let _ = self.ws.close(None);
        let _ = self.ws.flush();
    }
}

/// POST a JSON body; Ok when the server answers 2xx.
fn http_post(ep: &Endpoint, port: u16, path: &str, body: &str, timeout: Duration) -> Result<()> {
    let addr = ep.addr(port)?;
    let mut s = TcpStream::connect_timeout(&addr, timeout)
        .with_context(|| format!("cannot reach the command interface at {addr}"))?;
    s.set_read_timeout(Some(timeout))?;
    s.set_write_timeout(Some(timeout))?;
    let req = format!(
        "POST {path} HTTP/1.1\r\nHost: {}:{port}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        ep.host_for_url(),
        body.len()
    );
    s.write_all(req.as_bytes())?;
    let deadline = Instant::now() + timeout;
    let mut resp = Vec::new();
    let mut buf = [0u8; 4096];
    // Read until the server closes or the status line and headers are in (with the body
    // they announce), at most 64 kB.
    while resp.len() < 65536 && Instant::now() < deadline {
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                resp.extend_from_slice(&buf[..n]);
                if response_complete(&resp) {
                    break;
                }
            }
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => break,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e.into()),
        }
    }
    let text = String::from_utf8_lossy(&resp);
    let status = text.lines().next().unwrap_or("");
    let code = status.split_whitespace().nth(1).unwrap_or("");
    if !code.starts_with('2') {
        let body = text.split("\r\n\r\n").nth(1).unwrap_or("").trim();
        bail!(
            "command interface answered {:?} {}",
            status,
            &body[..body.len().min(200)]
        );
    }
    Ok(())
}

fn response_complete(r: &[u8]) -> bool {
    let Some(head_end) = r.windows(4).position(|w| w == b"\r\n\r\n") else {
        return false;
    };
    let head = String::from_utf8_lossy(&r[..head_end]).to_ascii_lowercase();
    let len = head
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|v| v.trim().parse::<usize>().ok());
    len.is_some_and(|n| r.len() >= head_end + 4 + n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connection_strings() {
        let e = Endpoint::parse("daq.lt://127.0.0.1:7414").unwrap();
        assert_eq!(
            (e.host.as_str(), e.port, e.path.as_str()),
            ("127.0.0.1", 7414, "/")
        );
        let e = Endpoint::parse("daq.lt://[::1]/x").unwrap();
        assert_eq!(
            (e.host.as_str(), e.port, e.path.as_str()),
            ("::1", 7414, "/x")
        );
        assert_eq!(e.to_string(), "daq.lt://[::1]:7414/x");
        assert!(Endpoint::parse("ws://sirius.local:9").is_ok());
        let err = Endpoint::parse("daq.nd://1.2.3.4").unwrap_err().to_string();
        assert!(err.contains("daq.lt://HOST"), "{err}");
        let err = Endpoint::parse("daq.lt://h:99999").unwrap_err().to_string();
        assert!(err.contains("99999"), "{err}");
    }

    #[test]
    fn http_response_framing() {
        assert!(response_complete(
            b"HTTP/1.1 200 OK\r\nContent-Length: 9\r\n\r\nSucceeded"
        ));
        assert!(!response_complete(
            b"HTTP/1.1 200 OK\r\nContent-Length: 9\r\n\r\nSucc"
        ));
    }
}
