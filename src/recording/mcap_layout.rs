//! The rigmon MCAP layout: how a [`Recording`](super::Recording) is stored in an MCAP file.
//! (Owned by the importers; documented in the README.)
