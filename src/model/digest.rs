//! The SHA-256 digest rigmon stamps on model files and training data (lower-case hex), shared
//! by the ONNX writer ([`super::export`]), inference ([`super::onnx`]) and training.

use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of some bytes.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
