//! Zenoh access control passed through from rigmon's config: user/password authentication
//! (`[zenoh.auth]`, zenoh's usrpwd), TLS (`[zenoh.tls]`, needs rigmon's `tls` feature) and an
//! access-control list (`[zenoh.acl]`) for the node others connect to (a daemon listening,
//! a router): deny by default; named `readers` may only subscribe to and query rigmon's keys
//! (`rigmon history` included: their queries go out to a historian and its replies come
//! back); named `historians` may also answer history (declare the queryable, reply, be
//! asked) and publish their own status under `<prefix>/@historian/**`; nobody else may put
//! or delete there. A session whose own config holds such a list denies every put coming
//! in to it, so it can receive nothing: [`receives_nothing`] says so before it starts.

use anyhow::{anyhow, bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `[zenoh.auth]`: zenoh's user/password authentication.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuthSettings {
    /// Accepting side (the daemon): a file of `user:password` lines. A peer that connects
    /// without credentials listed there is refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub users_file: Option<PathBuf>,
    /// Connecting side: the user name to present...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user: Option<String>,
    /// ...and a file holding its password (first line; never the password itself in config).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub password_file: Option<PathBuf>,
}

/// `[zenoh.tls]`: certificates for `tls/...` endpoints.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsSettings {
    /// CA certificate (PEM) that signed the peer's certificate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub root_ca: Option<PathBuf>,
    /// This side's certificate (PEM) and private key (PEM): needed to listen on tls/...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cert: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub key: Option<PathBuf>,
    /// Mutual TLS: the listener also requires a client certificate signed by `root_ca`.
    #[serde(default)]
    pub mtls: bool,
}

/// `[zenoh.acl]`: who may read.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AclSettings {
    /// Users (from `[zenoh.auth] users_file`) allowed to subscribe to and query
    /// `<key_prefix>/**` (and historians' status). Non-empty turns the access-control list
    /// on; everyone else, and every put or delete, is denied.
    #[serde(default)]
    pub readers: Vec<String>,
    /// Users of `rigmon historian`: what readers may, and also answer `rigmon history`
    /// (a queryable on `<key_prefix>/**/health`) and publish `<key_prefix>/@historian/**`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub historians: Vec<String>,
}

impl AuthSettings {
    pub fn is_empty(&self) -> bool {
        self == &AuthSettings::default()
    }
}
impl TlsSettings {
    pub fn is_empty(&self) -> bool {
        self == &TlsSettings::default()
    }
}
impl AclSettings {
    pub fn is_empty(&self) -> bool {
        self.readers.is_empty() && self.historians.is_empty()
    }
}

fn insert(c: &mut zenoh::Config, key: &str, value: String) -> Result<()> {
    c.insert_json5(key, &value)
        .map_err(|e| anyhow!("zenoh config {key} = {value}: {e}"))
}

fn path_json(p: &Path, what: &str) -> Result<String> {
    if !p.is_file() {
        bail!("{what} {} does not exist or is not a file", p.display());
    }
    Ok(serde_json::to_string(&p.to_string_lossy())?)
}

/// Read a password file: its first line, without the line end.
fn read_password(p: &Path) -> Result<String> {
    let s = std::fs::read_to_string(p).with_context(|| {
        format!(
            "cannot read the zenoh password file {} (zenoh.auth.password_file / --password-file)",
            p.display()
        )
    })?;
    let pw = s.lines().next().unwrap_or("").to_string();
    if pw.is_empty() {
        bail!("the zenoh password file {} is empty", p.display());
    }
    Ok(pw)
}

/// Check what can be checked without files.
pub fn validate(auth: &AuthSettings, tls: &TlsSettings, acl: &AclSettings) -> Result<()> {
    if auth.user.is_some() != auth.password_file.is_some() {
        bail!("zenoh.auth: user and password_file go together (--user and --password-file on the command line)");
    }
    if !acl.is_empty() && auth.users_file.is_none() {
        bail!("zenoh.acl.readers and historians name users, which needs zenoh.auth.users_file (the `user:password` list they log in with)");
    }
    if !tls.is_empty() && !cfg!(feature = "tls") {
        bail!(
            "zenoh.tls is set but this rigmon was built without TLS; rebuild with `--features tls`"
        );
    }
    if tls.cert.is_some() != tls.key.is_some() {
        bail!("zenoh.tls: cert and key go together");
    }
    if tls.mtls && (tls.root_ca.is_none() || tls.cert.is_none()) {
        bail!("zenoh.tls.mtls needs root_ca, cert and key");
    }
    Ok(())
}

/// Write the settings into a zenoh config.
pub fn apply(
    c: &mut zenoh::Config,
    prefix: &str,
    auth: &AuthSettings,
    tls: &TlsSettings,
    acl: &AclSettings,
) -> Result<()> {
    validate(auth, tls, acl)?;
    if let Some(f) = &auth.users_file {
        insert(
            c,
            "transport/auth/usrpwd/dictionary_file",
            path_json(f, "zenoh.auth.users_file")?,
        )?;
    }
    if let (Some(u), Some(p)) = (&auth.user, &auth.password_file) {
        insert(c, "transport/auth/usrpwd/user", serde_json::to_string(u)?)?;
        insert(
            c,
            "transport/auth/usrpwd/password",
            serde_json::to_string(&read_password(p)?)?,
        )?;
    }
    if let Some(ca) = &tls.root_ca {
        insert(
            c,
            "transport/link/tls/root_ca_certificate",
            path_json(ca, "zenoh.tls.root_ca")?,
        )?;
    }
    if let (Some(cert), Some(key)) = (&tls.cert, &tls.key) {
        let (cert, key) = (
            path_json(cert, "zenoh.tls.cert")?,
            path_json(key, "zenoh.tls.key")?,
        );
        insert(c, "transport/link/tls/listen_certificate", cert.clone())?;
        insert(c, "transport/link/tls/listen_private_key", key.clone())?;
        if tls.mtls {
            insert(c, "transport/link/tls/connect_certificate", cert)?;
            insert(c, "transport/link/tls/connect_private_key", key)?;
        }
    }
    if tls.mtls {
        insert(c, "transport/link/tls/enable_mtls", "true".into())?;
    }
    if !acl.is_empty() {
        insert(c, "access_control", acl_json(prefix, acl))?;
    }
    Ok(())
}

/// Why a session with this zenoh config can receive no health at all (its access control is
/// on, denies by default and allows no incoming put on `<prefix>/**/health`), or None.
pub fn receives_nothing(c: &zenoh::Config, prefix: &str) -> Option<String> {
    let health = zenoh::key_expr::KeyExpr::try_from(format!("{prefix}/m/a/p/health")).ok()?;
    let on = c.get_json("access_control/enabled").ok()? == "true";
    let default = c
        .get_json("access_control/default_permission")
        .unwrap_or_default();
    if !on || default.contains("allow") {
        return None;
    }
    let rules: serde_json::Value =
        serde_json::from_str(&c.get_json("access_control/rules").ok()?).ok()?;
    let allows_put_in = rules.as_array().into_iter().flatten().any(|r| {
        let has = |field: &str, word: &str| {
            r[field]
                .as_array()
                .is_some_and(|a| a.iter().any(|v| v == word))
        };
        let covers = r["key_exprs"].as_array().into_iter().flatten().any(|k| {
            k.as_str()
                .and_then(|k| zenoh::key_expr::KeyExpr::try_from(k.to_string()).ok())
                .is_some_and(|k| k.intersects(&health))
        });
        r["permission"] == "allow"
            && has("messages", "put")
            && (r["flows"].is_null() || has("flows", "ingress"))
            && covers
    });
    (!allows_put_in).then(|| {
        "its zenoh access control denies by default and allows no incoming put of health, so it would receive none. An access-control list belongs in the config of the node others connect to (the daemon that listens, or the router); remove [zenoh.acl] (or the access_control of the zenoh config file) here and list this user among that node's `historians` (or `readers`)".to_string()
    })
}

/// The access-control list: deny by default; readers' (and historians') subscriptions and
/// queries come in, publications, replies, queryable and liveliness declarations go out to
/// them; historians' history queryable and replies come in, queries go out to them, and
/// their status comes in.
pub fn acl_json(prefix: &str, acl: &AclSettings) -> String {
    let keys = serde_json::json!([format!("{prefix}/**"), format!("{prefix}/@historian/**")]);
    let everyone: Vec<&String> = acl.readers.iter().chain(&acl.historians).collect();
    let mut subjects = vec![serde_json::json!({"id": "rigmon-readers", "usernames": everyone})];
    let mut policies = vec![serde_json::json!(
        {"rules": ["rigmon-read-in", "rigmon-read-out"], "subjects": ["rigmon-readers"]}
    )];
    // A subject with no user names would match everyone: historians only when named.
    if !acl.historians.is_empty() {
        subjects.push(serde_json::json!({"id": "rigmon-historians", "usernames": acl.historians}));
        policies.push(serde_json::json!({
            "rules": ["rigmon-history-in", "rigmon-history-out", "rigmon-historian-status"],
            "subjects": ["rigmon-historians"],
        }));
    }
    serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [
            {
                "id": "rigmon-read-in",
                "messages": ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": keys,
            },
            {
                "id": "rigmon-read-out",
                "messages": ["put", "reply", "declare_queryable", "liveliness_token"],
                "flows": ["egress"],
                "permission": "allow",
                "key_exprs": keys,
            },
            {
                "id": "rigmon-history-in",
                "messages": ["declare_queryable", "reply"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [format!("{prefix}/**")],
            },
            {
                "id": "rigmon-history-out",
                "messages": ["query"],
                "flows": ["egress"],
                "permission": "allow",
                "key_exprs": [format!("{prefix}/**")],
            },
            {
                "id": "rigmon-historian-status",
                "messages": ["put"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [format!("{prefix}/@historian/**")],
            },
        ],
        "subjects": subjects,
        "policies": policies,
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acl_parses_as_zenoh_config_and_checks_pairs() {
        let mut c = zenoh::Config::default();
        let both = AclSettings {
            readers: vec!["alice".into()],
            historians: vec!["hist".into()],
        };
        insert(&mut c, "access_control", acl_json("rigmon", &both)).unwrap();
        assert!(
            receives_nothing(&c, "rigmon").is_some(),
            "a session holding this list takes no health in"
        );
        assert!(receives_nothing(&zenoh::Config::default(), "rigmon").is_none());
        let open = r#"{"enabled": true, "default_permission": "deny", "rules": [{"id": "in",
            "messages": ["put"], "flows": ["ingress"], "permission": "allow",
            "key_exprs": ["rigmon/**"]}], "subjects": [{"id": "s", "usernames": ["a"]}],
            "policies": [{"rules": ["in"], "subjects": ["s"]}]}"#;
        insert(&mut c, "access_control", open.into()).unwrap();
        assert!(
            receives_nothing(&c, "rigmon").is_none(),
            "puts on rigmon/** come in"
        );
        let a = AuthSettings {
            user: Some("alice".into()),
            ..Default::default()
        };
        assert!(validate(&a, &TlsSettings::default(), &AclSettings::default()).is_err());
        let acl = AclSettings {
            readers: vec!["alice".into()],
            historians: Vec::new(),
        };
        assert!(validate(&AuthSettings::default(), &TlsSettings::default(), &acl).is_err());
    }
}
