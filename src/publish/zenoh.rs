//! Zenoh: session settings (`[zenoh]` in the daemon config, or `--mode/--connect/--listen/
//! --zenoh-config` on the command line, as zenoh's own tools take them), the daemon's
//! publisher with its liveliness token and read-only queryables, and a subscriber.
//!
//! Safe defaults: peer mode, listening only where told, multicast scouting off. A session
//! with `connect` endpoints keeps retrying them forever, so a restarted router is picked up
//! again without restarting rigmon.

use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::qos::CongestionControl;
use zenoh::Wait;

pub use super::access::{AclSettings, AuthSettings, TlsSettings};

/// Default TCP port rigmon listens on (loopback only in the shipped config).
pub const DEFAULT_PORT: u16 = 7448;

/// `[zenoh]` section of the daemon config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZenohSettings {
    /// Publish at all (false = health only goes to stdout/recording).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// `peer`, `client` or `router`.
    #[serde(default = "default_mode")]
    pub mode: String,
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
}

fn default_history_windows() -> usize {
    super::recent::DEFAULT_WINDOWS
}

fn yes() -> bool {
    true
}
fn default_mode() -> String {
    "peer".into()
}
fn default_prefix() -> String {
    "rigmon".into()
}

impl Default for ZenohSettings {
    fn default() -> Self {
        ZenohSettings {
            enabled: true,
            mode: default_mode(),
            listen: Vec::new(),
            connect: Vec::new(),
            multicast_scouting: false,
            config_file: None,
            key_prefix: default_prefix(),
            auth: AuthSettings::default(),
            tls: TlsSettings::default(),
            acl: AclSettings::default(),
            history_windows: default_history_windows(),
        }
    }
}

/// Zenoh flags shared by `run`, `replay` and `watch` (the names zenoh's own tools use).
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ZenohArgs {
    /// Zenoh session mode: peer, client or router.
    #[arg(long, value_parser = ["peer", "client", "router"])]
    pub mode: Option<String>,
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
        if let Some(m) = &self.mode {
            base.mode = m.clone();
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
        if !["peer", "client", "router"].contains(&self.mode.as_str()) {
            bail!(
                "zenoh.mode = {:?}: use \"peer\", \"client\" or \"router\"",
                self.mode
            );
        }
        if self.mode == "client" && self.connect.is_empty() && self.config_file.is_none() {
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
        for e in self.listen.iter().chain(&self.connect) {
            e.parse::<zenoh::config::EndPoint>().map_err(|err| {
                anyhow!(
                    "zenoh endpoint {e:?} is not valid ({err}); write it like tcp/127.0.0.1:7448"
                )
            })?;
        }
        Ok(())
    }

    /// Build the zenoh config: the JSON5 file (if any), then mode, endpoints and scouting.
    pub fn zenoh_config(&self) -> Result<zenoh::Config> {
        self.validate()?;
        let mut c = match &self.config_file {
            Some(p) => zenoh::Config::from_file(p)
                .map_err(|e| anyhow!("cannot use zenoh config {}: {e}", p.display()))?,
            None => zenoh::Config::default(),
        };
        let set = |c: &mut zenoh::Config, key: &str, value: String| -> Result<()> {
            c.insert_json5(key, &value)
                .map_err(|e| anyhow!("zenoh config {key} = {value}: {e}"))
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
        super::access::apply(&mut c, &self.key_prefix, &self.auth, &self.tls, &self.acl)?;
        Ok(c)
    }

    /// Open a session.
    pub fn open(&self) -> Result<zenoh::Session> {
        let config = self.zenoh_config()?;
        zenoh::open(config).wait().map_err(|e| {
            anyhow!(
                "cannot open a zenoh session (mode {}, listen {:?}, connect {:?}): {e}; is the port already in use?",
                self.mode,
                self.listen,
                self.connect
            )
        })
    }

    /// `<prefix>/<rig>/<asset>/<point>`.
    pub fn base_key(&self, rig: &str, asset: &str, point: &str) -> String {
        format!("{}/{rig}/{asset}/{point}", self.key_prefix)
    }
}

/// Counters of the publisher (reported in the status topic).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PublishStats {
    pub health: u64,
    pub spectrum: u64,
    pub status: u64,
    pub errors: u64,
    pub queries_answered: u64,
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
    stats: PublishStats,
    recent: Option<super::recent::RecentHistory>,
    _token: zenoh::liveliness::LivelinessToken,
    _queryables: Vec<zenoh::query::Queryable<()>>,
}

impl ZenohPublisher {
    /// Open the session and declare everything under `base` (see [`ZenohSettings::base_key`]).
    /// `config_json` is what the `config` queryable answers.
    pub fn open(settings: &ZenohSettings, base: &str, config_json: Vec<u8>) -> Result<Self> {
        let session = settings.open()?;
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
        let z = |e: zenoh::Error| anyhow!("zenoh: {e}");
        let publisher = |suffix: &str, cc: CongestionControl| {
            session
                .declare_publisher(format!("{base}/{suffix}"))
                .congestion_control(cc)
                .express(true)
                .wait()
                .map_err(z)
                .with_context(|| format!("declaring publisher {base}/{suffix}"))
        };
        let health = publisher("health", CongestionControl::Block)?;
        let spectrum = publisher("spectrum", CongestionControl::Drop)?;
        let status = publisher("status", CongestionControl::Block)?;
        let token = session
            .liveliness()
            .declare_token(format!("{base}/alive"))
            .wait()
            .map_err(z)?;

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
            stats: PublishStats::default(),
            recent: None,
            _token: token,
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
                "zenoh put on {}/{what} failed ({} errors so far): {e}",
                self.base,
                self.stats.errors
            );
        }
    }

    pub fn stats(&self) -> PublishStats {
        PublishStats {
            queries_answered: self.queries.load(std::sync::atomic::Ordering::Relaxed),
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
            _queryables,
            ..
        } = self;
        drop((health, spectrum, status, _token, _queryables));
        if let Err(e) = session.close().wait() {
            tracing::debug!("zenoh close: {e}");
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
            .map_err(|e| anyhow!("cannot subscribe to {key_expr:?}: {e}"))?;
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
            Err(e) => Err(anyhow!("zenoh subscriber closed: {e}")),
        }
    }

    /// Ask the queryables under `selector` (e.g. `rigmon/**/health`) and collect the replies.
    pub fn get(&self, selector: &str, timeout: Duration) -> Result<Vec<(String, Vec<u8>)>> {
        let replies = self
            .session
            .get(selector.to_string())
            .timeout(timeout)
            .wait()
            .map_err(|e| anyhow!("zenoh get {selector:?}: {e}"))?;
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
            mode: "client".into(),
            ..Default::default()
        };
        assert!(client
            .validate()
            .unwrap_err()
            .to_string()
            .contains("needs at least one"));
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
