//! Zenoh: session settings (`[zenoh]` in the daemon config, or `--mode/--connect/--listen/
//! --zenoh-config` on the command line, as zenoh's own tools take them), the daemon's
//! publisher with its liveliness token and read-only queryables, and a subscriber.
//!
//! Safe defaults: peer mode, listening only where told, multicast scouting off. A session
//! with `connect` endpoints keeps retrying them forever, so a restarted router is picked up
//! again without restarting rigmon.
//!
//! The fleet sees itself: each daemon holds a liveliness token `<base>/alive/<session id>`.
//! A daemon refuses to start when another one already holds a token under its own base key
//! (two daemons with one machine id would interleave their health on one key), and announces
//! one that appears later (an error in the log, `publish.duplicates` in the status).
//! Endpoints are checked before a session opens (ports in range, listen ports free), and
//! zenoh's errors reach the user without the source paths of the machine that built zenoh.
//!
//! Health and status are published with [`FLEET_CONGESTION`] (`Drop`), see there for why.

use crate::vocabulary::ZenohMode;
use crate::wire::status::PublishStats;
use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

pub use super::access::{AclSettings, AuthSettings, TlsSettings};

/// The fleet's congestion policy for health and status: `Drop`, never `Block`.
///
/// In Zenoh the two differ only in what happens when a transport's queue stays full
/// (a slow subscriber, e.g. a historian behind a busy database, and the router's queue to it):
/// `Drop` drops that one message after `wait_before_drop` (1 ms); `Block` waits up to
/// `wait_before_close` (5 s), stalling the router's receive threads for every other
/// subscriber meanwhile, and then **closes the transport**, losing everything queued in it
/// while `put` had returned Ok (eclipse-zenoh/zenoh#2587, #1876, #2709; measured in the
/// historian bench, docs/fleet.md). A dropped window is a gap in its point's `seq` that the
/// historian sees with the point's next window and fetches from the daemon's recent history
/// (`[zenoh] history_windows`), or counts as lost with its seq range: nothing goes silently.
/// Status is the latest state and repeats. All messages of one priority share one queue
/// (eclipse-zenoh/zenoh#2584), so one `Block` message on the path would bring the close back.
pub const FLEET_CONGESTION: CongestionControl = CongestionControl::Drop;

/// Default TCP port rigmon listens on (loopback only in the shipped config).
pub const DEFAULT_PORT: u16 = 7448;

/// `[zenoh]` section of the daemon config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZenohSettings {
    /// Publish at all (false = health only goes to stdout/recording).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// `peer` (default), `client` or `router`.
    #[serde(default)]
    pub mode: ZenohMode,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7448`.
    #[serde(default)]
    pub listen: Vec<String>,
    /// Endpoints to connect to (routers or peers), e.g. `tcp/127.0.0.1:7447`.
    #[serde(default)]
    pub connect: Vec<String>,
    /// Multicast scouting (off by default; turn on only on a plant network that wants it).
    #[serde(default)]
    pub multicast_scouting: bool,
    /// A zenoh JSON5 config file used as the base (TLS, access control, ...). The keys above
    /// are applied on top of it, except `multicast_scouting`, which the file then decides.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config_file: Option<PathBuf>,
    /// First key segment (default `rigmon`).
    #[serde(default = "default_prefix")]
    pub key_prefix: String,
    /// User/password authentication (`[zenoh.auth]`).
    #[serde(default, skip_serializing_if = "AuthSettings::is_empty")]
    pub auth: AuthSettings,
    /// TLS certificates (`[zenoh.tls]`, with the `tls` feature).
    #[serde(default, skip_serializing_if = "TlsSettings::is_empty")]
    pub tls: TlsSettings,
    /// Access-control list (`[zenoh.acl]`).
    #[serde(default, skip_serializing_if = "AclSettings::is_empty")]
    pub acl: AclSettings,
    /// Health messages kept for late joiners on `<base>/recent` (a historian catching up
    /// after a restart); 0 turns the cache off. See [`super::recent`].
    #[serde(default = "default_history_windows")]
    pub history_windows: usize,
    /// How long a message waits for room in a full send queue before it is dropped (zenoh's
    /// `wait_before_drop`; None: zenoh's 1 ms, so a live daemon never stalls its acquisition
    /// behind a slow link). Not a config key: `rigmon replay` sets [`REPLAY_WAIT_BEFORE_DROP`].
    #[serde(skip)]
    pub wait_before_drop: Option<Duration>,
}

/// A replay's [`ZenohSettings::wait_before_drop`]: a file can wait for its slowest
/// subscriber. At `--speed max` on a loaded machine the send queue's thread may not run for
/// more than zenoh's 1 ms, and windows were dropped in the middle of a replay (3 to 6 of 15
/// under three busy loops on 2 cores); a drop is still possible (a subscriber stuck for this
/// long), and is then the seq gap every dropped window is.
pub const REPLAY_WAIT_BEFORE_DROP: Duration = Duration::from_millis(500);

fn default_history_windows() -> usize {
    super::recent::DEFAULT_WINDOWS
}

fn yes() -> bool {
    true
}
fn default_prefix() -> String {
    "rigmon".into()
}

impl Default for ZenohSettings {
    fn default() -> Self {
        ZenohSettings {
            enabled: true,
            mode: ZenohMode::default(),
            listen: Vec::new(),
            connect: Vec::new(),
            multicast_scouting: false,
            config_file: None,
            key_prefix: default_prefix(),
            auth: AuthSettings::default(),
            tls: TlsSettings::default(),
            acl: AclSettings::default(),
            history_windows: default_history_windows(),
            wait_before_drop: None,
        }
    }
}

/// Zenoh flags shared by `run`, `replay` and `watch` (the names zenoh's own tools use).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ZenohArgs {
    /// Zenoh session mode: peer, client or router.
    #[arg(long, value_enum)]
    pub mode: Option<ZenohMode>,
    /// Endpoint to connect to (repeatable), e.g. tcp/127.0.0.1:7448.
    #[arg(short = 'e', long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Endpoint to listen on (repeatable), e.g. tcp/127.0.0.1:7448.
    #[arg(short = 'l', long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// A zenoh JSON5 config file (the flags above are applied on top of it).
    #[arg(long = "zenoh-config", value_name = "JSON5")]
    pub zenoh_config: Option<PathBuf>,
    /// User name for zenoh's user/password authentication (with --password-file).
    #[arg(long, value_name = "NAME", requires = "password_file")]
    pub user: Option<String>,
    /// File whose first line is the password for --user.
    #[arg(long, value_name = "FILE", requires = "user")]
    pub password_file: Option<PathBuf>,
}

impl ZenohArgs {
    /// True when any zenoh flag was given.
    pub fn any(&self) -> bool {
        self.mode.is_some()
            || !self.connect.is_empty()
            || !self.listen.is_empty()
            || self.zenoh_config.is_some()
            || self.user.is_some()
    }

    /// Apply the flags over `base` (flags win; given endpoint lists replace the base's).
    pub fn apply(&self, mut base: ZenohSettings) -> ZenohSettings {
        if let Some(m) = self.mode {
            base.mode = m;
        }
        if !self.connect.is_empty() {
            base.connect = self.connect.clone();
        }
        if !self.listen.is_empty() {
            base.listen = self.listen.clone();
        }
        if let Some(c) = &self.zenoh_config {
            base.config_file = Some(c.clone());
        }
        if let (Some(u), Some(p)) = (&self.user, &self.password_file) {
            base.auth.user = Some(u.clone());
            base.auth.password_file = Some(p.clone());
        }
        if self.any() {
            base.enabled = true;
        }
        base
    }
}

impl ZenohSettings {
    /// Check what can be checked without opening a session.
    pub fn validate(&self) -> Result<()> {
        if self.mode == ZenohMode::Client && self.connect.is_empty() && self.config_file.is_none() {
            bail!("zenoh.mode = \"client\" needs at least one zenoh.connect endpoint (a router), e.g. tcp/127.0.0.1:7447");
        }
        if self.key_prefix.is_empty()
            || self.key_prefix.contains(['*', '$', '#', '?', ' '])
            || self.key_prefix.ends_with('/')
        {
            bail!(
                "zenoh.key_prefix = {:?}: must be a plain key (no * $ # ? spaces, no trailing /)",
                self.key_prefix
            );
        }
        super::access::validate(&self.auth, &self.tls, &self.acl)?;
        for (list, e) in self
            .listen
            .iter()
            .map(|e| ("listen", e))
            .chain(self.connect.iter().map(|e| ("connect", e)))
        {
            let port = endpoint_port(e)?;
            if list == "connect" && port == Some(0) {
                bail!("zenoh.connect {e:?}: port 0 names no peer; give the port it listens on, e.g. tcp/127.0.0.1:7448");
            }
        }
        Ok(())
    }

    /// Every TCP listen endpoint with a numeric address and port can be bound now (its port
    /// is free, the address is this machine's). The error says which endpoint and why.
    pub fn check_listen_ports(&self) -> Result<()> {
        for e in &self.listen {
            let Some(addr) = socket_addr(e) else {
                continue;
            };
            if addr.port() == 0 {
                continue;
            }
            if let Err(err) = std::net::TcpListener::bind(addr) {
                let hint = match err.kind() {
                    std::io::ErrorKind::AddrInUse => {
                        "another program (another rigmon?) already listens there; stop it or pick another port"
                    }
                    std::io::ErrorKind::AddrNotAvailable => {
                        "the address is not one of this machine's"
                    }
                    std::io::ErrorKind::PermissionDenied => {
                        "ports below 1024 need privileges; use a higher port"
                    }
                    _ => "check the address and port",
                };
                bail!("zenoh.listen {e:?}: cannot listen there ({err}); {hint}");
            }
        }
        Ok(())
    }

    /// Build the zenoh config: the JSON5 file (if any), then mode, endpoints and scouting.
    pub fn zenoh_config(&self) -> Result<zenoh::Config> {
        self.validate()?;
        let mut c = match &self.config_file {
            Some(p) => zenoh::Config::from_file(p).map_err(|e| {
                anyhow!(
                    "cannot use zenoh config {}: {}",
                    p.display(),
                    error_text(&e)
                )
            })?,
            None => zenoh::Config::default(),
        };
        let set = |c: &mut zenoh::Config, key: &str, value: String| -> Result<()> {
            c.insert_json5(key, &value)
                .map_err(|e| anyhow!("zenoh config {key} = {value}: {}", error_text(&e)))
        };
        set(&mut c, "mode", format!("\"{}\"", self.mode))?;
        // Always set listen explicitly: an empty zenoh config listens on every interface.
        if self.config_file.is_none() || !self.listen.is_empty() {
            set(
                &mut c,
                "listen/endpoints",
                serde_json::to_string(&self.listen)?,
            )?;
        }
        if self.config_file.is_none() || !self.connect.is_empty() {
            set(
                &mut c,
                "connect/endpoints",
                serde_json::to_string(&self.connect)?,
            )?;
        }
        if self.config_file.is_none() {
            set(
                &mut c,
                "scouting/multicast/enabled",
                self.multicast_scouting.to_string(),
            )?;
            // Keep retrying configured endpoints forever (router restarts), never give up.
            set(&mut c, "connect/timeout_ms", "-1".into())?;
            set(&mut c, "connect/exit_on_failure", "false".into())?;
        }
        if let Some(w) = self.wait_before_drop {
            set(
                &mut c,
                "transport/link/tx/queue/congestion_control/drop/wait_before_drop",
                w.as_micros().clamp(1, i64::MAX as u128).to_string(),
            )?;
        }
        super::access::apply(&mut c, &self.key_prefix, &self.auth, &self.tls, &self.acl)?;
        Ok(c)
    }

    /// Open a session.
    pub fn open(&self) -> Result<zenoh::Session> {
        let config = self.zenoh_config()?;
        zenoh::open(config).wait().map_err(|e| {
            let text = error_text(&e);
            let hint = if text.contains("in use") {
                "; is the port already in use (another rigmon?)"
            } else {
                ""
            };
            anyhow!(
                "cannot open a zenoh session (mode {}, listen {:?}, connect {:?}): {text}{hint}",
                self.mode,
                self.listen,
                self.connect
            )
        })
    }

    /// Open a session for a one-shot command (`rigmon history`): connecting gives up after
    /// `within` instead of retrying forever, and the error says that nothing was reachable
    /// (nothing listening, or the credentials refused) rather than hanging.
    pub fn open_within(&self, within: Duration) -> Result<zenoh::Session> {
        let mut c = self.zenoh_config()?;
        if !self.connect.is_empty() {
            let ms = within.as_millis().clamp(1, i64::MAX as u128).to_string();
            for (key, value) in [
                ("connect/timeout_ms", ms),
                ("connect/exit_on_failure", "true".into()),
            ] {
                c.insert_json5(key, &value)
                    .map_err(|e| anyhow!("zenoh config {key} = {value}: {}", error_text(&e)))?;
            }
        }
        zenoh::open(c).wait().map_err(|e| {
            anyhow!(
                "nothing reachable {}: no zenoh router or peer accepted a connection within {:.1} s ({}); is one running and listening there, and are --user/--password-file right?",
                self.reach(),
                within.as_secs_f64(),
                error_text(&e)
            )
        })
    }

    /// Where a session with these settings looks for others, for messages: `at
    /// tcp/127.0.0.1:7448`, `on listen [...]`.
    pub fn reach(&self) -> String {
        match (&self.connect[..], &self.listen[..], &self.config_file) {
            ([], [], Some(f)) => format!("with zenoh config {}", f.display()),
            ([], [], None) => "anywhere (no endpoint given)".into(),
            ([], listen, _) => format!("on listen {}", listen.join(", ")),
            (connect, _, _) => format!("at {}", connect.join(", ")),
        }
    }
}

/// A zenoh error as text, without the ` at <path>.rs:<line>` zenoh appends (the source path
/// of the machine that built it means nothing to a user).
pub fn error_text(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find(" at ") {
        let after = &rest[i + 4..];
        match source_location_len(after) {
            Some(n) => {
                out.push_str(&rest[..i]);
                rest = &after[n..];
            }
            None => {
                out.push_str(&rest[..i + 4]);
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// The length of a `<path>.rs:<line>` (and the full stop after it) at the start of `s`.
fn source_location_len(s: &str) -> Option<usize> {
    let word = &s[..s.find(char::is_whitespace).unwrap_or(s.len())];
    let rs = word.find(".rs:")?;
    let digits = word[rs + 4..]
        .bytes()
        .take_while(u8::is_ascii_digit)
        .count();
    if digits == 0 {
        return None;
    }
    let end = rs + 4 + digits;
    Some(if word[end..].starts_with('.') {
        end + 1
    } else {
        end
    })
}

/// The port of an endpoint whose address is `host:port` (`tcp/`, `tls/`, `udp/`, `quic/`),
/// checked to be a port; None for other kinds (unix sockets). Errors say how to write it.
fn endpoint_port(e: &str) -> Result<Option<u16>> {
    let ep = e.parse::<zenoh::config::EndPoint>().map_err(|err| {
        anyhow!(
            "zenoh endpoint {e:?} is not valid ({}); write it like tcp/127.0.0.1:7448",
            error_text(&err)
        )
    })?;
    if !matches!(ep.protocol().as_str(), "tcp" | "tls" | "udp" | "quic") {
        return Ok(None);
    }
    let address = ep.address();
    let Some((_, port)) = address.as_str().rsplit_once(':') else {
        bail!("zenoh endpoint {e:?} has no port; write it like tcp/127.0.0.1:7448");
    };
    match port.parse::<u16>() {
        Ok(p) => Ok(Some(p)),
        Err(_) => bail!(
            "zenoh endpoint {e:?}: port {port:?} is not a port number (0 to 65535); write it like tcp/127.0.0.1:7448"
        ),
    }
}

/// The socket address of a `tcp/` or `tls/` endpoint with a numeric address.
fn socket_addr(e: &str) -> Option<std::net::SocketAddr> {
    let ep = e.parse::<zenoh::config::EndPoint>().ok()?;
    if !matches!(ep.protocol().as_str(), "tcp" | "tls") {
        return None;
    }
    ep.address().as_str().parse().ok()
}

impl ZenohSettings {
    /// `<prefix>/<rig>/<asset>/<point>`.
    pub fn base_key(&self, rig: &str, asset: &str, point: &str) -> String {
        format!("{}/{rig}/{asset}/{point}", self.key_prefix)
    }
}

/// How long a daemon with `connect` endpoints waits for one of them before it looks for
/// another daemon under its base key (it starts anyway when none answers).
const CONNECT_GRACE: Duration = Duration::from_secs(2);

/// How long the look for another daemon's liveliness token waits for replies.
const LIVELINESS_QUERY: Duration = Duration::from_secs(1);

/// The zenoh peers and routers a session is connected to.
pub fn connected_nodes(session: &zenoh::Session) -> usize {
    let info = session.info();
    info.peers_zid().wait().count() + info.routers_zid().wait().count()
}

/// Wait up to `timeout` until the session is connected to some peer or router.
fn wait_connected(session: &zenoh::Session, timeout: Duration) -> bool {
    let deadline = Instant::now() + timeout;
    loop {
        if connected_nodes(session) > 0 {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Liveliness tokens under `<base>/alive` (of any daemon, this rigmon's form `<base>/alive/<zid>`
/// and the older `<base>/alive`).
fn alive_tokens(session: &zenoh::Session, base: &str) -> Result<Vec<String>> {
    let replies = session
        .liveliness()
        .get(format!("{base}/alive/**"))
        .timeout(LIVELINESS_QUERY)
        .wait()
        .map_err(|e| anyhow!("zenoh liveliness query {base}/alive/**: {}", error_text(&e)))?;
    let mut keys = Vec::new();
    while let Ok(r) = replies.recv() {
        if let Ok(s) = r.result() {
            keys.push(s.key_expr().to_string());
        }
    }
    Ok(keys)
}

/// The daemon's Zenoh face: three publishers, a liveliness token and two queryables
/// (latest health, running config), all under one base key.
pub struct ZenohPublisher {
    session: zenoh::Session,
    base: String,
    health: zenoh::pubsub::Publisher<'static>,
    spectrum: zenoh::pubsub::Publisher<'static>,
    status: zenoh::pubsub::Publisher<'static>,
    latest_health: Arc<Mutex<Option<Vec<u8>>>>,
    running_config: Arc<Mutex<Vec<u8>>>,
    queries: Arc<std::sync::atomic::AtomicU64>,
    duplicates: Arc<std::sync::atomic::AtomicU64>,
    stats: PublishStats,
    recent: Option<super::recent::RecentHistory>,
    _token: zenoh::liveliness::LivelinessToken,
    _watch: zenoh::pubsub::Subscriber<()>,
    _queryables: Vec<zenoh::query::Queryable<()>>,
}

impl ZenohPublisher {
    /// Open the session and declare everything under `base` (see [`ZenohSettings::base_key`]).
    /// `config_json` is what the `config` queryable answers. Refused when another daemon
    /// already publishes under `base`.
    pub fn open(settings: &ZenohSettings, base: &str, config_json: Vec<u8>) -> Result<Self> {
        let session = settings.open()?;
        if !settings.connect.is_empty() || settings.config_file.is_some() {
            // Connections open in the background: give them a moment, so that the look for
            // another daemon below sees the network (start anyway when nothing answers).
            wait_connected(&session, CONNECT_GRACE);
        }
        if let Some(other) = alive_tokens(&session, base)?.into_iter().next() {
            let _ = session.close().wait();
            bail!(
                "another rigmon already publishes as {base} (its liveliness token {other} is alive, reachable {}); two daemons with one machine id would interleave their health on one key. Give this one its own [machine] id, asset or point in its rig file, or stop the other",
                settings.reach()
            );
        }
        let mut publisher = Self::declare(session, base, config_json)?;
        publisher.recent = super::recent::RecentHistory::declare(
            &publisher.session,
            base,
            settings.history_windows,
            publisher.queries.clone(),
        )?;
        Ok(publisher)
    }

    fn declare(session: zenoh::Session, base: &str, config_json: Vec<u8>) -> Result<Self> {
        let z = |e: zenoh::Error| anyhow!("zenoh: {}", error_text(&e));
        let publisher = |suffix: &str, cc: CongestionControl| {
            session
                .declare_publisher(format!("{base}/{suffix}"))
                .congestion_control(cc)
                .express(true)
                .wait()
                .map_err(z)
                .with_context(|| format!("declaring publisher {base}/{suffix}"))
        };
        let health = publisher("health", FLEET_CONGESTION)?;
        let spectrum = publisher("spectrum", CongestionControl::Drop)?;
        let status = publisher("status", FLEET_CONGESTION)?;
        let own = format!("{base}/alive/{}", session.zid());
        let token = session
            .liveliness()
            .declare_token(own.clone())
            .wait()
            .map_err(z)?;
        let duplicates = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let watch = session
            .liveliness()
            .declare_subscriber(format!("{base}/alive/**"))
            .callback({
                let (duplicates, base) = (duplicates.clone(), base.to_string());
                move |sample| announce_other(&sample, &own, &base, &duplicates)
            })
            .wait()
            .map_err(z)
            .with_context(|| format!("watching {base}/alive/**"))?;

        let latest_health: Arc<Mutex<Option<Vec<u8>>>> = Arc::default();
        let running_config = Arc::new(Mutex::new(config_json));
        let queries = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let mut queryables = Vec::new();
        // Read-only: the queryables answer with stored bytes and ignore any query payload.
        for (suffix, store) in [
            ("health", Store::Health(latest_health.clone())),
            ("config", Store::Config(running_config.clone())),
        ] {
            let key = format!("{base}/{suffix}");
            let reply_key = key.clone();
            let queries = queries.clone();
            let q = session
                .declare_queryable(key.clone())
                .callback(move |query| {
                    // `_time=[..]` asks for history: historians answer that, not the daemon.
                    if query
                        .parameters()
                        .get(super::time_range::PARAMETER)
                        .is_some()
                    {
                        return;
                    }
                    let payload = match &store {
                        Store::Health(m) => m.lock().ok().and_then(|g| g.clone()),
                        Store::Config(m) => m.lock().ok().map(|g| g.clone()),
                    };
                    if let Some(p) = payload {
                        queries.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if let Err(e) = query.reply(reply_key.clone(), p).wait() {
                            tracing::debug!("zenoh reply on {reply_key} failed: {e}");
                        }
                    }
                })
                .wait()
                .map_err(z)
                .with_context(|| format!("declaring queryable {key}"))?;
            queryables.push(q);
        }
        Ok(ZenohPublisher {
            session,
            base: base.to_string(),
            health,
            spectrum,
            status,
            latest_health,
            running_config,
            queries,
            duplicates,
            stats: PublishStats::default(),
            recent: None,
            _token: token,
            _watch: watch,
            _queryables: queryables,
        })
    }

    pub fn base_key(&self) -> &str {
        &self.base
    }

    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// Publish one health message (JSON bytes) and remember it for the queryable.
    pub fn put_health(&mut self, json: Vec<u8>) {
        match self.health.put(json.clone()).wait() {
            Ok(()) => self.stats.health += 1,
            Err(e) => self.error("health", e),
        }
        if let Some(r) = &self.recent {
            r.push(&json);
        }
        if let Ok(mut g) = self.latest_health.lock() {
            *g = Some(json);
        }
    }

    pub fn put_spectrum(&mut self, json: Vec<u8>) {
        match self.spectrum.put(json).wait() {
            Ok(()) => self.stats.spectrum += 1,
            Err(e) => self.error("spectrum", e),
        }
    }

    pub fn put_status(&mut self, json: Vec<u8>) {
        match self.status.put(json).wait() {
            Ok(()) => self.stats.status += 1,
            Err(e) => self.error("status", e),
        }
    }

    /// Replace what the `config` queryable answers (after a reload).
    pub fn set_config(&self, json: Vec<u8>) {
        if let Ok(mut g) = self.running_config.lock() {
            *g = json;
        }
    }

    fn error(&mut self, what: &str, e: zenoh::Error) {
        self.stats.errors += 1;
        if self.stats.errors <= 3 || self.stats.errors.is_power_of_two() {
            tracing::warn!(
                "zenoh put on {}/{what} failed ({} errors so far): {}",
                self.base,
                self.stats.errors,
                error_text(&e)
            );
        }
    }

    pub fn stats(&self) -> PublishStats {
        use std::sync::atomic::Ordering::Relaxed;
        PublishStats {
            queries_answered: self.queries.load(Relaxed),
            duplicates: self.duplicates.load(Relaxed),
            ..self.stats
        }
    }

    /// Wait until something subscribes to the health topic, up to `timeout`. Returns whether
    /// a subscriber was seen.
    pub fn wait_for_subscriber(&self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        loop {
            if self
                .health
                .matching_status()
                .wait()
                .map(|m| m.matching())
                .unwrap_or(false)
            {
                return true;
            }
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Close the session after giving queued messages a moment to leave.
    pub fn close(self) {
        std::thread::sleep(Duration::from_millis(100));
        let ZenohPublisher {
            session,
            health,
            spectrum,
            status,
            _token,
            _watch,
            _queryables,
            ..
        } = self;
        drop((health, spectrum, status, _token, _watch, _queryables));
        if let Err(e) = session.close().wait() {
            tracing::debug!("zenoh close: {e}");
        }
    }
}

/// A liveliness change under this daemon's base key: another daemon's token appearing is
/// announced (an error in the log, counted), its going away noted.
fn announce_other(
    sample: &zenoh::sample::Sample,
    own: &str,
    base: &str,
    duplicates: &std::sync::atomic::AtomicU64,
) {
    let key = sample.key_expr().as_str();
    if key == own {
        return;
    }
    match sample.kind() {
        zenoh::sample::SampleKind::Put => {
            duplicates.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            tracing::error!(
                "another rigmon now publishes as {base} too (liveliness token {key}); its health interleaves with this one's on the same keys. Give one of them its own [machine] id, asset or point"
            );
        }
        zenoh::sample::SampleKind::Delete => {
            tracing::info!("the other rigmon publishing as {base} ({key}) is gone");
        }
    }
}

enum Store {
    Health(Arc<Mutex<Option<Vec<u8>>>>),
    Config(Arc<Mutex<Vec<u8>>>),
}

/// A subscriber delivering (key, payload) pairs through a bounded channel.
pub struct ZenohSubscriber {
    session: zenoh::Session,
    subscriber:
        zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
}

impl ZenohSubscriber {
    pub fn open(settings: &ZenohSettings, key_expr: &str) -> Result<Self> {
        let session = settings.open()?;
        let subscriber = session
            .declare_subscriber(key_expr.to_string())
            .wait()
            .map_err(|e| anyhow!("cannot subscribe to {key_expr:?}: {}", error_text(&e)))?;
        Ok(ZenohSubscriber {
            session,
            subscriber,
        })
    }

    /// Next sample within `timeout` (None on timeout).
    pub fn recv_timeout(&self, timeout: Duration) -> Result<Option<(String, Vec<u8>)>> {
        match self.subscriber.recv_timeout(timeout) {
            Ok(Some(s)) => Ok(Some((
                s.key_expr().to_string(),
                s.payload().to_bytes().into_owned(),
            ))),
            Ok(None) => Ok(None),
            Err(e) => Err(anyhow!("zenoh subscriber closed: {}", error_text(&e))),
        }
    }

    /// The zenoh peers and routers the session is connected to now.
    pub fn connected(&self) -> usize {
        connected_nodes(&self.session)
    }

    /// Wait up to `timeout` until the session is connected to some peer or router.
    pub fn wait_connected(&self, timeout: Duration) -> bool {
        wait_connected(&self.session, timeout)
    }

    /// Ask the queryables under `selector` (e.g. `rigmon/**/health`) and collect every reply:
    /// no consolidation, so two daemons answering for one key both show.
    pub fn get(&self, selector: &str, timeout: Duration) -> Result<Vec<(String, Vec<u8>)>> {
        let replies = self
            .session
            .get(selector.to_string())
            .consolidation(zenoh::query::ConsolidationMode::None)
            .timeout(timeout)
            .wait()
            .map_err(|e| anyhow!("zenoh get {selector:?}: {}", error_text(&e)))?;
        let mut out = Vec::new();
        while let Ok(r) = replies.recv() {
            if let Ok(s) = r.result() {
                out.push((
                    s.key_expr().to_string(),
                    s.payload().to_bytes().into_owned(),
                ));
            }
        }
        Ok(out)
    }

    pub fn close(self) {
        drop(self.subscriber);
        let _ = self.session.close().wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_override_settings_and_endpoints_are_checked() {
        let args = ZenohArgs {
            connect: vec!["tcp/127.0.0.1:7999".into()],
            ..Default::default()
        };
        let s = args.apply(ZenohSettings {
            enabled: false,
            listen: vec!["tcp/127.0.0.1:7448".into()],
            ..Default::default()
        });
        assert!(s.enabled);
        assert_eq!(s.connect, ["tcp/127.0.0.1:7999"]);
        assert_eq!(s.listen, ["tcp/127.0.0.1:7448"]);
        s.zenoh_config().unwrap();
        let bad = ZenohSettings {
            listen: vec!["127.0.0.1:7448".into()],
            ..Default::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("tcp/127.0.0.1:7448"));
        let client = ZenohSettings {
            mode: ZenohMode::Client,
            ..Default::default()
        };
        assert!(client
            .validate()
            .unwrap_err()
            .to_string()
            .contains("needs at least one"));
    }

    /// Issue 25, findings 9 and 12: ports are checked before a session opens, and zenoh's
    /// errors reach the user without the source paths of the machine that built zenoh.
    /// Before, `tcp/127.0.0.1:99999` passed the checks and the session's error ended `at
    /// /root/.cargo/registry/src/.../zenoh-link-commons-1.10.2/src/lib.rs:62.`
    #[test]
    fn ports_are_checked_and_zenoh_errors_carry_no_source_paths() {
        let bad = |ep: &str| ZenohSettings {
            listen: vec![ep.into()],
            ..Default::default()
        };
        let e = bad("tcp/127.0.0.1:99999")
            .validate()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("99999") && e.contains("not a port number"),
            "{e}"
        );
        let e = ZenohSettings {
            connect: vec!["tcp/127.0.0.1:0".into()],
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("port 0"), "{e}");
        bad("tcp/127.0.0.1:0").validate().unwrap();
        // A listen port in use is named before a session would fail on it.
        let held = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = held.local_addr().unwrap().port();
        let e = bad(&format!("tcp/127.0.0.1:{port}"))
            .check_listen_ports()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&port.to_string()) && e.contains("already listens"),
            "{e}"
        );
        // A real zenoh error (192.0.2.1 is a documentation address, not this machine's).
        let e = bad("tcp/192.0.2.1:17448")
            .open()
            .expect_err("cannot listen there");
        let text = format!("{e:#}");
        assert!(text.contains("192.0.2.1"), "{text}");
        assert!(!text.contains(".rs:") && !text.contains(".cargo"), "{text}");
        assert_eq!(
            error_text(&"invalid port value at /root/.cargo/registry/src/i/zenoh-link-commons-1.10.2/src/lib.rs:62."),
            "invalid port value"
        );
        assert_eq!(error_text(&"look at me"), "look at me");
    }

    #[test]
    fn a_replay_waits_for_room_before_dropping_and_a_daemon_does_not() {
        let key = "transport/link/tx/queue/congestion_control/drop/wait_before_drop";
        let live = ZenohSettings::default().zenoh_config().unwrap();
        assert_eq!(
            live.get_json(key).unwrap(),
            "1000",
            "zenoh's 1 ms for a live daemon"
        );
        let replay = ZenohSettings {
            wait_before_drop: Some(REPLAY_WAIT_BEFORE_DROP),
            ..Default::default()
        }
        .zenoh_config()
        .unwrap();
        assert_eq!(
            replay.get_json(key).unwrap(),
            REPLAY_WAIT_BEFORE_DROP.as_micros().to_string()
        );
    }

    #[test]
    fn default_config_disables_multicast_and_listens_nowhere_unasked() {
        let c = ZenohSettings::default().zenoh_config().unwrap();
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
        let listen = c.get_json("listen/endpoints").unwrap();
        assert!(!listen.contains("tcp/"), "default listens on {listen}");
        let c = ZenohSettings {
            listen: vec!["tcp/127.0.0.1:7448".into()],
            ..Default::default()
        }
        .zenoh_config()
        .unwrap();
        assert!(c
            .get_json("listen/endpoints")
            .unwrap()
            .contains("tcp/127.0.0.1:7448"));
    }
}
