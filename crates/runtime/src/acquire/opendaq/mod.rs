//! DeweSoft and other openDAQ devices: a live source over openDAQ **LT streaming** (the
//! WebSocket streaming protocol of the openDAQ SDK, port 7414), written in Rust from the
//! protocol specification (openDAQ/streaming-protocol-lt, `docs/openDAQ-streaming.md`
//! 1.3.0) and checked against the SDK's own reference server.
//!
//! - [`msgpack`]: the MessagePack reader for meta information.
//! - [`signal`]: what a `signal` meta information describes.
//! - [`protocol`]: the pure stream decoder (fuzzed).
//! - [`connection`]: WebSocket stream and HTTP JSON-RPC command interface.
//! - [`session`]: connect, learn the stream id and signals, subscribe.
//! - [`aligner`]: channels side by side on one sample clock.
//! - [`browse`]: list a server's signals (`rigmon devices`).
//! - [`source`]: the `[source] type = "opendaq"` source.

pub(crate) mod aligner;
pub(crate) mod browse;
pub mod connection;
pub(crate) mod msgpack;
pub mod protocol;
pub mod session;
pub mod signal;
pub mod source;

pub use browse::{list_signals, ServerSignals, SignalInfo};
pub use connection::Endpoint;
pub use source::{OpendaqSource, OpendaqSourceConfig};
