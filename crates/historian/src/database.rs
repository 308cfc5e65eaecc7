//! Which PostgreSQL, named the way psql names it: the `PGHOST`, `PGPORT`, `PGUSER`,
//! `PGDATABASE`, `PGAPPNAME`, `PGSSLMODE` and `PGCONNECT_TIMEOUT` environment variables, or
//! `[database] url` (a `postgresql://user@host:port/db` URL **without** password) on top of
//! them. The password comes from `[database] password_file` (its first line), else from a
//! pgpass file (`PGPASSFILE`, else `~/.pgpass`, as libpq reads it; see [`super::pgpass`]);
//! never from the command line, and it is never logged ([`Target::describe`] leaves it out).
//! TLS to PostgreSQL is not built in: `sslmode=require` and stricter are refused at start.

use super::pgpass;
use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;
use tokio_postgres::config::{Host, SslMode};
use tokio_postgres::{Client, Config, NoTls};

/// `[database]`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatabaseSettings {
    /// `postgresql://user@host:port/dbname` (no password); unset parts come from `PG*`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub url: Option<String>,
    /// A file whose first line is the password (else `PGPASSFILE` / `~/.pgpass`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub password_file: Option<PathBuf>,
    /// The PostgreSQL schema the historian's tables live in (made if missing; default: the
    /// server's `search_path`, i.e. `public`). One per site when sites replicate into one
    /// central database (docs/fleet.md): the names then never collide there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub schema: Option<String>,
}

/// A resolved connection target (its Debug leaves the password out).
#[derive(Clone, Debug)]
pub struct Target {
    config: Config,
    describe: String,
    schema: Option<String>,
}

impl DatabaseSettings {
    /// What can be checked without the environment: the URL parses and holds no password.
    pub fn validate(&self) -> Result<()> {
        if let Some(url) = &self.url {
            let c = Config::from_str(url).map_err(|e| {
                anyhow!("database.url does not parse ({e}); write it like postgresql://rigmon@db.plant:5432/rigmon")
            })?;
            if c.get_password().is_some() {
                bail!("database.url carries a password: remove it from the URL and put it in a file (database.password_file, or a pgpass file named by PGPASSFILE)");
            }
            check_ssl(c.get_ssl_mode(), "database.url sslmode")?;
        }
        if let Some(s) = &self.schema {
            let plain = s.len() <= 63
                && s.starts_with(|c: char| c.is_ascii_lowercase() || c == '_')
                && s.chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
            if !plain || s.starts_with("pg_") {
                bail!("database.schema = {s:?}: a plain lower-case name (a-z, 0-9, _, at most 63 characters, not pg_...), e.g. \"site_north\"");
            }
        }
        Ok(())
    }

    /// Resolve against the process environment.
    pub fn resolve(&self) -> Result<Target> {
        self.resolve_with(&|k| std::env::var(k).ok())
    }

    /// Resolve with `env` standing in for the environment (tests).
    pub fn resolve_with(&self, env: &dyn Fn(&str) -> Option<String>) -> Result<Target> {
        self.validate()?;
        let mut c = match &self.url {
            Some(u) => Config::from_str(u).map_err(|e| anyhow!("database.url: {e}"))?,
            None => Config::new(),
        };
        if env("PGPASSWORD").is_some() {
            tracing::warn!("PGPASSWORD is set and ignored: put the password in a pgpass file (PGPASSFILE) or [database] password_file");
        }
        if self.url.as_deref().is_some_and(|u| !url_has_port(u)) {
            // libpq takes PGPORT for a URL without a port; the URL parser put in 5432.
            c = without_ports(&c);
        }
        fill_from_env(&mut c, env)?;
        if let Some(schema) = &self.schema {
            c.options(format!("-c search_path={schema}").as_str());
        }
        let describe = match &self.schema {
            Some(s) => format!("{} (schema {s})", describe(&c)),
            None => describe(&c),
        };
        if let Some(pw) = self.password(&c, env)? {
            c.password(pw);
        }
        Ok(Target {
            config: c,
            describe,
            schema: self.schema.clone(),
        })
    }

    fn password(&self, c: &Config, env: &dyn Fn(&str) -> Option<String>) -> Result<Option<String>> {
        if let Some(p) = &self.password_file {
            return read_password_file(p).map(Some);
        }
        let file = match env("PGPASSFILE") {
            Some(f) => PathBuf::from(f),
            None => match env("HOME") {
                Some(h) if Path::new(&h).join(".pgpass").is_file() => Path::new(&h).join(".pgpass"),
                _ => return Ok(None),
            },
        };
        let host = match c.get_hosts().first() {
            Some(Host::Tcp(h)) => h.clone(),
            Some(Host::Unix(p)) => p.display().to_string(),
            None => "localhost".into(),
        };
        let port = c.get_ports().first().copied().unwrap_or(5432);
        pgpass::lookup(
            &file,
            &host,
            port,
            c.get_dbname().unwrap_or(""),
            c.get_user().unwrap_or(""),
        )
    }
}

/// Whether `postgresql://user@host:port/db` names a port.
fn url_has_port(url: &str) -> bool {
    let rest = url.split_once("://").map_or(url, |(_, r)| r);
    let authority = rest.split(['/', '?']).next().unwrap_or("");
    let hostport = authority.rsplit_once('@').map_or(authority, |(_, h)| h);
    match hostport.strip_prefix('[') {
        Some(v6) => v6.contains("]:"),
        None => hostport.contains(':'),
    }
}

/// The same config with no ports (so PGPORT or 5432 fill them in).
fn without_ports(c: &Config) -> Config {
    let mut n = Config::new();
    for h in c.get_hosts() {
        match h {
            Host::Tcp(t) => n.host(t),
            Host::Unix(p) => n.host_path(p),
        };
    }
    if let Some(u) = c.get_user() {
        n.user(u);
    }
    if let Some(d) = c.get_dbname() {
        n.dbname(d);
    }
    if let Some(a) = c.get_application_name() {
        n.application_name(a);
    }
    n.ssl_mode(c.get_ssl_mode());
    n
}

fn check_ssl(mode: SslMode, what: &str) -> Result<()> {
    match mode {
        SslMode::Disable | SslMode::Prefer => Ok(()),
        _ => bail!("{what}: this rigmon talks to PostgreSQL without TLS; use a Unix socket, loopback, or a tunnel (ssh, stunnel), and sslmode=disable or prefer"),
    }
}

/// Fill what the URL left unset from `PG*`, then libpq's defaults.
fn fill_from_env(c: &mut Config, env: &dyn Fn(&str) -> Option<String>) -> Result<()> {
    if c.get_hosts().is_empty() {
        let hosts = env("PGHOST").unwrap_or_else(|| {
            if Path::new("/var/run/postgresql").is_dir() {
                "/var/run/postgresql".into()
            } else {
                "localhost".into()
            }
        });
        for h in hosts.split(',').filter(|h| !h.is_empty()) {
            c.host(h);
        }
    }
    if c.get_ports().is_empty() {
        if let Some(p) = env("PGPORT") {
            let port = p
                .parse::<u16>()
                .map_err(|_| anyhow!("PGPORT={p:?} is not a port number"))?;
            c.port(port);
        } else {
            c.port(5432);
        }
    }
    if c.get_user().is_none() {
        let user = env("PGUSER")
            .or_else(|| env("USER"))
            .or_else(os_user)
            .ok_or_else(|| anyhow!("no database user: set PGUSER or put one in database.url"))?;
        c.user(user);
    }
    if c.get_dbname().is_none() {
        let db = env("PGDATABASE").unwrap_or_else(|| c.get_user().unwrap_or("").to_string());
        c.dbname(db);
    }
    if c.get_application_name().is_none() {
        c.application_name(env("PGAPPNAME").unwrap_or_else(|| "rigmon".into()));
    }
    if let Some(m) = env("PGSSLMODE") {
        let mode = match m.as_str() {
            "disable" => SslMode::Disable,
            "allow" | "prefer" => SslMode::Prefer,
            _ => SslMode::Require,
        };
        check_ssl(mode, &format!("PGSSLMODE={m}"))?;
        c.ssl_mode(mode);
    }
    let timeout = match env("PGCONNECT_TIMEOUT") {
        Some(t) => t
            .parse::<u64>()
            .map_err(|_| anyhow!("PGCONNECT_TIMEOUT={t:?} is not a number of seconds"))?,
        None => 5,
    };
    c.connect_timeout(Duration::from_secs(timeout.max(1)));
    c.keepalives(true);
    c.keepalives_idle(Duration::from_secs(10));
    Ok(())
}

/// The login name of this process's user (libpq's default for PGUSER).
fn os_user() -> Option<String> {
    // SAFETY: getpwuid returns a pointer into static storage or null; we copy the name out
    // at once and this runs before any other thread calls getpw*.
    unsafe {
        let pw = libc::getpwuid(libc::geteuid());
        if pw.is_null() || (*pw).pw_name.is_null() {
            return None;
        }
        Some(
            std::ffi::CStr::from_ptr((*pw).pw_name)
                .to_string_lossy()
                .into_owned(),
        )
    }
}

fn read_password_file(p: &Path) -> Result<String> {
    let text = std::fs::read_to_string(p).with_context(|| {
        format!(
            "cannot read the database password file {} (database.password_file)",
            p.display()
        )
    })?;
    let pw = text.lines().next().unwrap_or("").to_string();
    if pw.is_empty() {
        bail!("the database password file {} is empty", p.display());
    }
    Ok(pw)
}

/// `user@host:port/db` (never the password).
fn describe(c: &Config) -> String {
    let host = match c.get_hosts().first() {
        Some(Host::Tcp(h)) => h.clone(),
        Some(Host::Unix(p)) => p.display().to_string(),
        None => "?".into(),
    };
    format!(
        "{}@{}:{}/{}",
        c.get_user().unwrap_or("?"),
        host,
        c.get_ports().first().copied().unwrap_or(5432),
        c.get_dbname().unwrap_or("?")
    )
}

impl Target {
    /// `user@host:port/db`, for logs and errors.
    pub fn describe(&self) -> &str {
        &self.describe
    }

    /// The schema named by `[database] schema`, if any.
    pub fn schema(&self) -> Option<&str> {
        self.schema.as_deref()
    }

    /// Connect; the connection's own task runs on the current tokio runtime.
    pub async fn connect(&self) -> Result<Client> {
        let (client, connection) = self.config.connect(NoTls).await.map_err(|e| {
            let hint = if e.to_string().contains("password") {
                "; the server wants a password: put it in a pgpass file named by PGPASSFILE (mode 0600) or in [database] password_file"
            } else {
                ""
            };
            anyhow!("cannot connect to PostgreSQL {}: {e}{hint}", self.describe)
        })?;
        let who = self.describe.clone();
        tokio::spawn(async move {
            if let Err(e) = connection.await {
                tracing::debug!("PostgreSQL connection to {who} ended: {e}");
            }
        });
        Ok(client)
    }
}

/// Connect from synchronous code (CLI commands): a small runtime for one call.
pub fn block_on<F: std::future::Future>(f: F) -> Result<F::Output> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start a tokio runtime")?;
    Ok(rt.block_on(f))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env(vars: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let m: HashMap<String, String> = vars
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| m.get(k).cloned()
    }

    #[test]
    fn pg_variables_name_the_database_and_the_url_wins() {
        let e = env(&[
            ("PGHOST", "127.0.0.1"),
            ("PGPORT", "6543"),
            ("PGUSER", "hist"),
            ("PGDATABASE", "fleet"),
        ]);
        let t = DatabaseSettings::default().resolve_with(&e).unwrap();
        assert_eq!(t.describe(), "hist@127.0.0.1:6543/fleet");
        let s = DatabaseSettings {
            url: Some("postgresql://other@db.plant/plant".into()),
            ..Default::default()
        };
        assert_eq!(
            s.resolve_with(&e).unwrap().describe(),
            "other@db.plant:6543/plant"
        );
        let s = DatabaseSettings {
            url: Some("postgresql://other@db.plant:7000/plant".into()),
            ..Default::default()
        };
        assert_eq!(
            s.resolve_with(&e).unwrap().describe(),
            "other@db.plant:7000/plant"
        );
    }

    #[test]
    fn passwords_never_in_the_url_and_no_tls_refused_early() {
        let s = DatabaseSettings {
            url: Some("postgresql://u:secret@h/db".into()),
            ..Default::default()
        };
        let msg = s.validate().unwrap_err().to_string();
        assert!(msg.contains("password") && !msg.contains("secret"), "{msg}");
        let e = env(&[("PGSSLMODE", "require"), ("PGUSER", "u")]);
        let msg = DatabaseSettings::default()
            .resolve_with(&e)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("without TLS"), "{msg}");
        let e = env(&[("PGPORT", "54x"), ("PGUSER", "u")]);
        let msg = DatabaseSettings::default()
            .resolve_with(&e)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("PGPORT"), "{msg}");
    }
}
