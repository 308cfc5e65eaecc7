//! The project's vocabulary: every concept that was a string written in many places, defined
//! once, typed, with its serde names. The lowest floor of the house: it imports nothing from
//! the crate, and every other room may import it.
//!
//! - [`unit`]: acceleration units (one table of accepted spellings) and a channel's unit;
//! - [`condition`]: the machine-condition labels a model classifies into;
//! - [`quality`]: the quality flags a health message carries;
//! - [`speed_source`]: where a window's shaft speed came from;
//! - [`zenoh_mode`]: the Zenoh session mode;
//! - [`error_component`]: the components of the calibration error (calibrate's concept, but
//!   both its error and its views name them, so they sit below both).

pub mod condition;
pub(crate) mod error_component;
pub mod quality;
pub mod speed_source;
pub mod unit;
pub(crate) mod zenoh_mode;

pub use condition::Condition;
pub use error_component::ErrorComponent;
pub use quality::QualityFlag;
pub use speed_source::SpeedSourceKind;
pub use unit::{AccelUnit, ChannelUnit};
pub use zenoh_mode::ZenohMode;
