//! rigmon's runtime: the monitoring daemon and what it needs beyond the core.
//!
//! [`acquire`] (sources: serial, CAN, sound card, openDAQ, file replay) -> the core's analysis,
//! model and health -> [`publish`] (Zenoh) and [`recorder`] (MCAP); [`daemon`] wires them and
//! [`run`] is the `run` command (`rigmon run` and the lean service binary `rigmon-daemon`).
//! No PostgreSQL client, no plotting and no lab code is linked from here.

pub mod acquire;
pub mod daemon;
pub mod publish;
pub mod recorder;
pub mod run;

use rigmon_core::{
    analysis, bearing, config, dsp, health, importers, model, recording, vocabulary, wire,
};
