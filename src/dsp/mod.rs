//! Feature pipeline: low-pass, Hilbert envelope, computed order tracking from the tacho,
//! order spectrum, RMS per order bin. Plans and buffers are made once and reused.
//!
//! Layers, bottom up: [`tacho`] (analog tacho -> edges), [`speed`] (shaft angle/speed vs
//! time, pulse repair) and [`speed_estimate`] (speed from vibration), [`envelope`],
//! [`order_tracking`], [`order_spectrum`], [`features`] (the per-window pipeline),
//! [`quality`] (flags) and [`extract`] (whole recordings).

pub mod envelope;
pub mod extract;
pub mod features;
pub mod fft_len;
pub mod order_spectrum;
pub mod order_tracking;
pub mod quality;
pub mod speed;
pub mod speed_estimate;
pub mod synthetic;
pub mod tacho;

pub use extract::{extract_recording, extract_with_speed};
pub use features::{FeaturePipeline, FeatureWindow};
pub use quality::Quality;
pub use speed::SpeedTrack;
