//! rigmon core: everything the monitoring stream and the lab share.
//!
//! [`vocabulary`] is the lowest floor (the typed names: condition labels, quality flags,
//! acceleration units, Zenoh mode), with [`bearing`] kinematics, the in-memory [`recording`]
//! and [`usage`] (CPU time and load). On them: [`dsp`] (speed and shaft angle, envelope,
//! order spectra, quality), [`config`] (rig files), [`importers`] (files -> recordings),
//! [`analysis`] (the one analysis stage: the same code for training and serving), [`model`]
//! (inference), [`health`] (the window verdict and the state machine) and [`wire`] (the
//! health, status and spectrum messages, one definition each).
//! Lower modules never import higher ones (README "Floors"); nothing here names the daemon's
//! runtime, the lab or the historian, which sit on this crate.

pub mod analysis;
pub mod bearing;
pub mod config;
pub mod dsp;
pub mod health;
pub mod importers;
pub mod model;
pub mod recording;
pub mod usage;
pub mod vocabulary;
pub mod wire;
