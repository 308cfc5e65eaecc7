//! `rigmon watch [<key-expr>]`: subscribe to health messages and print one line each (state,
//! confidence, probabilities, rpm, velocity zone, quality) for an operator's terminal, or the
//! raw JSON with `--json`. `--query` asks the daemons' queryables for the latest message.
//! Within [`UNREACHABLE_AFTER`] it says when nothing is reachable at the endpoint (and keeps
//! waiting); it never claims a connection it does not have. A window that did not come (a
//! gap in its point's seq) is fetched from the daemon's recent history and printed, or said
//! to be lost ([`super::watch_gaps`]).

use super::watch_gaps::MissedWindows;
use crate::publish::zenoh::{ZenohArgs, ZenohSettings, ZenohSubscriber, DEFAULT_PORT};
use crate::wire::health::HealthMessage;
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::io::Write;
use std::time::{Duration, Instant};

/// Say that nothing is reachable when no zenoh peer or router has connected after this long.
pub const UNREACHABLE_AFTER: Duration = Duration::from_secs(3);

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
    let reach = settings.reach();
    if args.query {
        return query(sub, &args, &reach);
    }
    let mut out = std::io::stdout().lock();
    let mut n = 0u64;
    let started = Instant::now();
    let mut last = started;
    let idle = args.timeout.map(Duration::from_secs_f64);
    // None: not known yet; Some(false): told the user nothing is reachable.
    let mut reachable: Option<bool> = None;
    let mut missed = MissedWindows::new();
    loop {
        if args.count.is_some_and(|c| n >= c) {
            break;
        }
        match sub.recv_timeout(Duration::from_millis(200))? {
            Some((key, payload)) => {
                last = Instant::now();
                if let Ok(m) = serde_json::from_slice::<HealthMessage>(&payload) {
                    for (k, p) in missed.before(&sub, &key, &m) {
                        n += 1;
                        print_one(&mut out, &k, &p, args.json)?;
                    }
                }
                n += 1;
                print_one(&mut out, &key, &payload, args.json)?;
            }
            None => {
                if idle.is_some_and(|t| last.elapsed() >= t) {
                    bail!(
                        "nothing on {:?} for {:.0} s ({} messages so far; zenoh {} connect {:?} listen {:?}, {} node(s) connected); is a daemon running and reachable?",
                        args.key_expr,
                        idle.unwrap_or_default().as_secs_f64(),
                        n,
                        settings.mode,
                        settings.connect,
                        settings.listen,
                        sub.connected()
                    );
                }
            }
        }
        reachable = report_reach(&sub, started, reachable, &reach);
    }
    if let Some(s) = missed.summary() {
        tracing::warn!("{s}");
    }
    sub.close();
    Ok(())
}

/// Tell the user, once, when nothing has connected [`UNREACHABLE_AFTER`] after the start,
/// and again when something does. Returns the new state.
fn report_reach(
    sub: &ZenohSubscriber,
    started: Instant,
    reachable: Option<bool>,
    reach: &str,
) -> Option<bool> {
    match reachable {
        Some(true) => reachable,
        _ if sub.connected() > 0 => {
            if reachable == Some(false) {
                tracing::info!("connected {reach}; waiting for messages");
            }
            Some(true)
        }
        None if started.elapsed() >= UNREACHABLE_AFTER => {
            tracing::warn!(
                "nothing reachable {reach}: no zenoh peer or router connected after {} s; is a daemon running and listening there? Still waiting",
                UNREACHABLE_AFTER.as_secs()
            );
            Some(false)
        }
        _ => reachable,
    }
}

/// Declarations reach a new session a moment after its connection: wait this long before the
/// first query, then ask again until something answers or the deadline passes.
const SETTLE: Duration = Duration::from_millis(500);

/// Ask the queryables under `key` until some answer, or `deadline`.
fn ask(sub: &ZenohSubscriber, key: &str, deadline: Instant) -> Result<Vec<(String, Vec<u8>)>> {
    std::thread::sleep(SETTLE.min(deadline.saturating_duration_since(Instant::now())));
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let replies = sub.get(key, left.max(Duration::from_millis(100)))?;
        if !replies.is_empty() || Instant::now() >= deadline {
            return Ok(replies);
        }
        std::thread::sleep(Duration::from_millis(250));
    }
}

/// `--query`: the latest value of every queryable under the key, from every daemon that
/// answers (two daemons answering for one key are both printed, and said to be two).
fn query(sub: ZenohSubscriber, args: &Args, reach: &str) -> Result<()> {
    let wait = Duration::from_secs_f64(args.timeout.unwrap_or(3.0));
    if !sub.wait_connected(wait) {
        bail!(
            "nothing reachable {reach}: no zenoh peer or router connected within {:.0} s, so nobody could answer {:?}; is a daemon running and listening there?",
            wait.as_secs_f64(),
            args.key_expr
        );
    }
    let replies = ask(&sub, &args.key_expr, Instant::now() + wait)?;
    if replies.is_empty() {
        bail!(
            "{} zenoh node(s) reachable {reach}, but none answered {:?}; is a rigmon daemon among them, and does the key match its rig, asset and point?",
            sub.connected(),
            args.key_expr
        );
    }
    let mut per_key: BTreeMap<&str, usize> = BTreeMap::new();
    for (key, _) in &replies {
        *per_key.entry(key.as_str()).or_default() += 1;
    }
    for (key, count) in per_key.iter().filter(|(_, c)| **c > 1) {
        tracing::warn!(
            "{count} daemons answered for {key}: more than one daemon publishes with the same machine id, asset and point; give each its own"
        );
    }
    let mut out = std::io::stdout().lock();
    for (key, payload) in &replies {
        print_one(&mut out, key, payload, args.json)?;
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
