//! The daemon end to end, with real parts: the built `rigmon` binary, the shipped replays and
//! model, Zenoh sessions on loopback TCP (explicit endpoints, multicast scouting off), the
//! Python eclipse-zenoh client, a NOTIFY_SOCKET datagram socket, Unix signals, MCAP files read
//! back, and `systemd-analyze verify`.

use crate::daemon_harness::{bin, daemon_config, lines, repo, signal, wait_exit, Guard};
use crate::wrong_shape;

use rigmon::wire::health::HealthMessage;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::net::UnixDatagram;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};

fn model() -> PathBuf {
    let m = repo().join("models/lut-rig.onnx");
    assert!(
        m.exists(),
        "{} is missing: the trained model is part of the repository (rigmon train writes it)",
        m.display()
    );
    m
}

/// The shipped simulated replays of the LUT rig (`replay/lut-*.mcap`) with the label stored in
/// each file's metadata (the measured CWRU replay belongs to another rig).
fn replays() -> Vec<(PathBuf, String)> {
    let dir = repo().join("replay");
    let rig = rig();
    let mut out: Vec<(PathBuf, String)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| {
            panic!(
                "{}: {e}; the shipped replays are part of the repository",
                dir.display()
            )
        })
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("lut-"))
        })
        .map(|p| {
            let rec = rigmon::importers::load(&p, &rig, &Default::default()).unwrap();
            let label = rec
                .label()
                .unwrap_or_else(|| panic!("{}: no label in the metadata", p.display()))
                .to_string();
            (p, label)
        })
        .collect();
    out.sort();
    assert!(
        !out.is_empty(),
        "no replay/*.mcap files found in {}",
        dir.display()
    );
    out
}

pub(crate) fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn rig() -> rigmon::config::RigConfig {
    rigmon::config::RigConfig::load(&repo().join("config/lut-rig.toml")).unwrap()
}

/// Windows a recording yields with the rig's window/hop.
fn expected_windows(path: &Path) -> usize {
    let rig = rig();
    let rec = rigmon::importers::load(path, &rig, &Default::default()).unwrap();
    let fs = rec.sample_rate;
    let (w, h) = (
        (rig.features.window_s * fs).round() as usize,
        (rig.features.hop_s * fs).round() as usize,
    );
    (rec.len() - w) / h + 1
}

/// Wait for a line containing `needle`, collecting everything seen.
fn wait_line(
    rx: &Receiver<String>,
    needle: &str,
    timeout: Duration,
    seen: &mut Vec<String>,
) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if let Ok(l) = rx.recv_timeout(Duration::from_millis(100)) {
            let hit = l.contains(needle);
            seen.push(l);
            if hit {
                return true;
            }
        }
    }
    false
}

#[test]
fn replays_reach_watch_and_python_over_zenoh_with_expected_states() {
    model();
    for (file, label) in replays() {
        let n = expected_windows(&file);
        let (p1, p2) = (free_port(), free_port());
        let (e1, e2) = (format!("tcp/127.0.0.1:{p1}"), format!("tcp/127.0.0.1:{p2}"));
        let tmp = tempfile::tempdir().unwrap();
        let ready = tmp.path().join("py.ready");

        // Subscribers listen; the replaying daemon connects to both.
        let mut watch = Command::new(bin())
            .args([
                "watch",
                "--json",
                "--listen",
                &e1,
                "--count",
                &n.to_string(),
                "--timeout",
                "60",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let watch_out = lines(watch.stdout.take().unwrap());
        let watch_err = lines(watch.stderr.take().unwrap());
        let mut watch = Guard(watch);
        let py = Command::new("python3")
            .arg(repo().join("tests/python/zenoh_sub.py"))
            .args([
                "--listen",
                &e2,
                "--count",
                &n.to_string(),
                "--timeout",
                "60",
                "--ready-file",
            ])
            .arg(&ready)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("python3 with eclipse-zenoh (tests/python/requirements.txt) is needed");
        let mut py = Guard(py);
        let mut seen = Vec::new();
        assert!(
            wait_line(
                &watch_err,
                "subscribed to",
                Duration::from_secs(20),
                &mut seen
            ),
            "watch did not start: {seen:?}"
        );
        let t = Instant::now();
        while !ready.exists() {
            assert!(
                t.elapsed() < Duration::from_secs(20),
                "python subscriber did not start"
            );
            std::thread::sleep(Duration::from_millis(50));
        }

        let out = Command::new(bin())
            .arg("replay")
            .arg(&file)
            .args([
                "--json",
                "--speed",
                "max",
                "--wait-subscriber",
                "10",
                "--connect",
                &e1,
                "--connect",
                &e2,
            ])
            .args([
                "--rig",
                repo().join("config/lut-rig.toml").to_str().unwrap(),
                "--model",
                model().to_str().unwrap(),
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success(),
            "replay {} failed: {stderr}",
            file.display()
        );
        let printed: Vec<HealthMessage> = String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(
            printed.len(),
            n,
            "replay printed {} health lines for {n} windows: {stderr}",
            printed.len()
        );

        // (a) rigmon watch --json.
        let status = wait_exit(&mut watch.0, Duration::from_secs(30));
        let got: Vec<HealthMessage> = watch_out
            .try_iter()
            .map(|l| serde_json::from_str(&l).unwrap())
            .collect();
        assert!(
            status.success(),
            "watch failed after {} messages: {:?}",
            got.len(),
            watch_err.try_iter().collect::<Vec<_>>()
        );
        assert_eq!(got.len(), n, "watch got {} of {n}", got.len());
        assert_eq!(
            got, printed,
            "watch must see exactly what the daemon published"
        );
        let seqs: Vec<u64> = got.iter().map(|m| m.seq).collect();
        assert_eq!(seqs, (1..=n as u64).collect::<Vec<_>>());
        let final_state = &got.last().unwrap().state;
        assert_eq!(
            final_state,
            &label,
            "{}: final smoothed state",
            file.display()
        );
        let agree = got.iter().filter(|m| m.state == label).count();
        assert!(
            agree * 2 > n,
            "{}: only {agree} of {n} windows in state {label}",
            file.display()
        );
        assert!(got
            .iter()
            .all(|m| m.rig == "lut-rig" && m.model.labels.contains(&label)));

        // (b) the independent Python client.
        let status = wait_exit(&mut py.0, Duration::from_secs(30));
        let mut s = String::new();
        py.0.stdout.take().unwrap().read_to_string(&mut s).unwrap();
        let mut e = String::new();
        py.0.stderr.take().unwrap().read_to_string(&mut e).unwrap();
        assert!(status.success(), "python subscriber: {s} {e}");
        let v: serde_json::Value = serde_json::from_str(s.trim()).unwrap();
        assert_eq!(v["count"], n as u64, "{v}");
        assert_eq!(v["final_state"], label.as_str(), "{v}");
        assert_eq!(v["keys"][0], "rigmon/lut-rig/shaft/nde/health", "{v}");
        let py_states: BTreeMap<String, u64> = serde_json::from_value(v["states"].clone()).unwrap();
        assert_eq!(
            py_states.get(&label).copied().unwrap_or(0) as usize,
            agree,
            "{v}"
        );
    }
}

#[test]
fn sd_notify_ready_watchdog_status_then_sigterm_stops_cleanly_and_closes_the_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let sock_path = tmp.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let (file, _) = replays().into_iter().next().unwrap();
    let cfg = daemon_config(tmp.path(), &file, &model(), "1.0", free_port(), true);
    let child = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap()])
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "600000")
        .env_remove("WATCHDOG_PID")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = Guard(child);
    let err = lines(child.0.stderr.take().unwrap());

    let mut got: Vec<String> = Vec::new();
    let mut buf = vec![0u8; 4096];
    let deadline = Instant::now() + Duration::from_secs(30);
    let has = |got: &Vec<String>, s: &str| got.iter().any(|m| m.lines().any(|l| l.starts_with(s)));
    while Instant::now() < deadline
        && !(has(&got, "READY=1")
            && got.iter().filter(|m| m.contains("WATCHDOG=1")).count() >= 3
            && has(&got, "STATUS=running"))
    {
        if let Ok(n) = sock.recv(&mut buf) {
            got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
        }
    }
    assert!(has(&got, "READY=1"), "no READY=1: {got:?}");
    assert!(has(&got, "STATUS="), "no STATUS=: {got:?}");
    assert!(
        got.iter().filter(|m| m.contains("WATCHDOG=1")).count() >= 3,
        "watchdog not petted: {got:?}"
    );
    let ready_at = got.iter().position(|m| m.contains("READY=1")).unwrap();
    let first_pet = got.iter().position(|m| m.contains("WATCHDOG=1")).unwrap();
    assert!(ready_at <= first_pet, "READY=1 must come first: {got:?}");
    // Let at least one recording flush happen, then stop.
    std::thread::sleep(Duration::from_millis(1500));
    signal(&child.0, libc::SIGTERM);
    let deadline = Instant::now() + Duration::from_secs(15);
    while Instant::now() < deadline && !has(&got, "STOPPING=1") {
        if let Ok(n) = sock.recv(&mut buf) {
            got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
        }
    }
    assert!(has(&got, "STOPPING=1"), "no STOPPING=1: {got:?}");
    let status = wait_exit(&mut child.0, Duration::from_secs(15));
    assert!(
        status.success(),
        "daemon exit {status:?}: {:?}",
        err.try_iter().collect::<Vec<_>>()
    );

    // The recording was closed cleanly: one file per segment holds the raw layout and the
    // /features and /health channels, and reads back with a summary.
    let rec_dir = tmp.path().join("rec");
    let files: Vec<PathBuf> = std::fs::read_dir(&rec_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".mcap"))
        .collect();
    assert_eq!(files.len(), 1, "one segment expected: {files:?}");
    let raw = &files[0];
    let rec = rigmon::recording::mcap::read_recording(raw).unwrap();
    assert_eq!(rec.channels.len(), 3);
    assert!(rec.duration_s() >= 1.0, "recorded {} s", rec.duration_s());
    let bytes = std::fs::read(raw).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a cleanly closed MCAP has a summary");
    let mut health = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "/health" {
            let h: HealthMessage = serde_json::from_slice(&m.data).unwrap();
            assert_eq!(h.rig, "lut-rig");
            health += 1;
        }
    }
    assert!(health >= 2, "only {health} health messages recorded");
    assert!(summary.stats.is_some());
}

#[test]
fn sighup_swaps_the_model_without_losing_windows_and_rejects_a_bad_one() {
    let tmp = tempfile::tempdir().unwrap();
    let live_model = tmp.path().join("model.onnx");
    std::fs::copy(model(), &live_model).unwrap();
    // A second valid model: the same network with one more metadata entry (so another hash),
    // written by the onnx Python package and checked by its checker.
    let variant = tmp.path().join("variant.onnx");
    let py = Command::new("python3")
        .args([
            "-c",
            "import onnx,sys; m=onnx.load(sys.argv[1]); p=m.metadata_props.add(); p.key='variant'; p.value='b'; onnx.checker.check_model(m); onnx.save(m, sys.argv[2])",
        ])
        .arg(model())
        .arg(&variant)
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );

    let (file, _) = replays().into_iter().next().unwrap();
    let cfg = daemon_config(tmp.path(), &file, &live_model, "4.0", free_port(), false);
    let child = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap(), "--print", "json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = Guard(child);
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let mut msgs: Vec<HealthMessage> = Vec::new();
    let take = |msgs: &mut Vec<HealthMessage>, k: usize| {
        for _ in 0..k {
            let l = out
                .recv_timeout(Duration::from_secs(20))
                .expect("health line");
            msgs.push(serde_json::from_str(&l).unwrap());
        }
    };
    take(&mut msgs, 3);
    let sha0 = msgs[0].model.sha256.clone();

    // A corrupt model: rejected, the old one keeps running.
    std::fs::write(&live_model, b"not an onnx model").unwrap();
    signal(&child.0, libc::SIGHUP);
    let mut seen = Vec::new();
    assert!(
        wait_line(&err, "reload rejected", Duration::from_secs(20), &mut seen),
        "{seen:?}"
    );
    take(&mut msgs, 3);
    assert!(msgs.iter().all(|m| m.model.sha256 == sha0));

    // A real ONNX model of the wrong shape (its first 50 inputs only): rejected too.
    wrong_shape::write_wrong_shape_model(&model(), &live_model);
    signal(&child.0, libc::SIGHUP);
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &err,
            "model expects 50 bins",
            Duration::from_secs(20),
            &mut seen
        ),
        "{seen:?}"
    );
    take(&mut msgs, 3);
    assert!(msgs.iter().all(|m| m.model.sha256 == sha0));

    // A valid model trained for another rig (issue 25, finding 1: before, SIGHUP swapped the
    // CWRU model in and the outer-race state fell to unknown): rejected, naming both rigs.
    std::fs::copy(repo().join("models/cwru-de.onnx"), &live_model).unwrap();
    signal(&child.0, libc::SIGHUP);
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &err,
            "rig_id: model cwru-de, rig file lut-rig",
            Duration::from_secs(20),
            &mut seen
        ),
        "{seen:?}"
    );
    assert!(
        seen.iter().any(|l| l.contains("reload rejected")),
        "{seen:?}"
    );
    take(&mut msgs, 3);
    assert!(msgs.iter().all(|m| m.model.sha256 == sha0));
    assert!(msgs.iter().all(|m| m.model.foreign.is_empty()));

    // A good new model: swapped in between two windows.
    std::fs::copy(&variant, &live_model).unwrap();
    signal(&child.0, libc::SIGHUP);
    let deadline = Instant::now() + Duration::from_secs(30);
    while msgs.last().unwrap().model.sha256 == sha0 {
        assert!(Instant::now() < deadline, "model never swapped");
        take(&mut msgs, 1);
    }
    take(&mut msgs, 2);
    signal(&child.0, libc::SIGTERM);
    let status = wait_exit(&mut child.0, Duration::from_secs(15));
    assert!(status.success());
    for l in out.try_iter() {
        msgs.push(serde_json::from_str(&l).unwrap());
    }
    let seqs: Vec<u64> = msgs.iter().map(|m| m.seq).collect();
    assert_eq!(
        seqs,
        (1..=msgs.len() as u64).collect::<Vec<_>>(),
        "no window may be lost across reloads"
    );
    assert!(
        msgs.iter().all(|m| m.quality.dropout_samples == 0),
        "no samples may be lost across reloads"
    );
    let shas: std::collections::BTreeSet<&str> =
        msgs.iter().map(|m| m.model.sha256.as_str()).collect();
    assert_eq!(shas.len(), 2);
}

#[test]
fn systemd_unit_passes_systemd_analyze_verify() {
    let unit = std::fs::read_to_string(repo().join("systemd/rigmon.service")).unwrap();
    for key in [
        "Type=notify",
        "WatchdogSec=",
        "Restart=on-failure",
        "ProtectSystem=strict",
        "StateDirectory=",
        "NoNewPrivileges=yes",
        "AF_CAN",
        "DeviceAllow=",
        "SupplementaryGroups=",
    ] {
        assert!(unit.contains(key), "unit lacks {key}");
    }
    // verify checks that ExecStart exists: point it at the binary under test.
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("rigmon.service");
    std::fs::write(&p, unit.replace("/usr/local/bin/rigmon", bin())).unwrap();
    let out = Command::new("systemd-analyze")
        .args(["verify", "--man=no"])
        .arg(&p)
        .output()
        .expect("systemd-analyze is needed (apt-get install systemd)");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success() && !text.contains("rigmon.service:"),
        "systemd-analyze verify: {text}"
    );
}

const PY_ROUTER: &str = r#"
import json, sys, time, zenoh
c = zenoh.Config()
c.insert_json5("mode", '"router"')
c.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:" + sys.argv[1]]))
c.insert_json5("connect/endpoints", "[]")
c.insert_json5("scouting/multicast/enabled", "false")
s = zenoh.open(c)
print("up", flush=True)
while True:
    time.sleep(1)
"#;

fn router(port: u16) -> Guard {
    let mut c = Command::new("python3")
        .args(["-c", PY_ROUTER, &port.to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let out = lines(c.stdout.take().unwrap());
    assert_eq!(
        out.recv_timeout(Duration::from_secs(20))
            .expect("python zenoh router did not start"),
        "up"
    );
    Guard(c)
}

#[test]
fn survives_a_router_restart_and_answers_queries_and_liveliness() {
    let tmp = tempfile::tempdir().unwrap();
    let port = free_port();
    let ep = format!("tcp/127.0.0.1:{port}");
    let mut r = router(port);
    let (file, label) = replays().into_iter().find(|(_, l)| l != "healthy").unwrap();
    let cfg = daemon_config(tmp.path(), &file, &model(), "2.0", free_port(), false);
    // Client mode through the router (the config's listen endpoint is replaced by none).
    let daemon = Command::new(bin())
        .args([
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--mode",
            "client",
            "--connect",
            &ep,
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut daemon = Guard(daemon);
    let _daemon_err = lines(daemon.0.stderr.take().unwrap());
    let watch = Command::new(bin())
        .args(["watch", "--json", "--mode", "client", "--connect", &ep])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut watch = Guard(watch);
    let got = lines(watch.0.stdout.take().unwrap());
    for _ in 0..3 {
        got.recv_timeout(Duration::from_secs(20))
            .expect("health through the router");
    }

    // Kill the router, restart it, and time how long until health flows again.
    r.0.kill().unwrap();
    r.0.wait().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    while got.try_recv().is_ok() {}
    let t = Instant::now();
    let _r2 = router(port);
    let first: HealthMessage = serde_json::from_str(
        &got.recv_timeout(Duration::from_secs(30))
            .expect("health resumed after the router restart"),
    )
    .unwrap();
    println!(
        "FIGURE router restart: health resumed {:.1} s after the router restarted",
        t.elapsed().as_secs_f64()
    );
    assert_eq!(first.state, label);

    // Read-only queryables: the latest health and the running config.
    let q = |key: &str| {
        let out = Command::new(bin())
            .args([
                "watch",
                "--query",
                "--json",
                "--mode",
                "client",
                "--connect",
                &ep,
                key,
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "query {key}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let latest: HealthMessage =
        serde_json::from_str(q("rigmon/lut-rig/shaft/nde/health").trim()).unwrap();
    assert_eq!(latest.rig, "lut-rig");
    let config: serde_json::Value =
        serde_json::from_str(q("rigmon/lut-rig/shaft/nde/config").trim()).unwrap();
    assert_eq!(config["zenoh"]["mode"], "client", "{config}");
    assert_eq!(config["health"]["vote_k"], 3, "{config}");
    // The liveliness token, seen by the independent Python client.
    let live = Command::new("python3")
        .args([
            "-c",
            "import json,sys,zenoh\nc=zenoh.Config()\nc.insert_json5('mode','\"client\"')\nc.insert_json5('connect/endpoints',json.dumps([sys.argv[1]]))\nc.insert_json5('scouting/multicast/enabled','false')\nwith zenoh.open(c) as s:\n    print(sorted(str(r.ok.key_expr) for r in s.liveliness().get('rigmon/**', timeout=5.0) if r.ok))",
            &ep,
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&live.stdout);
    assert!(
        text.contains("rigmon/lut-rig/shaft/nde/alive"),
        "liveliness: {text} {}",
        String::from_utf8_lossy(&live.stderr)
    );
    signal(&daemon.0, libc::SIGTERM);
    assert!(wait_exit(&mut daemon.0, Duration::from_secs(15)).success());
    let _ = watch.0.kill();
}

/// Serial emulator on a real pty -> daemon (a child process) -> Zenoh on loopback: corrupt
/// frames are counted, an unplug of 1.1 s shows as `connected: false`, the source reconnects
/// once the pty is back and health resumes. Prints how long after the replug the source was
/// reading again (from the daemon's "reconnected" log line).
#[test]
fn serial_emulator_corrupt_frames_and_unplug_are_counted_in_status_and_health_resumes() {
    use rigmon::acquire::emulator::{EmulatorOptions, EmulatorPort, SerialEmulator};
    use rigmon::acquire::{FileSourceConfig, ReplaySpeed, StopToken};
    let tmp = tempfile::tempdir().unwrap();
    let rig = rig();
    let (file, label) = replays().into_iter().find(|(_, l)| l != "healthy").unwrap();
    let mut fc = FileSourceConfig::new(&file);
    fc.speed = ReplaySpeed::Factor(2.0);
    let replay = fc.build(&rig).unwrap();
    let opts = EmulatorOptions {
        speed: ReplaySpeed::Factor(2.0),
        corrupt_every: Some(400),
        // Sample-clock seconds: 3 s of wall time at speed 2, after the daemon is up.
        unplug_after_s: Some(6.0),
        unplug_for_s: 1.1,
        looping: true,
        ..EmulatorOptions::default()
    };
    let emu = SerialEmulator::new(replay, &rig, opts).unwrap();
    let link = tmp.path().join("ttyRIG");
    let stop = StopToken::new();
    let (ptx, prx) = channel();
    let emu_thread = {
        let (stop, link) = (stop.clone(), link.clone());
        std::thread::spawn(move || {
            emu.run(
                &EmulatorPort::Pty { link: Some(link) },
                &stop,
                &mut |p: &str| {
                    let _ = ptx.send((p.to_string(), Instant::now()));
                },
            )
        })
    };
    prx.recv_timeout(Duration::from_secs(10))
        .expect("emulator pty");

    let port = 7600;
    let cfg = tmp.path().join("rigmon.toml");
    std::fs::write(
        &cfg,
        format!(
            "rig = \"{}\"\n[model]\npath = \"{}\"\n[source]\ntype = \"serial\"\nport = \"{}\"\nreconnect_max_ms = 200\n[pipeline]\nstatus_every_s = 0.25\n[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n",
            repo().join("config/lut-rig.toml").display(),
            model().display(),
            link.display()
        ),
    )
    .unwrap();
    let daemon = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap()])
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut daemon = Guard(daemon);
    // Daemon log lines with the time they arrived.
    let derr = {
        let (tx, rx) = channel();
        let r = daemon.0.stderr.take().unwrap();
        std::thread::spawn(move || {
            for l in BufReader::new(r).lines() {
                let Ok(l) = l else { break };
                if tx.send((l, Instant::now())).is_err() {
                    break;
                }
            }
        });
        rx
    };
    let ep = format!("tcp/127.0.0.1:{port}");
    let watch = Command::new(bin())
        .args([
            "watch",
            "--json",
            "--connect",
            &ep,
            "rigmon/lut-rig/shaft/nde/*",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut watch = Guard(watch);
    let got = lines(watch.0.stdout.take().unwrap());

    // Run until the status shows bad frames, the unplug and a reconnect, and health kept
    // coming after the reconnect.
    let deadline = Instant::now() + Duration::from_secs(60);
    let (mut bad, mut reconnects, mut lost) = (0u64, 0u64, 0u64);
    let (mut disconnected_seen, mut health_after_replug) = (0usize, 0usize);
    let mut states = Vec::new();
    let mut last_status = serde_json::Value::Null;
    while Instant::now() < deadline && !(bad > 0 && reconnects > 0 && health_after_replug >= 6) {
        let Ok(l) = got.recv_timeout(Duration::from_secs(1)) else {
            continue;
        };
        let v: serde_json::Value = serde_json::from_str(&l).unwrap();
        match v["schema"].as_str() {
            Some("rigmon.status") => {
                bad = v["source"]["bad_frames"].as_u64().unwrap();
                reconnects = v["source"]["reconnects"].as_u64().unwrap();
                lost = v["source"]["samples_lost"].as_u64().unwrap()
                    + v["pipeline"]["samples_lost"].as_u64().unwrap();
                if v["source"]["connected"] == serde_json::Value::Bool(false) {
                    disconnected_seen += 1;
                }
                last_status = v;
            }
            Some("rigmon.health") => {
                let m: HealthMessage = serde_json::from_value(v).unwrap();
                if reconnects > 0 {
                    health_after_replug += 1;
                }
                states.push(m.state);
            }
            _ => {}
        }
    }
    let log: Vec<(String, Instant)> = derr.try_iter().collect();
    let text: Vec<&str> = log.iter().map(|(l, _)| l.as_str()).collect();
    assert!(bad > 0, "no bad frames counted in status: {text:?}");
    assert!(
        lost > 0,
        "corrupt frames and the unplug must show up as lost samples: {last_status}"
    );
    assert!(
        disconnected_seen > 0,
        "no status with connected = false during the 1.1 s unplug: {last_status} {text:?}"
    );
    assert!(
        reconnects >= 1,
        "the source did not reconnect after the replug: {last_status} {text:?}"
    );
    assert!(
        health_after_replug >= 6,
        "health did not resume after the reconnect ({health_after_replug}): {text:?}"
    );
    assert!(
        last_status["source"]["connected"].as_bool() == Some(true),
        "{last_status}"
    );
    assert_eq!(states.last().unwrap(), &label, "{states:?}");
    // Reconnect delay: the emulator's second announce (pty back) to the daemon's log line.
    let (_, replugged) = prx
        .recv_timeout(Duration::from_secs(1))
        .expect("the emulator announced no replug");
    let (_, reconnected) = log
        .iter()
        .find(|(l, _)| l.contains("reconnected"))
        .unwrap_or_else(|| panic!("no 'reconnected' line in the daemon log: {text:?}"));
    println!(
        "FIGURE serial reconnect {:.0} ms after replug (reconnect_max_ms = 200), {disconnected_seen} status messages with connected = false, reconnects = {reconnects}, bad frames = {bad}",
        reconnected.saturating_duration_since(replugged).as_secs_f64() * 1e3
    );
    assert!(daemon.0.try_wait().unwrap().is_none(), "daemon exited");
    stop.stop();
    signal(&daemon.0, libc::SIGTERM);
    assert!(wait_exit(&mut daemon.0, Duration::from_secs(15)).success());
    let _ = watch.0.kill();
    let report = emu_thread.join().unwrap().unwrap();
    assert!(report.corrupted > 0, "{report:?}");
    assert_eq!(report.unplugs, 1, "{report:?}");
}

/// `rigmon <args>` to completion within `timeout`: (exit code, None when killed by a
/// signal; stdout; stderr).
fn rigmon_within(args: &[&str], timeout: Duration) -> (Option<i32>, String, String) {
    let child = Command::new(bin())
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = Guard(child);
    let (out, err) = (
        lines(child.0.stdout.take().unwrap()),
        lines(child.0.stderr.take().unwrap()),
    );
    let status = wait_exit(&mut child.0, timeout);
    std::thread::sleep(Duration::from_millis(50));
    let join = |rx: Receiver<String>| rx.try_iter().collect::<Vec<_>>().join("\n");
    (status.code(), join(out), join(err))
}

/// A copy of config/lut-rig.toml in `dir` with one line replaced.
fn lut_rig_with(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("config/lut-rig.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    let p = dir.join(name);
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    p
}

/// Issue 25, findings 2, 9, 10 and 12: `run --check` runs exactly the checks `run` runs. For
/// each broken config it fails with the reason, and `run` fails the same way (exit code 1,
/// never a signal); errors carry no source paths. Before, `--check` said `ok` for all of
/// these, `run` then aborted (SIGABRT on `window_s = 1e9`), failed ("is the port already in
/// use?" with zenoh's source path for port 99999), or ran a wrong-rig model.
#[test]
fn run_check_runs_exactly_the_checks_run_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let (file, _) = replays().into_iter().next().unwrap();
    let port = free_port();
    let good = daemon_config(tmp.path(), &file, &model(), "4.0", port, false);
    let text = std::fs::read_to_string(&good).unwrap();
    let (rc, out, err) = rigmon_within(
        &["run", "--config", good.to_str().unwrap(), "--check"],
        Duration::from_secs(30),
    );
    assert_eq!(rc, Some(0), "{err}");
    assert!(out.starts_with("ok: rig lut-rig"), "{out}");

    let rig_file = repo().join("config/lut-rig.toml").display().to_string();
    let huge = lut_rig_with(tmp.path(), "huge.toml", "window_s = 1.0", "window_s = 1e9");
    let nyquist = lut_rig_with(
        tmp.path(),
        "nyq.toml",
        "lowpass_hz = 4000.0",
        "lowpass_hz = 9000.0",
    );
    let orders = lut_rig_with(
        tmp.path(),
        "ord.toml",
        "max_order = 50.0",
        "max_order = 4000.0",
    );
    let held = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let busy = held.local_addr().unwrap().port();
    let listen = format!("tcp/127.0.0.1:{port}");
    let cases = [
        (
            "port out of range",
            text.replace(&listen, "tcp/127.0.0.1:99999"),
            "port \"99999\" is not a port number",
        ),
        (
            "port in use",
            text.replace(&listen, &format!("tcp/127.0.0.1:{busy}")),
            "already listens there",
        ),
        (
            "window_s = 1e9",
            text.replace(&rig_file, huge.to_str().unwrap()),
            "features.window_s = 1000000000 s: at most 3600 s",
        ),
        (
            "low-pass past Nyquist",
            text.replace(&rig_file, nyquist.to_str().unwrap()),
            "features.lowpass_hz = 9000 Hz is at or above the Nyquist frequency 5000 Hz",
        ),
        (
            "orders past the low-pass",
            text.replace(&rig_file, orders.to_str().unwrap()),
            "features.max_order = 4000 puts the highest order at 8000 Hz",
        ),
        (
            "wrong-rig model",
            text.replace(
                &model().display().to_string(),
                &repo().join("models/cwru-de.onnx").display().to_string(),
            ),
            "rig_id: model cwru-de, rig file lut-rig",
        ),
    ];
    for (what, config, says) in cases {
        let p = tmp.path().join("case.toml");
        std::fs::write(&p, &config).unwrap();
        for mode in [&["--check"][..], &[][..]] {
            let mut args = vec!["run", "--config", p.to_str().unwrap()];
            args.extend(mode);
            let (rc, _, err) = rigmon_within(&args, Duration::from_secs(30));
            assert_eq!(rc, Some(1), "{what} {mode:?}: exit {rc:?}: {err}");
            assert!(err.contains(says), "{what} {mode:?}: {says:?} not in {err}");
            assert!(
                !err.contains(".rs:") && !err.contains(".cargo/registry"),
                "{what} {mode:?}: a source path: {err}"
            );
        }
    }
    drop(held);

    // The other commands that size a window refuse it the same way instead of aborting.
    let file = file.to_str().unwrap();
    let huge = huge.to_str().unwrap();
    let model = model();
    for args in [
        vec!["features", file, "--rig", huge],
        vec![
            "replay",
            file,
            "--rig",
            huge,
            "--model",
            model.to_str().unwrap(),
            "--quiet",
        ],
    ] {
        let (rc, _, err) = rigmon_within(&args, Duration::from_secs(30));
        assert_eq!(rc, Some(1), "{args:?}: {err}");
        assert!(
            err.contains("features.window_s") && err.contains("huge.toml"),
            "{err}"
        );
    }
}

/// Issue 25, finding 9: a recording folder that cannot be created never stops monitoring (as
/// the docs promise): `run --check` names it and fails, `run` keeps publishing health, says
/// so in its log and in the status topic (`recording.failed`), retries, and stops cleanly.
/// Before, `run` exited 1 at start and monitoring never began, while `--check` said `ok`.
#[test]
fn a_recording_folder_that_cannot_be_created_never_stops_monitoring() {
    let tmp = tempfile::tempdir().unwrap();
    let (file, label) = replays().into_iter().find(|(_, l)| l != "healthy").unwrap();
    let port = free_port();
    let cfg = daemon_config(tmp.path(), &file, &model(), "4.0", port, true);
    // The recording folder lies under a plain file: it cannot be created, even by root.
    let plain = tmp.path().join("plain");
    std::fs::write(&plain, b"not a folder").unwrap();
    let rec = tmp.path().join("rec").display().to_string();
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(
        &cfg,
        text.replace(&rec, &plain.join("rec").display().to_string()),
    )
    .unwrap();

    let (rc, _, err) = rigmon_within(
        &["run", "--config", cfg.to_str().unwrap(), "--check"],
        Duration::from_secs(30),
    );
    assert_eq!(rc, Some(1), "{err}");
    assert!(
        err.contains("recording.dir")
            && err.contains("plain/rec")
            && err.contains("Not a directory"),
        "{err}"
    );

    let child = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap(), "--print", "json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = Guard(child);
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let watch = Command::new(bin())
        .args(["watch", "--json", "--count", "1", "--connect"])
        .arg(format!("tcp/127.0.0.1:{port}"))
        .arg("rigmon/lut-rig/shaft/nde/status")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut watch = Guard(watch);
    let status_line = lines(watch.0.stdout.take().unwrap());
    let mut msgs: Vec<HealthMessage> = Vec::new();
    // 7 s of wall time at speed 4: past the first retry of the recorder (every 5 s).
    let deadline = Instant::now() + Duration::from_secs(7);
    while Instant::now() < deadline {
        if let Ok(l) = out.recv_timeout(Duration::from_secs(20)) {
            msgs.push(serde_json::from_str(&l).unwrap());
        } else {
            break;
        }
    }
    assert!(
        msgs.len() >= 20,
        "monitoring must go on: {} messages",
        msgs.len()
    );
    assert_eq!(msgs.last().unwrap().state, label);
    let status: serde_json::Value = serde_json::from_str(
        &status_line
            .recv_timeout(Duration::from_secs(20))
            .expect("a status message"),
    )
    .unwrap();
    let failed = status["recording"]["failed"].as_str().unwrap_or_default();
    assert!(failed.contains("plain/rec"), "{status}");
    signal(&child.0, libc::SIGTERM);
    assert!(wait_exit(&mut child.0, Duration::from_secs(15)).success());
    let log: Vec<String> = err.try_iter().collect();
    let retries = log
        .iter()
        .filter(|l| l.contains("monitoring continues without recording"))
        .count();
    assert!(retries >= 2, "a failure and at least one retry: {log:?}");
    let _ = watch.0.kill();
}

const PY_BRIDGE: &str = r#"
import json, sys, time, zenoh
c = zenoh.Config()
c.insert_json5("mode", '"router"')
c.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:" + sys.argv[1]]))
c.insert_json5("connect/endpoints", json.dumps(["tcp/127.0.0.1:" + p for p in sys.argv[2:]]))
c.insert_json5("scouting/multicast/enabled", "false")
s = zenoh.open(c)
print("up", flush=True)
while True:
    time.sleep(1)
"#;

/// Issue 25, finding 7: the fleet sees itself. A second daemon with the same machine id that
/// can see the first is refused at start, naming the key; two that were started apart and
/// then joined (a router linking them) both announce it; `watch --query` shows both latest
/// messages and says there are two. Before, both published on one key, interleaved, and
/// `watch --query` returned one of them.
#[test]
fn a_second_daemon_with_the_same_machine_id_is_refused_or_announced() {
    let tmp = tempfile::tempdir().unwrap();
    // Two replays at different speeds, so the two daemons' messages can be told apart.
    let faulty = repo().join("replay/lut-outer_race-588rpm.mcap");
    let healthy = repo().join("replay/lut-healthy-1188rpm.mcap");
    let (p1, p2, p3) = (free_port(), free_port(), free_port());
    let start = |dir: &str, file: &Path, port: u16, extra: &[String]| {
        let d = tmp.path().join(dir);
        std::fs::create_dir_all(&d).unwrap();
        let cfg = daemon_config(&d, file, &model(), "1.0", port, false);
        let mut c = Guard(
            Command::new(bin())
                .args(["run", "--config", cfg.to_str().unwrap(), "--print", "json"])
                .args(extra)
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap(),
        );
        let out = lines(c.0.stdout.take().unwrap());
        let err = lines(c.0.stderr.take().unwrap());
        (c, out, err)
    };
    let (mut a, a_out, a_err) = start("a", &faulty, p1, &[]);
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &a_err,
            "pipeline running",
            Duration::from_secs(30),
            &mut seen
        ),
        "{seen:?}"
    );

    // B sees A: refused.
    let (mut b, _, b_err) = start(
        "b",
        &healthy,
        p2,
        &[format!("--connect=tcp/127.0.0.1:{p1}")],
    );
    let status = wait_exit(&mut b.0, Duration::from_secs(20));
    let b_log: Vec<String> = b_err.try_iter().collect();
    assert_eq!(status.code(), Some(1), "{b_log:?}");
    assert!(
        b_log
            .iter()
            .any(|l| l.contains("another rigmon already publishes as rigmon/lut-rig/shaft/nde")),
        "{b_log:?}"
    );

    // C starts alone (it sees nobody), then a router links A and C: both announce it.
    let (mut c, c_out, c_err) = start("c", &healthy, p2, &[]);
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &c_err,
            "pipeline running",
            Duration::from_secs(30),
            &mut seen
        ),
        "{seen:?}"
    );
    let mut r = Command::new("python3")
        .args([
            "-c",
            PY_BRIDGE,
            &p3.to_string(),
            &p1.to_string(),
            &p2.to_string(),
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let up = lines(r.stdout.take().unwrap());
    let _r = Guard(r);
    assert_eq!(
        up.recv_timeout(Duration::from_secs(20)).expect("router"),
        "up"
    );
    for (name, log) in [("A", &a_err), ("C", &c_err)] {
        let mut seen = Vec::new();
        assert!(
            wait_line(
                log,
                "another rigmon now publishes as rigmon/lut-rig/shaft/nde too",
                Duration::from_secs(20),
                &mut seen
            ),
            "{name}: {seen:?}"
        );
    }
    // Each has published (its queryable answers only once it has a message).
    for out in [&a_out, &c_out] {
        out.recv_timeout(Duration::from_secs(20))
            .expect("a health message");
    }
    let (rc, out, err) = rigmon_within(
        &[
            "watch",
            "--query",
            "--json",
            "--mode",
            "client",
            "--connect",
            &format!("tcp/127.0.0.1:{p3}"),
            "rigmon/lut-rig/shaft/nde/health",
        ],
        Duration::from_secs(30),
    );
    assert_eq!(rc, Some(0), "{err}");
    // Both daemons' latest messages: one at 588 rpm, one at 1188 rpm.
    let rpms: std::collections::BTreeSet<i64> = out
        .lines()
        .filter_map(|l| serde_json::from_str::<HealthMessage>(l).unwrap().rpm)
        .map(|r| (r / 100.0).round() as i64)
        .collect();
    assert_eq!(rpms, [6, 12].into(), "{out}");
    assert!(
        err.contains("2 daemons answered for rigmon/lut-rig/shaft/nde/health"),
        "{err}"
    );
    for d in [&mut a, &mut c] {
        signal(&d.0, libc::SIGTERM);
        assert!(wait_exit(&mut d.0, Duration::from_secs(15)).success());
    }
}

/// Issue 25, finding 8: `rigmon watch` says within a few seconds that nothing is reachable at
/// its endpoint, keeps waiting, and prints health once a daemon comes up there; `watch
/// --query` with nothing there fails without claiming a connection. Before, `watch` waited
/// silently forever and `--query` said "connected to [...]".
#[test]
fn watch_says_nothing_is_reachable_and_keeps_waiting() {
    let tmp = tempfile::tempdir().unwrap();
    let port = free_port();
    let ep = format!("tcp/127.0.0.1:{port}");
    let (rc, _, err) = rigmon_within(
        &["watch", "--query", "--connect", &ep],
        Duration::from_secs(30),
    );
    assert_eq!(rc, Some(1), "{err}");
    assert!(err.contains(&format!("nothing reachable at {ep}")), "{err}");
    assert!(!err.contains("connected to"), "{err}");

    let watch = Command::new(bin())
        .args(["watch", "--json", "--connect", &ep])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut watch = Guard(watch);
    let got = lines(watch.0.stdout.take().unwrap());
    let werr = lines(watch.0.stderr.take().unwrap());
    let t = Instant::now();
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &werr,
            &format!("nothing reachable at {ep}"),
            Duration::from_secs(10),
            &mut seen
        ),
        "{seen:?}"
    );
    println!(
        "FIGURE watch: 'nothing reachable' after {:.1} s",
        t.elapsed().as_secs_f64()
    );
    assert!(
        watch.0.try_wait().unwrap().is_none(),
        "watch must keep waiting"
    );

    let (file, _) = replays().into_iter().next().unwrap();
    let cfg = daemon_config(tmp.path(), &file, &model(), "1.0", port, false);
    let daemon = Command::new(bin())
        .args(["run", "--config", cfg.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut daemon = Guard(daemon);
    let first: HealthMessage = serde_json::from_str(
        &got.recv_timeout(Duration::from_secs(30))
            .expect("health once the daemon is up"),
    )
    .unwrap();
    assert_eq!(first.rig, "lut-rig");
    let mut seen = Vec::new();
    assert!(
        wait_line(
            &werr,
            &format!("connected at {ep}"),
            Duration::from_secs(5),
            &mut seen
        ),
        "{seen:?}"
    );
    signal(&daemon.0, libc::SIGTERM);
    assert!(wait_exit(&mut daemon.0, Duration::from_secs(15)).success());
}
