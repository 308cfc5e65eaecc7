//! Simulator calibration against measured recordings (`rigmon calibrate`): simulate the
//! measured operating points ([`measured`], analysed at the simulator's output rate,
//! [`rate`]), compare physically meaningful views
//! ([`views`]: envelope and raw spectra, [`fault_peaks`], [`shaft_orders`],
//! [`fractional_orders`] with its [`half_orders`], [`impacts`], [`modes`] (a loose housing's
//! landings: [`landing_comb`], their mode's damping [`ring_width`]), with order
//! [`stats`]) with one scalar error of named components ([`error`]), locate the residual
//! ([`locate`]) and name its usual causes ([`trace`]), attribute it greedily to catalog
//! effects ([`catalog`], [`search`], [`fit`]; a speed fluctuation around the line the
//! measured speed spectra show, [`speed_line`]) confirmed on a held-out part, and report
//! ([`report`], [`plots`]).

pub mod catalog;
pub mod error;
pub mod fault_peaks;
pub mod fit;
pub mod fractional_orders;
pub mod half_orders;
pub mod impacts;
pub mod landing_comb;
pub mod locate;
pub mod measured;
pub mod modes;
pub mod plots;
pub mod rate;
pub mod report;
pub mod ring_width;
pub mod search;
pub mod shaft_orders;
pub(crate) mod speed_line;
pub mod stats;
pub(crate) mod timing;
pub(crate) mod trace;
pub mod views;
