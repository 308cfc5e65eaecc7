//! The fast tier of rigmon's integration tests: everything a developer runs before each
//! commit, in a few minutes (`cargo test --all-features --lib --test fast`). One binary, so the
//! crate and its dependencies are linked once. Each module is one area (its own module doc says
//! what it checks); the heavy tier (`tests/heavy`) holds fuzzing, long calibrations, adapt end
//! to end and the PostgreSQL historian.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/daemon_harness.rs"]
mod daemon_harness;
#[path = "../common/estimate_rig.rs"]
mod estimate_rig;
#[path = "../common/femto_life.rs"]
mod femto_life;
#[path = "../common/wrong_shape.rs"]
mod wrong_shape;

mod access;
mod acquire;
mod daemon;
mod dsp;
mod early_warning;
mod estimate_mode;
mod faults;
mod features_identity;
mod house;
mod importers;
mod impulsive;
mod looseness;
mod model;
mod novel_faults;
mod opendaq;
mod real_files;
mod recent_history;
mod rule_agreement;
mod service_binary;
mod sim;
mod snapshots;
mod speed_comb_sim;
mod speed_cues;
mod speed_cwru;
mod speed_free;
mod speed_hint;
mod speed_joint;
mod watch_gaps;
