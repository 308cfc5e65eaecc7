//! `rigmon history <key-expr> --since 24h [--until ..] [--json] [--png trend.png]`: a point's
//! stored windows from any machine on the Zenoh mesh, without SQL: a `get` with a
//! `_time=[..]` selector that historians answer. One line per window (time, point, state,
//! probabilities, speed, velocity and zone, quality), or the JSON, or a trend PNG of one point.
//! It ends by `--timeout` whatever happens: nothing reachable (nothing listening, credentials
//! refused), reachable but no historian answering, or the historian refusing, each said so.

use crate::health::iso20816::ZoneConfig;
use crate::plots::point_trend;
use crate::publish::time_range::{now_ns, parse_duration, TimeRange, PARAMETER};
use crate::publish::zenoh::{connected_nodes, error_text, ZenohArgs, ZenohSettings};
use crate::vocabulary::ZenohMode;
use crate::wire::health::HealthMessage;
use anyhow::{anyhow, bail, Result};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant, UNIX_EPOCH};
use zenoh::query::ConsolidationMode;
use zenoh::Wait;

/// Arguments of `rigmon history`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Key expression of the points, e.g. rigmon/lut-rig/shaft/nde or rigmon/**
    /// (`/health` is added when missing).
    pub key_expr: String,
    /// How far back: a duration (24h, 30m, 7d) or an RFC 3339 time.
    #[arg(long, default_value = "24h")]
    pub since: String,
    /// Up to: a duration ago or an RFC 3339 time (default: now).
    #[arg(long)]
    pub until: Option<String>,
    /// Print each window's JSON on one line.
    #[arg(long)]
    pub json: bool,
    /// Draw the trend of the (single) matching point to this PNG.
    #[arg(long, value_name = "PNG")]
    pub png: Option<PathBuf>,
    /// Seconds this command may take: connecting, then waiting for the historian's answer.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

/// A reply: the health message and the point's zone limits when the historian knows them.
#[derive(Deserialize)]
struct Reply {
    #[serde(flatten)]
    health: HealthMessage,
    #[serde(default)]
    iso_limits_mm_s: Option<Vec<f64>>,
}

/// `24h` (ago) or an RFC 3339 time, as ns since the epoch.
fn instant(s: &str, now: u64) -> Result<u64> {
    if let Ok(t) = humantime::parse_rfc3339_weak(s) {
        return Ok(t.duration_since(UNIX_EPOCH)?.as_nanos() as u64);
    }
    let d = parse_duration(s)
        .map_err(|e| anyhow!("{e}; or give an RFC 3339 time like 2026-11-26T00:00:00Z"))?;
    Ok(now.saturating_sub(d.as_nanos() as u64))
}

/// The key expression asked: `/health` added when missing.
pub fn health_key(k: &str) -> String {
    let k = k.trim_end_matches('/');
    if k.ends_with("/health") {
        k.to_string()
    } else {
        format!("{k}/health")
    }
}

pub fn run(args: Args) -> Result<()> {
    if !(args.timeout > 0.0 && args.timeout.is_finite()) {
        bail!("--timeout {}: a positive number of seconds", args.timeout);
    }
    let started = Instant::now();
    let timeout = Duration::from_secs_f64(args.timeout);
    let now = now_ns();
    let range = TimeRange {
        from_ns: Some(
            instant(&args.since, now).map_err(|e| anyhow!("--since {:?}: {e}", args.since))?,
        ),
        until_ns: args
            .until
            .as_deref()
            .map(|u| instant(u, now))
            .transpose()
            .map_err(|e| anyhow!("--until: {e}"))?,
    };
    let key = health_key(&args.key_expr);
    zenoh::key_expr::KeyExpr::try_from(key.clone())
        .map_err(|e| anyhow!("{key:?} is not a key expression: {e}"))?;
    let local = ZenohSettings {
        mode: ZenohMode::Client,
        connect: vec!["tcp/127.0.0.1:7447".into()],
        history_windows: 0,
        ..Default::default()
    };
    let settings = args.zenoh.apply(local);
    let session = settings.open_within(timeout)?;
    let selector = format!("{key}?{PARAMETER}={}", range.to_selector_value());
    let left = timeout
        .saturating_sub(started.elapsed())
        .max(Duration::from_millis(100));
    let replies = session
        .get(selector.clone())
        .consolidation(ConsolidationMode::None)
        .timeout(left)
        .wait()
        .map_err(|e| anyhow!("zenoh get {selector}: {}", error_text(&e)))?;
    let mut by_point: BTreeMap<String, BTreeMap<u64, (Vec<u8>, Reply)>> = BTreeMap::new();
    let mut refusals = Vec::new();
    while let Ok(r) = replies.recv() {
        match r.result() {
            Ok(s) => {
                let bytes = s.payload().to_bytes().into_owned();
                let reply: Reply = serde_json::from_slice(&bytes).map_err(|e| {
                    anyhow!("a reply on {} is not a health message: {e}", s.key_expr())
                })?;
                by_point
                    .entry(reply.health.address())
                    .or_default()
                    .insert(reply.health.window.end_ns, (bytes, reply));
            }
            Err(e) => refusals.push(error_text(&String::from_utf8_lossy(
                &e.payload().to_bytes(),
            ))),
        }
    }
    let nodes = connected_nodes(&session);
    let _ = session.close().wait();
    if !refusals.is_empty() {
        bail!("the historian refused: {}", refusals.join("; "));
    }
    if by_point.is_empty() {
        let what = format!("no history for {key} in {}", range.to_selector_value());
        return Err(nothing(&what, nodes, &settings, args.timeout));
    }
    print(&by_point, args.json)?;
    if let Some(png) = &args.png {
        draw(&by_point, png)?;
    }
    Ok(())
}

/// Why nothing came back: nothing reachable, or reachable but no historian answering.
fn nothing(what: &str, nodes: usize, settings: &ZenohSettings, timeout: f64) -> anyhow::Error {
    if nodes == 0 {
        return anyhow!(
            "{what}: nothing reachable {} (no zenoh router or peer connected within {timeout:.1} s; is one running there, and are --user/--password-file right?)",
            settings.reach()
        );
    }
    anyhow!(
        "{what}: {nodes} zenoh node(s) reachable {}, but no historian answered within {timeout:.1} s (is `rigmon historian` running on this mesh, and does it hold windows of these points in this range? With [zenoh.acl], is its user among the `historians`?)",
        settings.reach()
    )
}

fn print(by_point: &BTreeMap<String, BTreeMap<u64, (Vec<u8>, Reply)>>, json: bool) -> Result<()> {
    let mut out = std::io::stdout().lock();
    for windows in by_point.values() {
        for (end_ns, (bytes, r)) in windows {
            if json {
                out.write_all(bytes)?;
                out.write_all(b"\n")?;
            } else {
                let when =
                    humantime::format_rfc3339_millis(UNIX_EPOCH + Duration::from_nanos(*end_ns));
                writeln!(out, "{when}  {}  {}", r.health.address(), r.health.line())?;
            }
        }
    }
    out.flush()?;
    Ok(())
}

fn draw(
    by_point: &BTreeMap<String, BTreeMap<u64, (Vec<u8>, Reply)>>,
    png: &std::path::Path,
) -> Result<()> {
    if by_point.len() > 1 {
        bail!(
            "--png draws one point; the key expression matched {} ({}): narrow it",
            by_point.len(),
            by_point.keys().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    let windows = by_point.values().next().expect("one point");
    let own = windows
        .values()
        .find_map(|(_, r)| r.iso_limits_mm_s.clone())
        .filter(|l| l.len() == 3);
    let limits = match own {
        Some(l) => ([l[0], l[1], l[2]], true),
        None => (ZoneConfig::default().limits(), false),
    };
    let msgs: Vec<HealthMessage> = windows.values().map(|(_, r)| r.health.clone()).collect();
    point_trend::draw(png, &msgs, limits)?;
    eprintln!(
        "trend of {} windows written to {}",
        msgs.len(),
        png.display()
    );
    Ok(())
}
