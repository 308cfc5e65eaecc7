//! The heavy tier of rigmon's integration tests: fuzzing the decoders, 20 s calibrations of
//! every generator case, adapt end to end, the historian with a real PostgreSQL and two sites
//! replicating into one central database. CI runs it with the fast tier (`cargo test
//! --all-features`); alone: `cargo test --all-features --test heavy`. One binary, so the
//! crate and its dependencies are linked once.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/estimate_rig.rs"]
mod estimate_rig;
#[path = "../common/femto_life.rs"]
mod femto_life;

mod adapt;
mod adapt_captures;
mod audit;
mod backpressure;
mod calibrate;
mod estimate_mode;
mod fleet;
mod fuzz;
mod historian;
mod looseness;
