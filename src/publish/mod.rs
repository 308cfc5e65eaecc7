//! Publishing: where health, spectra and status leave the process. [`zenoh`] holds the Zenoh
//! session settings (config file and the command-line flags zenoh's own tools use), the
//! publisher (topics, liveliness token, read-only queryables) and the subscriber `watch` uses.
//!
//! Key expressions: `rigmon/<rig>/<asset>/<point>/{health,spectrum,status,config}` and the
//! liveliness token `rigmon/<rig>/<asset>/<point>/alive`.

pub mod access;
pub mod zenoh;
