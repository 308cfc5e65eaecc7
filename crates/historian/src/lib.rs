//! The fleet historian: `rigmon historian` joins the Zenoh mesh as a client, subscribes to
//! every rig's health and status and writes them to PostgreSQL in batched binary `COPY`
//! transactions ([`writer`]) into a schema a CM engineer recognises ([`migrations`]: the asset
//! tree, one typed row per window keyed on (point, window time), 1-minute aggregates,
//! partitions for retention, state-change events with the full JSON). Between the two a
//! bounded [`buffer`] with a disk [`spill`] rides out a slow or absent database; a [`recovery`]
//! tracker fetches what was missed from the daemons' recent history, and what neither could
//! keep is entered by point and seq range in the [`losses`] ledger. History goes back out
//! over Zenoh ([`history`], `rigmon history`), alarms are listed and acknowledged
//! ([`alarms`]). [`service`] wires it together.
//!
//! Data flows one way: Zenoh -> [`intake`] -> [`buffer`] -> [`service`]'s write loop
//! ([`admit`]: every message checked against its key, its names, time and seq) ->
//! [`writer`] -> PostgreSQL; [`history`] and [`alarms`] read it back.

pub mod admit;
pub mod alarms;
pub mod audit;
pub mod buffer;
pub mod columns;
pub mod config;
pub mod database;
pub mod history;
pub mod holes;
pub mod incoming;
pub(crate) mod intake;
pub(crate) mod latency;
pub mod losses;
pub mod migrations;
pub mod partitions;
pub mod pgpass;
pub(crate) mod point_config;
pub mod recovery;
pub mod recovery_plan;
pub mod row;
pub mod service;
pub mod spill;
pub mod status;
pub mod streams;
pub mod writer;
