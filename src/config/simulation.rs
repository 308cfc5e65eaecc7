//! The `[simulation]` section of a rig file: what the simulator needs to build this rig.
//! (Owned by the simulator; see `sim/`.)

use serde::{Deserialize, Serialize};

/// Simulator description of a rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SimulationConfig {}
