//! `rigmon watch` and the windows it does not get (`src/cli/watch_gaps.rs`), over real Zenoh
//! on loopback: a daemon-side session (its recent history and its health publisher, as a
//! daemon declares them) publishes the shipped replay's windows but leaves out seq 5-7,
//! which its history holds, and seq 11, which it does not. The watcher prints 5-7 fetched
//! from the history, says that 11 is lost by point and seq range, and its closing account
//! counts both.

use crate::daemon::free_port;
use crate::daemon_harness::{bin, lines, repo, wait_exit, Guard};
use rigmon::publish::recent::RecentHistory;
use rigmon::publish::zenoh::{ZenohSettings, FLEET_CONGESTION};
use rigmon::wire::health::HealthMessage;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// The shipped healthy 588 rpm replay's health messages, as `rigmon replay --json` prints
/// them (one run, seq 1-15).
fn windows() -> Vec<Vec<u8>> {
    let out = Command::new(bin())
        .arg("replay")
        .arg(repo().join("replay/lut-healthy-588rpm.mcap"))
        .args(["--json", "--speed", "max", "--rig"])
        .arg(repo().join("config/lut-rig.toml"))
        .arg("--model")
        .arg(repo().join("models/lut-rig.onnx"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.as_bytes().to_vec())
        .collect()
}

#[test]
fn missed_windows_are_fetched_from_the_daemons_history_or_said_lost() {
    let all = windows();
    assert_eq!(all.len(), 15);
    let key = {
        let m: HealthMessage = serde_json::from_slice(&all[0]).unwrap();
        format!("rigmon/{}", m.address())
    };
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let daemon = ZenohSettings {
        listen: vec![endpoint.clone()],
        history_windows: 0,
        ..Default::default()
    }
    .open()
    .unwrap();
    let ring = RecentHistory::declare(&daemon, &key, 100, Arc::default())
        .unwrap()
        .unwrap();
    let health = daemon
        .declare_publisher(format!("{key}/health"))
        .congestion_control(FLEET_CONGESTION)
        .wait()
        .unwrap();
    let mut watch = Command::new(bin())
        .args(["watch", "--json", "--count", "14", "--timeout", "20"])
        .args(["--connect", &endpoint])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let out = lines(watch.stdout.take().unwrap());
    let err = lines(watch.stderr.take().unwrap());
    let mut watch = Guard(watch);
    let deadline = Instant::now() + Duration::from_secs(20);
    while !health.matching_status().wait().unwrap().matching() {
        assert!(Instant::now() < deadline, "the watcher never subscribed");
        std::thread::sleep(Duration::from_millis(20));
    }
    for (i, json) in all.iter().enumerate() {
        let seq = i as u64 + 1;
        if seq != 11 {
            ring.push(json);
        }
        if !(5..=7).contains(&seq) && seq != 11 {
            health.put(json.clone()).wait().unwrap();
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let status = wait_exit(&mut watch.0, Duration::from_secs(30));
    let printed: Vec<u64> = out
        .try_iter()
        .map(|l| serde_json::from_str::<HealthMessage>(&l).unwrap().seq)
        .collect();
    let said: Vec<String> = err.try_iter().collect();
    assert!(status.success(), "{said:?}");
    let expected: Vec<u64> = (1..=15).filter(|&s| s != 11).collect();
    assert_eq!(printed, expected, "{said:?}");
    let has = |needle: &str| said.iter().any(|l| l.contains(needle));
    assert!(has("seq 5..7 did not come; fetched"), "{said:?}");
    assert!(
        has("1 of the 1 windows seq 11..11 did not come"),
        "{said:?}"
    );
    assert!(
        has("3 windows missed on the way were fetched") && has("1 are lost: "),
        "{said:?}"
    );
}
