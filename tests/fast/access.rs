//! Zenoh access control end to end, with real parts: the built `rigmon` daemon and `watch`,
//! zenoh's user/password authentication and access-control list from `[zenoh.auth]` and
//! `[zenoh.acl]`, the independent Python eclipse-zenoh client, and (with the `tls` feature) a
//! CA and server certificate made by the openssl CLI. Loopback only, explicit endpoints,
//! multicast scouting off; ports 7610-7629.

use rigmon::publish::zenoh::{AuthSettings, ZenohSettings};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};
use zenoh::Wait;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_rigmon")
}

/// Kills a child when dropped (a failing assertion must not leave daemons behind).
struct Guard(Child);
impl Drop for Guard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn lines(r: impl Read + Send + 'static) -> Receiver<String> {
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

/// A daemon replaying the outer-race recording at real time, with extra `[zenoh]` lines.
fn daemon(dir: &Path, zenoh: &str) -> (Guard, Receiver<String>) {
    let cfg = dir.join("rigmon.toml");
    std::fs::write(
        &cfg,
        format!(
            "rig = {:?}\n[model]\npath = {:?}\n[source]\ntype = \"file\"\npath = {:?}\nspeed = 1.0\nloop = true\n[pipeline]\nspectrum = false\nstatus_every_s = 0.5\n{zenoh}",
            repo().join("config/lut-rig.toml"),
            repo().join("models/lut-rig.onnx"),
            repo().join("replay/lut-outer_race-588rpm.mcap"),
        ),
    )
    .unwrap();
    let mut c = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = lines(c.stderr.take().unwrap());
    (Guard(c), err)
}

/// `rigmon watch --json` on the daemon's health with extra arguments.
fn watch(args: &[&str]) -> (Guard, Receiver<String>) {
    let mut c = Command::new(bin())
        .args(["watch", "--json"])
        .args(args)
        .arg("rigmon/lut-rig/shaft/nde/health")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let out = lines(c.stdout.take().unwrap());
    (Guard(c), out)
}

/// Wait until `n` health messages arrived on `rx` (false on timeout).
fn health(rx: &Receiver<String>, n: usize, timeout: Duration) -> bool {
    let deadline = Instant::now() + timeout;
    let mut got = 0;
    while got < n && Instant::now() < deadline {
        if let Ok(l) = rx.recv_timeout(Duration::from_millis(200)) {
            let v: serde_json::Value = serde_json::from_str(&l).unwrap();
            if v["schema"] == "rigmon.health" {
                got += 1;
            }
        }
    }
    got >= n
}

fn alive(c: &mut Guard, log: &Receiver<String>) {
    if let Some(s) = c.0.try_wait().unwrap() {
        let l: Vec<String> = log.try_iter().collect();
        panic!("daemon exited ({s}): {l:?}");
    }
}

/// Ask a queryable, optionally with a payload; the replies' payloads.
fn query(s: &zenoh::Session, key: &str, payload: Option<&str>) -> Vec<Vec<u8>> {
    let g = s.get(key).timeout(Duration::from_secs(3));
    let replies = match payload {
        Some(p) => g.payload(p.to_string()).wait(),
        None => g.wait(),
    }
    .unwrap();
    let mut out = Vec::new();
    while let Ok(r) = replies.recv() {
        if let Ok(sample) = r.result() {
            out.push(sample.payload().to_bytes().into_owned());
        }
    }
    out
}

#[test]
fn usrpwd_and_acl_let_only_listed_readers_in_and_nothing_reachable_changes_the_daemon() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("users"), "alice:alice-secret\nbob:bob-secret\n").unwrap();
    for (f, pw) in [
        ("alice.pw", "alice-secret\n"),
        ("wrong.pw", "guess\n"),
        ("bob.pw", "bob-secret\n"),
    ] {
        std::fs::write(d.join(f), pw).unwrap();
    }
    let ep = "tcp/127.0.0.1:7610";
    let (mut dmn, dlog) = daemon(
        d,
        &format!("[zenoh]\nlisten = [\"{ep}\"]\n[zenoh.auth]\nusers_file = \"users\"\n[zenoh.acl]\nreaders = [\"alice\"]\n"),
    );
    let pw = |f: &str| d.join(f).to_string_lossy().into_owned();
    let (alice_pw, wrong_pw, bob_pw) = (pw("alice.pw"), pw("wrong.pw"), pw("bob.pw"));
    let (_a, alice) = watch(&[
        "--connect",
        ep,
        "--user",
        "alice",
        "--password-file",
        &alice_pw,
    ]);
    let (_n, nobody) = watch(&["--connect", ep]);
    let (_w, wrong) = watch(&[
        "--connect",
        ep,
        "--user",
        "alice",
        "--password-file",
        &wrong_pw,
    ]);
    let (_b, bob) = watch(&["--connect", ep, "--user", "bob", "--password-file", &bob_pw]);
    let py = Command::new("python3")
        .arg(repo().join("tests/python/zenoh_sub.py"))
        .args(["--connect", ep, "--count", "1", "--timeout", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 with eclipse-zenoh (tests/python/requirements.txt) is needed");
    let mut py = Guard(py);

    assert!(
        health(&alice, 3, Duration::from_secs(40)),
        "alice (a listed reader with her password) received no health: {:?}",
        dlog.try_iter().collect::<Vec<_>>()
    );
    alive(&mut dmn, &dlog);
    // The others had the same time and more; give them 3 s beyond alice's third message.
    std::thread::sleep(Duration::from_secs(3));
    for (who, rx) in [
        ("no credentials", &nobody),
        ("a wrong password", &wrong),
        ("bob (valid password, not a reader)", &bob),
    ] {
        let got: Vec<String> = rx.try_iter().collect();
        assert!(got.is_empty(), "a client with {who} received {got:?}");
    }
    // The Python client without credentials times out with nothing (exit 1, count 0).
    let status = {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            if let Some(s) = py.0.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < deadline, "python client did not exit");
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    let mut out = String::new();
    py.0.stdout
        .take()
        .unwrap()
        .read_to_string(&mut out)
        .unwrap();
    assert!(
        !status.success(),
        "python client without credentials: {out}"
    );
    assert!(
        out.contains("\"count\": 0") || out.contains("\"count\":0"),
        "python client without credentials received something: {out}"
    );

    // Read-only: alice puts and deletes on rigmon's keys and queries with a payload.
    let alice_settings = ZenohSettings {
        connect: vec![ep.into()],
        auth: AuthSettings {
            user: Some("alice".into()),
            password_file: Some(d.join("alice.pw")),
            ..Default::default()
        },
        ..Default::default()
    };
    let s = alice_settings.open().unwrap();
    let base = "rigmon/lut-rig/shaft/nde";
    let config_before = {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let r = query(&s, &format!("{base}/config"), None);
            if !r.is_empty() || Instant::now() > deadline {
                break r;
            }
        }
    };
    assert_eq!(
        config_before.len(),
        1,
        "alice's config query got no single reply"
    );
    for k in ["health", "config", "status", "alive", "model", "**"] {
        let key = format!("{base}/{k}");
        let _ = s.put(&key, r#"{"model":{"path":"/dev/null"}}"#).wait();
        let _ = s.delete(&key).wait();
    }
    let with_payload = query(
        &s,
        &format!("{base}/config"),
        Some(r#"{"model":{"path":"/dev/null"},"health":{"vote_k":1}}"#),
    );
    assert_eq!(
        with_payload, config_before,
        "a query payload changed the answer"
    );
    assert!(
        health(&alice, 4, Duration::from_secs(20)),
        "health stopped after the puts and deletes"
    );
    assert_eq!(
        query(&s, &format!("{base}/config"), None),
        config_before,
        "the config changed"
    );
    let _ = s.close().wait();
    alive(&mut dmn, &dlog);
}

#[cfg(feature = "tls")]
fn openssl(dir: &Path, args: &[&str]) {
    let out = Command::new("openssl")
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the openssl CLI is needed for the TLS test (apt-get install openssl)");
    assert!(
        out.status.success(),
        "openssl {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[cfg(feature = "tls")]
#[test]
fn tls_client_with_the_ca_receives_and_one_without_it_does_not() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    openssl(
        d,
        &[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "ca.key",
            "-out",
            "ca.pem",
            "-days",
            "2",
            "-subj",
            "/CN=rigmon test CA",
        ],
    );
    openssl(
        d,
        &[
            "req",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "server.key",
            "-out",
            "server.csr",
            "-subj",
            "/CN=localhost",
        ],
    );
    std::fs::write(
        d.join("san.cnf"),
        "subjectAltName=IP:127.0.0.1,DNS:localhost\n",
    )
    .unwrap();
    openssl(
        d,
        &[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            "server.pem",
            "-days",
            "2",
            "-extfile",
            "san.cnf",
        ],
    );
    let ep = "tls/127.0.0.1:7620";
    let (mut dmn, dlog) = daemon(
        d,
        &format!("[zenoh]\nlisten = [\"{ep}\"]\n[zenoh.tls]\nroot_ca = \"ca.pem\"\ncert = \"server.pem\"\nkey = \"server.key\"\n"),
    );
    let client = d.join("client.json5");
    std::fs::write(
        &client,
        format!(
            "{{ mode: \"peer\", scouting: {{ multicast: {{ enabled: false }} }}, transport: {{ link: {{ tls: {{ root_ca_certificate: {:?} }} }} }} }}",
            d.join("ca.pem")
        ),
    )
    .unwrap();
    let (_c, with_ca) = watch(&["--zenoh-config", client.to_str().unwrap(), "--connect", ep]);
    let (_n, without) = watch(&["--connect", ep]);
    assert!(
        health(&with_ca, 3, Duration::from_secs(40)),
        "a client with the CA received no health over TLS: {:?}",
        dlog.try_iter().collect::<Vec<_>>()
    );
    std::thread::sleep(Duration::from_secs(2));
    let got: Vec<String> = without.try_iter().collect();
    assert!(got.is_empty(), "a client without the CA received {got:?}");
    alive(&mut dmn, &dlog);
}

/// A health message of `rigmon/r1/shaft/nde` (what a historian's reply carries).
fn a_health_message() -> String {
    serde_json::json!({
        "schema": "rigmon.health", "schema_version": 1,
        "rig": "r1", "asset": "shaft", "point": "nde", "seq": 7,
        "window": {"start_s": 3.0, "end_s": 4.0, "start_ns": 1_700_000_003_000_000_000u64, "end_ns": 1_700_000_004_000_000_000u64},
        "publish_time_ns": 1_700_000_004_010_000_000u64, "rpm": 588.0, "speed_source": "tacho",
        "quality": {"ok": true, "flags": [], "clipped_samples": 0, "nan_samples": 0,
                    "dropout_samples": 0, "flat_channels": [], "missing_tacho_pulses": 0},
        "probabilities": {"healthy": 0.1, "outer_race": 0.9},
        "window_state": "outer_race", "unknown_reason": null, "state": "outer_race",
        "state_since_s": 4.0, "state_changed": false, "confidence": 0.9, "novelty": 0.2,
        "novelty_threshold": 1.0,
        "fault_bands": {"channel": "vertical", "orders": {}, "bpfo": [], "bpfi": [], "two_bsf": [], "floor": 0.0},
        "velocity_rms_mm_s": null, "iso_zone": null,
        "model": {"id": "m", "sha256": "ab", "labels": ["healthy", "outer_race"]},
        "calibration_id": null, "software_version": "0.1.0"
    })
    .to_string()
}

/// `rigmon history` with extra arguments: exit code, stdout, stderr, seconds taken.
fn history(args: &[&str]) -> (i32, String, String, f64) {
    let t = Instant::now();
    let out = Command::new(bin())
        .args(["history", "rigmon/r1/shaft/nde", "--since", "100000h"])
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        t.elapsed().as_secs_f64(),
    )
}

/// Issue 38, F6 and F13. With `[zenoh.acl]` on the node others connect to, an authorised
/// reader's `rigmon history` got nothing ("is a historian running and reachable?"): the
/// list let queries and replies through only one way. Now a user listed in `historians`
/// answers history through it and `readers` receive the answers. A historian given the
/// list in its own config passed `--check` and then stored nothing; now `--check` refuses
/// it. And `rigmon history --timeout 2` with nothing listening, or with a password the node
/// refuses, hung (a client retried forever); now it ends by its timeout saying so.
#[test]
fn history_passes_the_acl_and_ends_by_its_timeout() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("users"), "alice:alice-secret\nhist:hist-secret\n").unwrap();
    for (f, pw) in [
        ("alice.pw", "alice-secret\n"),
        ("hist.pw", "hist-secret\n"),
        ("wrong.pw", "guess\n"),
    ] {
        std::fs::write(d.join(f), pw).unwrap();
    }
    let ep = "tcp/127.0.0.1:7621";
    let node_toml = format!(
        "listen = [\"{ep}\"]\n[auth]\nusers_file = {:?}\n[acl]\nreaders = [\"alice\"]\nhistorians = [\"hist\"]\n",
        d.join("users")
    );
    let node: ZenohSettings = toml::from_str(&node_toml).unwrap();
    let node = node.open().unwrap();
    let hist = ZenohSettings {
        mode: rigmon::vocabulary::ZenohMode::Client,
        connect: vec![ep.into()],
        auth: AuthSettings {
            user: Some("hist".into()),
            password_file: Some(d.join("hist.pw")),
            ..Default::default()
        },
        ..Default::default()
    }
    .open()
    .unwrap();
    let reply = a_health_message();
    let _q = hist
        .declare_queryable("rigmon/**/health")
        .callback(move |q| {
            if q.parameters().get("_time").is_some() {
                let _ = q.reply("rigmon/r1/shaft/nde/health", reply.clone()).wait();
            }
        })
        .wait()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let pw = |f: &str| d.join(f).to_string_lossy().into_owned();
    let (rc, out, err, _) = history(&[
        "--connect",
        ep,
        "--user",
        "alice",
        "--password-file",
        &pw("alice.pw"),
        "--json",
        "--timeout",
        "5",
    ]);
    assert_eq!(rc, 0, "alice's history through the ACL: {err}");
    assert_eq!(out.lines().count(), 1, "{out}");
    assert!(out.contains("\"rig\":\"r1\""), "{out}");

    // Credentials refused, and nothing listening: ended by --timeout 2, saying so.
    let (rc, _, err, took) = history(&[
        "--connect",
        ep,
        "--user",
        "alice",
        "--password-file",
        &pw("wrong.pw"),
        "--timeout",
        "2",
    ]);
    assert!(rc == 1 && took < 6.0, "rc {rc} after {took:.1} s: {err}");
    assert!(
        err.contains("nothing reachable at tcp/127.0.0.1:7621"),
        "{err}"
    );
    let (rc, _, err, took) = history(&["--connect", "tcp/127.0.0.1:7622", "--timeout", "2"]);
    assert!(rc == 1 && took < 6.0, "rc {rc} after {took:.1} s: {err}");
    assert!(
        err.contains("nothing reachable at tcp/127.0.0.1:7622"),
        "{err}"
    );
    let error = err.lines().find(|l| l.starts_with("error:")).unwrap_or("");
    assert!(
        !error.is_empty() && !error.contains(".rs:"),
        "rigmon's error, without source paths (zenoh's own log lines aside): {err}"
    );

    // A historian whose own config holds the list would store nothing: refused at --check.
    std::fs::write(
        d.join("historian.toml"),
        format!(
            "[zenoh]\nmode = \"client\"\nconnect = [\"{ep}\"]\n[zenoh.auth]\nusers_file = \"users\"\nuser = \"hist\"\npassword_file = \"hist.pw\"\n[zenoh.acl]\nreaders = [\"hist\"]\n"
        ),
    )
    .unwrap();
    let out = Command::new(bin())
        .args(["historian", "--check", "--config"])
        .arg(d.join("historian.toml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("would store nothing"), "{err}");
    drop(hist);
    drop(node);
}
