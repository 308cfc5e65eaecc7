//! House rule from issue 17: no function in src/daemon/ is longer than 100 lines, checked
//! with the same script CI runs (`.ci/fn-lengths src/daemon --max 100`).

use std::path::PathBuf;
use std::process::Command;

#[test]
fn no_daemon_function_is_longer_than_100_lines() {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new("python3")
        .arg(repo.join(".ci/fn-lengths"))
        .args(["src/daemon", "--max", "100"])
        .current_dir(&repo)
        .output()
        .expect("python3 runs .ci/fn-lengths; install python3");
    assert!(
        out.status.success(),
        ".ci/fn-lengths src/daemon --max 100 failed; split the functions it lists:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
