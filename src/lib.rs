//! rigmon: on-line condition monitoring of rotating machinery.
//!
//! Data flows one way: [`acquire`] (sources) -> [`analysis`] (windows, speed and features,
//! built on [`dsp`]; the same code for training and serving) -> [`model`] (inference)
//! -> [`health`] (state machine) -> [`publish`], [`recorder`] (sinks). [`sim`] and [`train`]
//! sit beside the stream and produce models; [`calibrate`] fits the simulator to measured
//! recordings (residual views, effect catalog, held-out acceptance, calibrated rig file);
//! [`adapt`] chains calibration, simulation and training for one measured machine.
//! [`historian`] keeps a fleet's health in PostgreSQL, fed over the Zenoh mesh.
//! [`vocabulary`] is the lowest floor: the typed names (condition labels, quality flags,
//! acceleration units, Zenoh mode) every other module shares.
//! Lower modules never import higher ones.

pub mod acquire;
pub mod adapt;
pub mod analysis;
pub mod bearing;
pub mod bench;
pub mod calibrate;
pub mod cli;
pub mod config;
pub mod daemon;
pub mod dsp;
pub mod embed;
pub mod evaluate;
pub mod health;
pub mod historian;
pub mod importers;
pub mod manifest;
pub mod model;
pub(crate) mod plots;
pub mod publish;
pub mod recorder;
pub mod recording;
pub mod sim;
pub mod train;
pub(crate) mod usage;
pub mod vocabulary;
