//! `rigmon watch [<key-expr>]`: subscribe to health messages and print one line each (state,
//! confidence, probabilities, rpm, velocity zone, quality) for an operator's terminal, or the
//! raw JSON with `--json`. `--query` asks the daemons' queryables for the latest message.

use crate::health::message::HealthMessage;
use crate::publish::zenoh::{ZenohArgs, ZenohSettings, ZenohSubscriber, DEFAULT_PORT};
use anyhow::{bail, Result};
use std::io::Write;
use std::time::{Duration, Instant};

/// Arguments of `rigmon watch`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Key expression to subscribe to.
    #[arg(default_value = "rigmon/**/health")]
    pub key_expr: String,
    /// Print each message's JSON on one line.
    #[arg(long)]
    pub json: bool,
    /// Exit after this many messages.
    #[arg(long)]
    pub count: Option<u64>,
    /// Give up (exit with an error) when nothing arrives for this many seconds.
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
    /// Ask the queryables for the latest value instead of subscribing, then exit.
    #[arg(long)]
    pub query: bool,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

pub fn run(args: Args) -> Result<()> {
    // Without endpoints (or a zenoh config file), connect to a daemon on this machine (the
    // shipped config's endpoint); other flags (--user, --mode) apply on top.
    let local = ZenohSettings {
        connect: vec![format!("tcp/127.0.0.1:{DEFAULT_PORT}")],
        ..Default::default()
    };
    let settings = if args.zenoh.zenoh_config.is_some() || !args.zenoh.listen.is_empty() {
        args.zenoh.apply(ZenohSettings::default())
    } else {
        args.zenoh.apply(local)
    };
    let sub = ZenohSubscriber::open(&settings, &args.key_expr)?;
    tracing::info!(
        "subscribed to {} (zenoh {} connect {:?} listen {:?})",
        args.key_expr,
        settings.mode,
        settings.connect,
        settings.listen
    );
    let mut out = std::io::stdout().lock();
    if args.query {
        let replies = sub.get(
            &args.key_expr,
            Duration::from_secs_f64(args.timeout.unwrap_or(3.0)),
        )?;
        if replies.is_empty() {
            bail!(
                "no replies to {:?} (connected to {:?}); is a daemon running and reachable?",
                args.key_expr,
                settings.connect
            );
        }
        for (key, payload) in replies {
            print_one(&mut out, &key, &payload, args.json)?;
        }
        sub.close();
        return Ok(());
    }
    let mut n = 0u64;
    let mut last = Instant::now();
    let idle = args.timeout.map(Duration::from_secs_f64);
    loop {
        if args.count.is_some_and(|c| n >= c) {
            break;
        }
        match sub.recv_timeout(Duration::from_millis(200))? {
            Some((key, payload)) => {
                n += 1;
                last = Instant::now();
                print_one(&mut out, &key, &payload, args.json)?;
            }
            None => {
                if idle.is_some_and(|t| last.elapsed() >= t) {
                    bail!(
                        "nothing on {:?} for {:.0} s ({} messages so far; zenoh {} connect {:?} listen {:?}); is a daemon running and reachable?",
                        args.key_expr,
                        idle.unwrap_or_default().as_secs_f64(),
                        n,
                        settings.mode,
                        settings.connect,
                        settings.listen
                    );
                }
            }
        }
    }
    sub.close();
    Ok(())
}

fn print_one(out: &mut impl Write, key: &str, payload: &[u8], json: bool) -> Result<()> {
    if json {
        out.write_all(payload)?;
        out.write_all(b"\n")?;
    } else {
        match serde_json::from_slice::<HealthMessage>(payload) {
            Ok(m) => writeln!(out, "{}  {}", m.address(), m.line())?,
            // Status, spectrum or config messages: show them compactly as JSON.
            Err(_) => writeln!(out, "{key}  {}", String::from_utf8_lossy(payload))?,
        }
    }
    out.flush()?;
    Ok(())
}
