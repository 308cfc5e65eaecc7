//! The daemon's own configuration file (`config/rigmon.toml`): rig file, source, model,
//! health policy, Zenoh and recording. (Owned by the daemon.)
