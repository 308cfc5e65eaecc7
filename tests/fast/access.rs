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
