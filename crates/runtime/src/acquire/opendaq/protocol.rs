//! The openDAQ LT streaming protocol decoder: a pure function over the bytes of the
//! WebSocket binary messages a server sends (no I/O, fuzzed by `tests/heavy/fuzz.rs`).
//!
//! Wire format, from the openDAQ Stream Protocol Specification 1.3.0
//! (openDAQ/streaming-protocol-lt `docs/openDAQ-streaming.md`, transport layer grammar in
//! `docs/openDAQ-streaming-transportlayer.bnf`) and the SDK's own reader
//! (`lib/ProtocolHandler.cpp`, header layout in openDAQ/ws-streaming
//! `detail/streaming_protocol.hpp`):
//!
//! ```text
//! u32 LE header: bits 0..19 signal number, bits 20..27 size, bits 28..29 type
//!                (1 = signal data, 2 = meta information), bits 30..31 reserved = 0
//! [u32 LE length]  present only when size = 0 (payloads of 256 bytes and more)
//! payload
//!   meta: u32 LE Metainfo_Type (2 = MessagePack) + {"method", "params"} in MessagePack
//!   data: explicit signals: the values back to back (little-endian);
//!         implicit signals (linear time): pairs of u64 value index + value, an index alone
//!         at the end is a progress marker
//! ```
//!
//! Packets form a byte stream that may span WebSocket messages (the SDK reads it as one
//! stream). Signal number 0 carries stream meta information (`apiVersion`, `init`,
//! `available`, `unavailable`, `alive`); other numbers are bound to a signal id by the
//! `subscribe` acknowledge and described by `signal`.
//!
//! Trouble is counted, never a panic: meta information that does not decode, data for a
//! signal that was never described, data whose length is not a whole number of values. A
//! header with a wrong type, reserved bits set or an absurd length means the stream can no
//! longer be framed: the decoder drops what it holds and reports [`Event::Desync`] (the SDK
//! closes the session in that case; the source reconnects).

use super::msgpack;
use super::signal::{Rule, SignalDescription};
use serde_json::Value;
use std::collections::HashMap;

/// Largest payload accepted (a 4096-channel device at 1 MHz sends far smaller packets).
pub const MAX_PAYLOAD: usize = 16 << 20;
/// Packet type: signal data.
pub const TYPE_DATA: u32 = 1;
/// Packet type: meta information.
pub const TYPE_META: u32 = 2;
/// Meta information encoding: MessagePack.
pub const META_MSGPACK: u32 = 2;

/// Something the stream said, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Event<'a> {
    /// `apiVersion` (the server's protocol version).
    ApiVersion(String),
    /// `init`: the stream id for the command interface, and the HTTP JSON-RPC command
    /// interface's port and path when offered.
    Init {
        stream_id: String,
        http_port: Option<u16>,
        http_path: String,
    },
    /// Signal ids that can be subscribed.
    Available(Vec<String>),
    /// Signal ids that went away.
    Unavailable(Vec<String>),
    /// A signal number now carries this signal id.
    Subscribed { signo: u32, id: String },
    /// A signal number was unsubscribed.
    Unsubscribed { signo: u32 },
    /// A signal was (re)described; read it with [`StreamDecoder::signal`].
    Described { signo: u32 },
    /// Explicit values of a signal (post-scaling applied) starting at table index
    /// `first_index`.
    Values {
        signo: u32,
        first_index: u64,
        values: &'a [f64],
    },
    /// A new start value of an implicit linear signal (time), valid from table index `index`.
    LinearStart { signo: u32, index: u64, value: i128 },
    /// The stream could not be framed any more; what was buffered is dropped.
    Desync(String),
}

/// What the decoder saw (cumulative).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counters {
    pub packets: u64,
    /// Meta information that did not decode, or unknown meta encodings.
    pub bad_meta: u64,
    /// Data packets for signals never described, or whose length is not a whole number of
    /// values (the remainder is dropped).
    pub bad_data: u64,
    /// Headers that broke the framing.
    pub desyncs: u64,
}

impl Counters {
    /// Every packet rejected, for the `bad_frames` status counter.
    pub fn bad(&self) -> u64 {
        self.bad_meta + self.bad_data + self.desyncs
    }
}

#[derive(Debug, Clone)]
struct Bound {
    id: String,
    desc: Option<SignalDescription>,
    next_index: u64,
}

/// Decodes the server-to-client byte stream into [`Event`]s.
#[derive(Debug, Default)]
pub struct StreamDecoder {
    pending: Vec<u8>,
    signals: HashMap<u32, Bound>,
    values: Vec<f64>,
    counters: Counters,
}

/// A framed packet: (signal number, type, payload range in the buffer, total length).
fn frame(b: &[u8]) -> Result<Option<(u32, u32, usize, usize)>, String> {
    if b.len() < 4 {
        return Ok(None);
    }
    let h = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let signo = h & 0x000F_FFFF;
    let size = ((h >> 20) & 0xFF) as usize;
    let kind = (h >> 28) & 0x3;
    if h >> 30 != 0 || !(kind == TYPE_DATA || kind == TYPE_META) {
        return Err(format!(
            "packet header 0x{h:08x}: type {kind} (must be 1 = data or 2 = meta), reserved bits {}",
            h >> 30
        ));
    }
    let (start, len) = if size == 0 {
        if b.len() < 8 {
            return Ok(None);
        }
        (8, u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize)
    } else {
        (4, size)
    };
    if len > MAX_PAYLOAD {
        return Err(format!(
            "packet header 0x{h:08x} announces {len} bytes (more than {MAX_PAYLOAD})"
        ));
    }
    if b.len() < start + len {
        return Ok(None);
    }
    Ok(Some((signo, kind, start, start + len)))
}

impl StreamDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Bytes waiting for the rest of a packet.
    pub fn buffered(&self) -> usize {
        self.pending.len()
    }

    /// The signal id and description bound to a signal number.
    pub fn signal(&self, signo: u32) -> Option<(&str, Option<&SignalDescription>)> {
        self.signals
            .get(&signo)
            .map(|b| (b.id.as_str(), b.desc.as_ref()))
    }

    /// The signal number a signal id is subscribed on.
    pub fn signo_of(&self, id: &str) -> Option<u32> {
        self.signals
            .iter()
            .find(|(_, b)| b.id == id)
            .map(|(&n, _)| n)
    }

    /// Forget everything (a new connection).
    pub fn reset(&mut self) {
        self.pending.clear();
        self.signals.clear();
    }

    /// Feed one WebSocket binary message; `on` receives the events it completes, in order.
    pub fn feed(&mut self, msg: &[u8], on: &mut dyn FnMut(Event<'_>)) {
        self.pending.extend_from_slice(msg);
        let mut at = 0;
        loop {
            match frame(&self.pending[at..]) {
                Ok(Some((signo, kind, start, end))) => {
                    self.counters.packets += 1;
                    let payload = std::mem::take(&mut self.pending);
                    let p = &payload[at + start..at + end];
                    if kind == TYPE_META {
                        self.meta(signo, p, on);
                    } else {
                        self.data(signo, p, on);
                    }
                    self.pending = payload;
                    at += end;
                }
                Ok(None) => break,
                Err(why) => {
                    self.counters.desyncs += 1;
                    self.pending.clear();
                    at = 0;
                    on(Event::Desync(why));
                    break;
                }
            }
        }
        self.pending.drain(..at);
    }

    fn meta(&mut self, signo: u32, p: &[u8], on: &mut dyn FnMut(Event<'_>)) {
        if p.len() < 4 || u32::from_le_bytes([p[0], p[1], p[2], p[3]]) != META_MSGPACK {
            self.counters.bad_meta += 1;
            return;
        }
        let Ok(v) = msgpack::decode(&p[4..]) else {
            self.counters.bad_meta += 1;
            return;
        };
        let Some(method) = v.get("method").and_then(Value::as_str) else {
            self.counters.bad_meta += 1;
            return;
        };
        let params = v.get("params").unwrap_or(&Value::Null);
        let ids = |p: &Value| -> Option<Vec<String>> {
            p.get("signalIds")?
                .as_array()?
                .iter()
                .map(|s| s.as_str().map(str::to_string))
                .collect()
        };
        if signo == 0 {
            match method {
                "apiVersion" => {
                    let v = params.get("version").and_then(Value::as_str);
                    on(Event::ApiVersion(v.unwrap_or("").to_string()))
                }
                "init" => {
                    let Some(stream_id) = params.get("streamId").and_then(Value::as_str) else {
                        self.counters.bad_meta += 1;
                        return;
                    };
                    let http = params
                        .get("commandInterfaces")
                        .and_then(|c| c.get("jsonrpc-http"));
                    let http_port = http.and_then(|h| h.get("port")).and_then(|p| {
                        p.as_u64()
                            .or_else(|| p.as_str().and_then(|s| s.parse().ok()))
                            .and_then(|x| u16::try_from(x).ok())
                    });
                    let http_path = http
                        .and_then(|h| h.get("httpPath"))
                        .and_then(Value::as_str)
                        .unwrap_or("/")
                        .to_string();
                    on(Event::Init {
                        stream_id: stream_id.to_string(),
                        http_port,
                        http_path,
                    })
                }
                "available" | "unavailable" => match ids(params) {
                    Some(v) if method == "available" => on(Event::Available(v)),
                    Some(v) => on(Event::Unavailable(v)),
                    None => self.counters.bad_meta += 1,
                },
                // `alive`, `stream`, fill levels and future additions carry nothing rigmon needs.
                _ => {}
            }
            return;
        }
        match method {
            "subscribe" => {
                let Some(id) = params.get("signalId").and_then(Value::as_str) else {
                    self.counters.bad_meta += 1;
                    return;
                };
                self.signals.insert(
                    signo,
                    Bound {
                        id: id.to_string(),
                        desc: None,
                        next_index: 0,
                    },
                );
                on(Event::Subscribed {
                    signo,
                    id: id.to_string(),
                })
            }
            "unsubscribe" => {
                self.signals.remove(&signo);
                on(Event::Unsubscribed { signo })
            }
            "signal" => {
                let Some(b) = self.signals.get_mut(&signo) else {
                    self.counters.bad_meta += 1;
                    return;
                };
                match SignalDescription::from_params(params) {
                    Ok(d) => {
                        // A description only updates what it carries: a later `signal` without
                        // a `valueIndex` keeps the running index.
                        if params.get("valueIndex").is_some() || b.desc.is_none() {
                            b.next_index = d.value_index;
                        }
                        b.desc = Some(d);
                        on(Event::Described { signo })
                    }
                    Err(_) => self.counters.bad_meta += 1,
                }
            }
            _ => {}
        }
    }

    fn data(&mut self, signo: u32, p: &[u8], on: &mut dyn FnMut(Event<'_>)) {
        let Some(b) = self.signals.get_mut(&signo) else {
            self.counters.bad_data += 1;
            return;
        };
        let Some(desc) = b.desc.as_ref() else {
            self.counters.bad_data += 1;
            return;
        };
        let Some(dt) = desc.data_type else {
            self.counters.bad_data += 1;
            return;
        };
        match desc.rule {
            Rule::Explicit => {
                let size = dt.size();
                if p.len() % size != 0 {
                    self.counters.bad_data += 1;
                }
                self.values.clear();
                let (scale, offset) = (desc.scale, desc.offset);
                self.values.extend(
                    p.chunks_exact(size)
                        .map(|c| scale * dt.read_f64(c) + offset),
                );
                let first_index = b.next_index;
                b.next_index = b.next_index.wrapping_add(self.values.len() as u64);
                on(Event::Values {
                    signo,
                    first_index,
                    values: &self.values,
                })
            }
            Rule::Linear { .. } | Rule::Other(_) => {
                let pair = 8 + dt.size();
                let whole = p.len() / pair * pair;
                let rest = p.len() - whole;
                if rest != 0 && rest != 8 {
                    self.counters.bad_data += 1;
                }
                let linear = matches!(desc.rule, Rule::Linear { .. });
                for c in p[..whole].chunks_exact(pair) {
                    let index = u64::from_le_bytes(c[..8].try_into().unwrap_or([0; 8]));
                    match dt.read_ticks(&c[8..]) {
                        Some(value) if linear => on(Event::LinearStart {
                            signo,
                            index,
                            value,
                        }),
                        Some(_) => {}
                        None if linear => {
                            // A floating-point time axis: not a tick count rigmon can align.
                            self.counters.bad_data += 1;
                        }
                        None => {}
                    }
                }
            }
        }
    }
}

/// Build one packet (for tests, fake servers and the fuzz corpus).
pub fn encode_packet(signo: u32, kind: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(payload.len() + 8);
    if !payload.is_empty() && payload.len() < 256 {
        out.extend_from_slice(
            &((signo & 0xF_FFFF) | ((payload.len() as u32) << 20) | (kind << 28)).to_le_bytes(),
        );
    } else {
        out.extend_from_slice(&((signo & 0xF_FFFF) | (kind << 28)).to_le_bytes());
        out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(payload);
    out
}

/// A meta information packet from a JSON value (encoded as MessagePack).
pub fn encode_meta(signo: u32, meta: &Value) -> Vec<u8> {
    let mut p = META_MSGPACK.to_le_bytes().to_vec();
    p.extend_from_slice(&msgpack::encode(meta));
    encode_packet(signo, TYPE_META, &p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[derive(Debug, PartialEq)]
    enum Ev {
        Init(String, Option<u16>),
        Sub(u32, String),
        Desc(u32),
        Vals(u32, u64, Vec<f64>),
        Lin(u32, u64, i128),
        Desync,
        Other,
    }

    fn run(dec: &mut StreamDecoder, msgs: &[Vec<u8>]) -> Vec<Ev> {
        let mut got = Vec::new();
        for m in msgs {
            dec.feed(m, &mut |e| {
                got.push(match e {
                    Event::Init {
                        stream_id,
                        http_port,
                        ..
                    } => Ev::Init(stream_id, http_port),
                    Event::Subscribed { signo, id } => Ev::Sub(signo, id),
                    Event::Described { signo } => Ev::Desc(signo),
                    Event::Values {
                        signo,
                        first_index,
                        values,
                    } => Ev::Vals(signo, first_index, values.to_vec()),
                    Event::LinearStart {
                        signo,
                        index,
                        value,
                    } => Ev::Lin(signo, index, value),
                    Event::Desync(_) => Ev::Desync,
                    _ => Ev::Other,
                })
            });
        }
        got
    }

    fn reference_stream() -> Vec<u8> {
        let mut s = encode_meta(
            0,
            &json!({"method": "apiVersion", "params": {"version": "2.0.0"}}),
        );
        s.extend(encode_meta(
            0,
            &json!({"method": "init", "params": {"streamId": "s1",
            "commandInterfaces": {"jsonrpc-http": {"httpMethod": "POST", "httpPath": "/",
            "httpVersion": "1.1", "port": "7438"}}}}),
        ));
        s.extend(encode_meta(
            2,
            &json!({"method": "subscribe", "params": {"signalId": "AI0Time"}}),
        ));
        s.extend(encode_meta(
            2,
            &json!({"method": "signal", "params": {"definition": {
            "dataType": "int64", "linear": {"delta": 1000}, "name": "t",
            "resolution": {"denom": 1_000_000, "num": 1}, "rule": "linear"},
            "tableId": "AI0Time", "valueIndex": 0}}),
        ));
        s.extend(encode_meta(
            3,
            &json!({"method": "subscribe", "params": {"signalId": "AI0"}}),
        ));
        s.extend(encode_meta(
            3,
            &json!({"method": "signal", "params": {"definition": {
            "dataType": "real64", "name": "AI 1", "rule": "explicit",
            "unit": {"displayName": "V"}}, "tableId": "AI0Time", "valueIndex": 0}}),
        ));
        // Bytes captured from the SDK's reference server: time start at index 0.
        s.extend(encode_packet(
            2,
            TYPE_DATA,
            &hex("0000000000000000057fd64f0d610600"),
        ));
        let vals: Vec<u8> = (0..40)
            .flat_map(|i| (i as f64 * 0.5).to_le_bytes())
            .collect();
        s.extend(encode_packet(3, TYPE_DATA, &vals));
        s
    }

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    #[test]
    fn decodes_a_reference_stream_whole_and_split_anywhere() {
        let s = reference_stream();
        let whole = run(&mut StreamDecoder::new(), std::slice::from_ref(&s));
        assert_eq!(whole[0], Ev::Other);
        assert_eq!(whole[1], Ev::Init("s1".into(), Some(7438)));
        assert_eq!(whole[2], Ev::Sub(2, "AI0Time".into()));
        assert_eq!(whole[6], Ev::Lin(2, 0, 0x06610d4fd67f05));
        let Ev::Vals(3, 0, v) = &whole[7] else {
            panic!("{whole:?}")
        };
        assert_eq!((v.len(), v[3]), (40, 1.5));
        for cut in [1, 3, 4, 7, 100, s.len() - 1] {
            let mut dec = StreamDecoder::new();
            let parts = vec![s[..cut].to_vec(), s[cut..].to_vec()];
            assert_eq!(run(&mut dec, &parts), whole, "split at {cut}");
            assert_eq!(dec.counters().bad(), 0);
            assert_eq!(dec.buffered(), 0);
        }
    }

    #[test]
    fn value_index_runs_on_and_scaling_applies() {
        let mut dec = StreamDecoder::new();
        let mut s = encode_meta(
            5,
            &json!({"method": "subscribe", "params": {"signalId": "x"}}),
        );
        s.extend(encode_meta(
            5,
            &json!({"method": "signal", "params": {"definition": {
            "dataType": "int16", "rule": "explicit", "postScaling": {"scale": 0.5, "offset": 1.0}},
            "valueIndex": 10}}),
        ));
        s.extend(encode_packet(5, TYPE_DATA, &[2, 0, 4, 0]));
        s.extend(encode_packet(5, TYPE_DATA, &[6, 0, 1]));
        let got = run(&mut dec, &[s]);
        assert_eq!(got[2], Ev::Vals(5, 10, vec![2.0, 3.0]));
        assert_eq!(got[3], Ev::Vals(5, 12, vec![4.0]));
        assert_eq!(dec.counters().bad_data, 1, "odd byte counted");
    }

    #[test]
    fn damage_is_counted_and_a_broken_header_desyncs() {
        let mut dec = StreamDecoder::new();
        let mut s = encode_packet(9, TYPE_DATA, &[1, 2, 3]); // never subscribed
        s.extend(encode_packet(0, TYPE_META, &[2, 0, 0, 0, 0xc1])); // bad MessagePack
        s.extend(encode_packet(0, TYPE_META, &[1, 0, 0, 0, 0x80])); // JSON encoding
        s.extend(0xC000_0001u32.to_le_bytes()); // reserved bits
        s.extend([0u8; 20]);
        let got = run(&mut dec, &[s, reference_stream()]);
        assert_eq!(got[0], Ev::Desync);
        assert_eq!(dec.counters().bad_data, 1);
        assert_eq!(dec.counters().bad_meta, 2);
        assert_eq!(dec.counters().desyncs, 1);
        // The next message frames again.
        assert!(got.contains(&Ev::Init("s1".into(), Some(7438))));
        let mut huge = (TYPE_DATA << 28).to_le_bytes().to_vec();
        huge.extend(u32::MAX.to_le_bytes());
        assert_eq!(run(&mut dec, &[huge]), [Ev::Desync]);
    }
}
