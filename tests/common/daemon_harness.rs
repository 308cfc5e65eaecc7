//! Helpers to run the real `rigmon` binary in tests (the fast tier's daemon, faults and
//! openDAQ modules share them): the repository paths, a child guard, line readers for its
//! pipes, waiting for exit, signals, and a daemon config replaying a file with recording on.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::Child;
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_rigmon")
}

pub fn model() -> PathBuf {
    repo().join("models/lut-rig.onnx")
}

pub fn rig_path() -> PathBuf {
    repo().join("config/lut-rig.toml")
}

/// Kills a child when dropped (a failing assertion must not leave daemons behind).
pub struct Guard(pub Child);
impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Lines of a child's pipe, delivered through a channel by a reader thread.
pub fn lines(r: impl Read + Send + 'static) -> Receiver<String> {
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for l in BufReader::new(r).lines() {
            let Ok(l) = l else { break };
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    rx
}

pub fn wait_exit(child: &mut Child, timeout: Duration) -> std::process::ExitStatus {
    let pid = child.id();
    wait_exit_or_kill(child, timeout)
        .unwrap_or_else(|| panic!("process {pid} did not exit within {timeout:?}"))
}

/// Like [`wait_exit`] but returns `None` (after killing it) when the child is still running
/// at the deadline, so a test can say what it expected instead of panicking here.
pub fn wait_exit_or_kill(child: &mut Child, timeout: Duration) -> Option<std::process::ExitStatus> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Every line left in a pipe's channel, up to the pipe closing (or 5 s).
pub fn rest_of(rx: &Receiver<String>) -> Vec<String> {
    let mut v = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(5);
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok(l) => v.push(l),
            Err(_) => break,
        }
    }
    v
}

pub fn signal(child: &Child, sig: i32) {
    // SAFETY: plain kill(2) on our own child.
    assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
}

/// A daemon config in `dir` replaying `file` (looping, at `speed`) with `model`, Zenoh on
/// loopback `port`, recording to `dir/rec` when `record`.
pub fn daemon_config(
    dir: &Path,
    file: &Path,
    model: &Path,
    speed: &str,
    port: u16,
    record: bool,
) -> PathBuf {
    let text = format!(
        r#"rig = "{rig}"
[model]
path = "{model}"
[source]
type = "file"
path = "{file}"
speed = {speed}
loop = true
[health]
vote_n = 5
vote_k = 3
dwell_s = 1.0
[pipeline]
status_every_s = 0.25
[zenoh]
mode = "peer"
listen = ["tcp/127.0.0.1:{port}"]
multicast_scouting = false
[recording]
enabled = {record}
dir = "{rec}"
flush_s = 0.5
chunk_kb = 64
"#,
        rig = rig_path().display(),
        model = model.display(),
        file = file.display(),
        rec = dir.join("rec").display(),
    );
    let p = dir.join("rigmon.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// The `.mcap` files in `dir`, sorted.
pub fn mcaps(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}
