//! Publishing: where health, spectra and status leave the process. [`zenoh`] holds the Zenoh
//! session settings (config file and the command-line flags zenoh's own tools use), the
//! publisher (topics, liveliness token, read-only queryables) and the subscriber `watch` uses.
//!
//! Key expressions: `rigmon/<rig>/<asset>/<point>/{health,spectrum,status,config}` and the
//! liveliness token `rigmon/<rig>/<asset>/<point>/alive`; [`recent`] keeps the last health
//! messages for late joiners on `.../recent`; [`time_range`] reads `_time=[..]` selectors.

pub mod access;
pub mod recent;
pub mod time_range;
pub mod zenoh;
