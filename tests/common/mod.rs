//! Helpers shared by the integration tests: the shipped rig files and the real shared data.
#![allow(dead_code)] // each test binary uses its own subset

use rigmon::config::RigConfig;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A shipped rig file from `config/`.
pub fn rig(name: &str) -> RigConfig {
    RigConfig::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config")
            .join(name),
    )
    .unwrap()
}

/// `../shared/data` beside the checkout; fails (never skips) when it is missing.
pub fn shared_data() -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    assert!(
        p.join("cwru/97_Normal_0.mat").is_file(),
        "shared CWRU data missing at {}: ../shared must sit beside the checkout (CI always has it)",
        p.display()
    );
    p
}

/// Run the `rigmon` binary; fails the test with its stderr unless it exits 0; its stdout.
pub fn rigmon(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rigmon {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}
