//! The SHA-256 digest rigmon stamps on model files and training data (lower-case hex), shared
//! by the ONNX writer ([`super::export`]), inference ([`super::onnx`]) and training; a folder
//! of captures is digested file by file ([`sha256_of_path`]).

use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of a recording: a file's bytes, or for a folder (a series of
/// captures) the digest of one `name hash` line per file, in name order, so the folder's
/// files are read one at a time.
pub fn sha256_of_path(path: &std::path::Path) -> anyhow::Result<String> {
    use anyhow::Context;
    let read = |p: &std::path::Path| {
        std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))
    };
    if !path.is_dir() {
        return Ok(sha256_hex(&read(path)?));
    }
    let mut files: Vec<_> = std::fs::read_dir(path)
        .with_context(|| format!("{}: cannot list the folder", path.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    let mut lines = String::new();
    for f in files {
        let name = f.file_name().unwrap_or_default().to_string_lossy();
        lines.push_str(&format!("{name} {}\n", sha256_hex(&read(&f)?)));
    }
    Ok(sha256_hex(lines.as_bytes()))
}

/// Lower-case hex SHA-256 of some bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
