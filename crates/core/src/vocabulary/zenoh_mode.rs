//! The Zenoh session mode (`peer`, `client`, `router`): the `mode` key of `[zenoh]` in the
//! daemon's and the historian's files, the `--mode` flag, and zenoh's own config value.

use serde::{Deserialize, Serialize};
use std::fmt;

/// How a Zenoh session joins the mesh.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum ZenohMode {
    /// Talks to other peers directly (the daemon's default).
    #[default]
    Peer,
    /// Talks through a router (needs a `connect` endpoint).
    Client,
    /// Routes for clients.
    Router,
}

impl ZenohMode {
    /// The name zenoh's config uses (the serde name).
    pub const fn as_str(self) -> &'static str {
        match self {
            ZenohMode::Peer => "peer",
            ZenohMode::Client => "client",
            ZenohMode::Router => "router",
        }
    }
}

impl fmt::Display for ZenohMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn serde_clap_and_display_use_one_name() {
        for m in [ZenohMode::Peer, ZenohMode::Client, ZenohMode::Router] {
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{m}\""));
            assert_eq!(serde_json::from_str::<ZenohMode>(&json).unwrap(), m);
            assert_eq!(ZenohMode::from_str(m.as_str(), false).unwrap(), m);
        }
        #[derive(Debug, Deserialize)]
        struct S {
            #[allow(dead_code)]
            mode: ZenohMode,
        }
        let e = toml::from_str::<S>("mode = \"hub\"")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("peer") && e.contains("router") && e.contains("line 1"),
            "{e}"
        );
    }
}
