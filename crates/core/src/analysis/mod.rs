//! The analysis stage, shared by the daemon and by whole recordings (`rigmon features`,
//! `dataset`/`train`, `evaluate`): samples -> windows ([`windows`]) -> shaft speed per window
//! ([`speed_source`], the one place `[speed]` is interpreted) -> envelope order spectrum
//! features, quality flags and velocity RMS ([`stage`], [`velocity`]). [`recording`] feeds a
//! whole recording through the same windows as a stream, so training and serving compute
//! the same features bit for bit. [`rig_recipe`] plans the DSP for a rig file. Sits between
//! `dsp` (the maths) and `model`/`health`.

pub mod recording;
pub(crate) mod rig_recipe;
pub mod speed_source;
pub mod stage;
pub mod velocity;
pub mod windows;

pub use recording::{analyze_recording, extract_recording, extract_with_speed};
pub use speed_source::{whole_recording, whole_recording_checked, HintContradiction, SpeedSource};
pub use stage::{AnalysisStage, WindowAnalysis, WindowError};
pub use windows::{WindowSpec, WindowView, Windower};
