//! Where a window's shaft speed came from (`tacho`, `edges`, `fixed`, `recording`, `estimate`,
//! `simulator`): the `source` key of the rig file's `[speed]`, the `speed_source` of a features
//! window, a health message, the daemon's status and the historian's column, one name each.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Where a shaft speed came from.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum SpeedSourceKind {
    /// An analog tacho channel, its edges detected by rigmon.
    Tacho,
    /// Tacho edge times delivered by the source (a DAQ adapter, an MCAP edges channel).
    Edges,
    /// A fixed speed the rig file states (checked against the vibration).
    Fixed,
    /// The speed stored in the recording (or, failing that, its edges or its vibration).
    Recording,
    /// The speed read from the vibration by the streaming tracker.
    #[default]
    Estimate,
    /// The simulator's own speed (a simulated recording's known profile).
    Simulator,
}

impl SpeedSourceKind {
    /// Every kind, in the order the docs list them.
    pub const ALL: [SpeedSourceKind; 6] = [
        SpeedSourceKind::Tacho,
        SpeedSourceKind::Edges,
        SpeedSourceKind::Fixed,
        SpeedSourceKind::Recording,
        SpeedSourceKind::Estimate,
        SpeedSourceKind::Simulator,
    ];

    /// The serde name (as in the rig file, JSON messages and the historian's column).
    pub const fn as_str(self) -> &'static str {
        match self {
            SpeedSourceKind::Tacho => "tacho",
            SpeedSourceKind::Edges => "edges",
            SpeedSourceKind::Fixed => "fixed",
            SpeedSourceKind::Recording => "recording",
            SpeedSourceKind::Estimate => "estimate",
            SpeedSourceKind::Simulator => "simulator",
        }
    }
}

impl fmt::Display for SpeedSourceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.as_str())
    }
}

impl FromStr for SpeedSourceKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SpeedSourceKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = SpeedSourceKind::ALL.iter().map(|k| k.as_str()).collect();
                format!("unknown speed source {s:?}: one of {}", names.join(", "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serde_display_and_parse_use_one_name() {
        for k in SpeedSourceKind::ALL {
            let json = serde_json::to_string(&k).unwrap();
            assert_eq!(json, format!("\"{k}\""));
            assert_eq!(serde_json::from_str::<SpeedSourceKind>(&json).unwrap(), k);
            assert_eq!(k.as_str().parse::<SpeedSourceKind>().unwrap(), k);
        }
        let e = "hall".parse::<SpeedSourceKind>().unwrap_err();
        assert!(e.contains("\"hall\"") && e.contains("estimate"), "{e}");
    }
}
