//! Zenoh access control passed through from rigmon's config: user/password authentication
//! (`[zenoh.auth]`, zenoh's usrpwd), TLS (`[zenoh.tls]`, needs rigmon's `tls` feature) and an
//! access-control list (`[zenoh.acl]`): deny by default, named readers may only subscribe to
//! and query rigmon's keys, and nobody may put or delete there.

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
    /// `<key_prefix>/**`. Non-empty turns the access-control list on; everyone else, and
    /// every put or delete, is denied.
    #[serde(default)]
    pub readers: Vec<String>,
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
        self.readers.is_empty()
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
        bail!("zenoh.acl.readers names users, which needs zenoh.auth.users_file (the `user:password` list they log in with)");
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
        insert(c, "access_control", acl_json(prefix, &acl.readers))?;
    }
    Ok(())
}

/// The access-control list: deny by default; readers' subscriptions and queries come in,
/// publications, replies, queryable and liveliness declarations go out to them.
pub fn acl_json(prefix: &str, readers: &[String]) -> String {
    let keys = serde_json::json!([format!("{prefix}/**")]);
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
        ],
        "subjects": [{"id": "rigmon-readers", "usernames": readers}],
        "policies": [{"rules": ["rigmon-read-in", "rigmon-read-out"], "subjects": ["rigmon-readers"]}],
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn acl_parses_as_zenoh_config_and_checks_pairs() {
        let mut c = zenoh::Config::default();
        insert(
            &mut c,
            "access_control",
            acl_json("rigmon", &["alice".into()]),
        )
        .unwrap();
        let a = AuthSettings {
            user: Some("alice".into()),
            ..Default::default()
        };
        assert!(validate(&a, &TlsSettings::default(), &AclSettings::default()).is_err());
        let acl = AclSettings {
            readers: vec!["alice".into()],
        };
        assert!(validate(&AuthSettings::default(), &TlsSettings::default(), &acl).is_err());
    }
}
