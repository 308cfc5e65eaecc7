//! Feature pipeline: low-pass, Hilbert envelope, computed order tracking from the tacho,
//! order spectrum, RMS per order bin. Plans and buffers are made once and reused.
//!
//! Layers, bottom up: [`speed_config`] and [`feature_settings`] (the rig file's `[speed]` and
//! `[features]` sections), [`tacho`] (analog tacho -> edges), [`speed`] (shaft angle/speed vs
//! time, pulse repair) and [`speed_estimate`] (speed from vibration), [`envelope`],
//! [`kurtogram`] (the band where the signal is most impulsive, for the envelope),
//! [`order_tracking`], [`order_spectrum`], [`features`] (the per-window pipeline) and
//! [`quality`] (flags), [`fault_band_ratios`] (the band levels at a bearing's fault orders);
//! [`resample`] (a whole stretch down to a lower rate, band-limited).
//! Windows of a stream or a whole recording are cut and given their speed in `analysis`.

pub(crate) mod biquad;
pub mod decimate;
pub mod envelope;
pub mod fault_band_ratios;
pub mod fault_family;
pub(crate) mod feature_settings;
pub mod features;
pub(crate) mod fft_len;
pub(crate) mod harmonic_bound;
pub(crate) mod harmonic_sum;
pub mod kurtogram;
pub mod order_spectrum;
pub(crate) mod order_tracking;
pub mod phase_smoother;
pub mod quality;
pub mod resample;
pub(crate) mod sliding_median;
pub mod speed;
pub(crate) mod speed_comb;
pub mod speed_config;
pub mod speed_estimate;
pub(crate) mod speed_hint;
pub(crate) mod speed_phase;
pub mod speed_tracker;
pub(crate) mod stored_speed;
pub mod synthetic;
pub mod tacho;

pub use feature_settings::FeatureSettings;
pub use features::{FeaturePipeline, FeatureWindow};
pub use quality::Quality;
pub use speed::SpeedTrack;
pub use speed_config::SpeedConfig;
