//! The pgpass file as libpq reads it: lines `hostname:port:database:username:password`, `*`
//! matching anything, `\:` and `\\` escapes, `#` comments, the first matching line wins. A
//! Unix-socket host also matches `localhost`. Like libpq, a file others can read is refused
//! (libpq ignores it with a warning; here the error says what to do).

use anyhow::{bail, Context, Result};
use std::os::unix::fs::PermissionsExt;
use std::path::Path;

/// The password for this connection, if a line of `file` matches.
pub fn lookup(file: &Path, host: &str, port: u16, db: &str, user: &str) -> Result<Option<String>> {
    let meta = std::fs::metadata(file).with_context(|| {
        format!(
            "cannot read the pgpass file {} (PGPASSFILE)",
            file.display()
        )
    })?;
    if meta.permissions().mode() & 0o077 != 0 {
        bail!(
            "the pgpass file {} can be read by others (mode {:o}); `chmod 600` it",
            file.display(),
            meta.permissions().mode() & 0o777
        );
    }
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("cannot read the pgpass file {}", file.display()))?;
    let port = port.to_string();
    let socket = host.starts_with('/');
    for line in text.lines() {
        if line.trim_start().starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let f = fields(line);
        if f.len() < 5 {
            continue;
        }
        let matches = |pat: &str, v: &str| pat == "*" || pat == v;
        let host_ok = matches(&f[0], host) || (socket && f[0] == "localhost");
        if host_ok && matches(&f[1], &port) && matches(&f[2], db) && matches(&f[3], user) {
            return Ok(Some(f[4..].join(":")));
        }
    }
    Ok(None)
}

/// Split on unescaped `:`, undoing `\:` and `\\`.
fn fields(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '\\' => {
                if let Some(n) = chars.next() {
                    out.last_mut().unwrap().push(n);
                }
            }
            ':' => out.push(String::new()),
            _ => out.last_mut().unwrap().push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_matching_line_with_wildcards_and_escapes() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("pgpass");
        std::fs::write(
            &f,
            "# comment\ndb.plant:5432:fleet:hist:first\n*:6543:*:hist:p\\:w\\\\d\nlocalhost:*:*:*:sock\n",
        )
        .unwrap();
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(
            lookup(&f, "db.plant", 5432, "fleet", "hist")
                .unwrap()
                .as_deref(),
            Some("first")
        );
        assert_eq!(
            lookup(&f, "10.0.0.1", 6543, "x", "hist")
                .unwrap()
                .as_deref(),
            Some("p:w\\d")
        );
        assert_eq!(
            lookup(&f, "/run/postgresql", 5432, "x", "y")
                .unwrap()
                .as_deref(),
            Some("sock")
        );
        assert_eq!(
            lookup(&f, "db.plant", 5432, "fleet", "nobody").unwrap(),
            None
        );
        std::fs::set_permissions(&f, std::fs::Permissions::from_mode(0o644)).unwrap();
        let e = lookup(&f, "h", 1, "d", "u").unwrap_err().to_string();
        assert!(e.contains("chmod 600"), "{e}");
    }
}
