//! rigmon: on-line condition monitoring of rotating machinery.
//!
//! The `rigmon` command ([`cli`]) and the benchmarks ([`bench`]) over the workspace's crates,
//! whose modules are re-exported here under their usual names:
//! - `rigmon-core`: [`vocabulary`], [`bearing`], [`recording`], [`usage`], [`dsp`], [`config`],
//!   [`importers`], [`analysis`], [`model`], [`health`], [`wire`] (the health, status and
//!   spectrum messages);
//! - `rigmon-runtime`: [`acquire`] -> ... -> [`publish`], [`recorder`], wired by [`daemon`];
//! - `rigmon-lab`: [`sim`], [`train`], [`calibrate`], [`adapt`], [`evaluate`], [`manifest`],
//!   [`plots`], [`embed`];
//! - `rigmon-historian`: [`historian`], a fleet's health in PostgreSQL over the Zenoh mesh.
//!
//! Data flows one way: acquire -> analysis (on dsp) -> model -> health -> publish, recorder.

pub mod bench;
pub mod cli;

pub use rigmon_core::{
    analysis, bearing, config, dsp, health, importers, model, recording, usage, vocabulary, wire,
};
pub use rigmon_historian as historian;
pub use rigmon_lab::{adapt, calibrate, embed, evaluate, manifest, plots, sim, train};
pub use rigmon_runtime::{acquire, daemon, publish, recorder};
