//! The messages rigmon puts on the wire, one definition each: [`health`] (one per window),
//! [`status`] (what the daemon is doing and what it counted) and [`spectrum`] (a window's
//! envelope order spectrum). The daemon writes them (Zenoh, the MCAP recording, `--print`),
//! `rigmon watch`, the historian and `rigmon history` read them back through these types.

pub mod health;
pub mod spectrum;
pub mod status;
