//! `rigmon devices <connection>`: list the signals an openDAQ LT streaming server offers
//! (id, name, sample rate, unit), so `[source.signals]` can be written without guessing.

use crate::acquire::opendaq::{list_signals, Endpoint};
use anyhow::Result;
use std::time::Duration;

/// Arguments of `rigmon devices`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The server: `daq.lt://HOST[:PORT]` (openDAQ LT streaming, default port 7414).
    pub connection: String,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// How long to wait for the server, seconds.
    #[arg(long, default_value_t = 5.0)]
    pub timeout: f64,
}

pub fn run(a: Args) -> Result<()> {
    let endpoint = Endpoint::parse(&a.connection)?;
    let timeout = Duration::from_secs_f64(a.timeout.clamp(0.1, 600.0));
    let found = list_signals(&endpoint, None, timeout)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&found)?);
    } else {
        print!("{}", found.table());
        println!(
            "\nMap rig channels to `waveform` signals in the daemon config, e.g.\n[source]\ntype = \"opendaq\"\nconnection = \"{}\"\n[source.signals]\nvertical = \"{}\"",
            found.connection,
            found
                .signals
                .iter()
                .find(|s| s.kind == "waveform")
                .map_or("AI0", |s| s.id.rsplit('/').next().unwrap_or(&s.id))
        );
    }
    Ok(())
}
