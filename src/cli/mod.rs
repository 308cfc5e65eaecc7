//! One module per subcommand: its clap arguments (`Args`) and `run`, wiring the library
//! modules together. `main.rs` only parses and dispatches.

pub mod adapt;
pub mod alarms;
pub mod align;
pub mod bench;
pub mod calibrate;
pub mod dataset;
pub mod devices;
pub mod embed;
pub mod emulate;
pub mod evaluate;
pub mod features;
pub mod finetune;
pub mod historian;
pub mod history;
pub mod import;
pub mod inspect;
pub mod model;
pub(crate) mod read_args;
pub mod repair;
pub mod replay;
pub use rigmon_runtime::run;
pub mod same_file;
pub mod simulate;
pub mod train;
pub mod trend;
pub mod watch;
pub mod watch_gaps;
