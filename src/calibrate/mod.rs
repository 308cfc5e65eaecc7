//! Simulator calibration against measured recordings (`rigmon calibrate`): simulate the
//! measured operating points ([`measured`]), compare physically meaningful views
//! ([`views`]) with one scalar error of named components ([`error`]), locate the residual
//! ([`locate`]), attribute it greedily to catalog effects ([`catalog`], [`search`],
//! [`fit`]) confirmed on a held-out part, and report ([`report`], [`plots`]).

pub mod catalog;
pub mod error;
pub mod fit;
pub mod locate;
pub mod measured;
pub mod plots;
pub mod report;
pub mod search;
pub mod views;
