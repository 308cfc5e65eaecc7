//! Fault injection with real parts: the built `rigmon` binary, the shipped replay and model,
//! Zenoh on loopback (ports 7650-7699), a NOTIFY_SOCKET datagram socket, Unix signals, a file
//! size limit on the child (EFBIG, the same path as a full disk), MCAP files read back by
//! rigmon and by the Python `mcap` package (tests/python/read_cut_mcap.py).
//!
//! Each test prints its figure (`FIGURE ...`) for the README's reliability table; run with
//! `cargo test --all-features --test fast faults:: -- --nocapture --test-threads=1`.

use crate::daemon_harness as harness;
use crate::wrong_shape;

use harness::*;
use rigmon::recording::mcap::{read_recording, write_recording};
use rigmon::recording::{Recording, Tacho};
use rigmon::wire::health::HealthMessage;
use std::os::unix::net::UnixDatagram;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn healthy_replay() -> PathBuf {
    repo().join("replay/lut-healthy-588rpm.mcap")
}

/// The model's fault classes (every label but `healthy`).
const FAULTS: [&str; 2] = ["outer_race", "inner_race"];

/// Start `rigmon run` on `cfg` with health as JSON on stdout and a NOTIFY_SOCKET; an optional
/// file size limit (bytes) applies to the child only.
fn spawn_daemon(cfg: &Path, notify: &Path, fsize_limit: Option<u64>) -> Guard {
    let mut cmd = Command::new(bin());
    cmd.args(["run", "--config", cfg.to_str().unwrap(), "--print", "json"])
        .env("NOTIFY_SOCKET", notify)
        .env_remove("WATCHDOG_USEC")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(limit) = fsize_limit {
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                // Without this SIGXFSZ would kill the daemon; ignored, write() gets EFBIG.
                libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
                let r = libc::rlimit {
                    rlim_cur: limit,
                    rlim_max: limit,
                };
                if libc::setrlimit(libc::RLIMIT_FSIZE, &r) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
    Guard(cmd.spawn().unwrap())
}

fn notify_socket(dir: &Path) -> (UnixDatagram, PathBuf) {
    let p = dir.join("notify.sock");
    let s = UnixDatagram::bind(&p).unwrap();
    s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
    (s, p)
}

/// Collect NOTIFY_SOCKET datagrams into `got`.
fn drain(sock: &UnixDatagram, got: &mut Vec<String>) {
    let mut buf = vec![0u8; 8192];
    while let Ok(n) = sock.recv(&mut buf) {
        got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
    }
}

fn health_lines(out: &std::sync::mpsc::Receiver<String>) -> Vec<HealthMessage> {
    out.try_iter()
        .filter_map(|l| serde_json::from_str::<HealthMessage>(&l).ok())
        .collect()
}

#[test]
fn disk_full_while_recording_keeps_monitoring_and_status_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let (sock, sock_path) = notify_socket(tmp.path());
    let cfg = daemon_config(tmp.path(), &healthy_replay(), &model(), "1.0", 7651, true);
    // 300 kB: about 1.5 s of the replay's raw data, then every write fails with EFBIG.
    let limit = 300_000u64;
    let mut child = spawn_daemon(&cfg, &sock_path, Some(limit));
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let t0 = Instant::now();
    let mut got = Vec::new();
    let mut failed_at = None;
    let mut health = Vec::new();
    while t0.elapsed() < Duration::from_secs(40) {
        drain(&sock, &mut got);
        health.extend(health_lines(&out));
        if failed_at.is_none() && got.iter().any(|m| m.contains("RECORDING FAILED")) {
            failed_at = Some((Instant::now(), health.len()));
        }
        if let Some((t, _)) = failed_at {
            if t.elapsed() > Duration::from_secs(3) {
                break;
            }
        }
    }
    let stderr: Vec<String> = err.try_iter().collect();
    let (t_fail, n_before) = failed_at
        .unwrap_or_else(|| panic!("no RECORDING FAILED in STATUS: {got:?}\nstderr: {stderr:?}"));
    let status = got
        .iter()
        .flat_map(|m| m.lines())
        .find(|l| l.contains("RECORDING FAILED"))
        .unwrap()
        .to_string();
    assert!(status.contains("disk full"), "{status}");
    assert!(
        status.contains(".mcap"),
        "STATUS must name the file: {status}"
    );
    let after = health.len() - n_before;
    assert!(
        after >= 4,
        "monitoring must continue after the recording failed: {after} health messages in 3 s"
    );
    assert!(child.0.try_wait().unwrap().is_none(), "the daemon died");
    signal(&child.0, libc::SIGTERM);
    let st = wait_exit(&mut child.0, Duration::from_secs(20));
    assert!(st.success(), "exit {st:?}");
    // What reached the disk reads back (up to the last complete chunk).
    let files = mcaps(&tmp.path().join("rec"));
    let first = files.first().expect("a recording file");
    let bytes = std::fs::metadata(first).unwrap().len();
    assert!(bytes <= limit);
    let rec = read_recording(first).unwrap();
    assert!(
        rec.duration_s() > 0.0,
        "nothing readable in {}",
        first.display()
    );
    println!(
        "FIGURE disk full (RLIMIT_FSIZE {limit} B, EFBIG): STATUS '{status}' {:.1} s after start; \
         {after} health messages in the next 3 s; first file {bytes} B, {:.2} s of signal readable; \
         {} files tried",
        t_fail.duration_since(t0).as_secs_f64(),
        rec.duration_s(),
        files.len()
    );
}

#[test]
fn kill_9_while_recording_reads_back_to_the_last_complete_chunk() {
    let tmp = tempfile::tempdir().unwrap();
    let (sock, sock_path) = notify_socket(tmp.path());
    let cfg = daemon_config(tmp.path(), &healthy_replay(), &model(), "1.0", 7652, true);
    let mut child = spawn_daemon(&cfg, &sock_path, None);
    let out = lines(child.0.stdout.take().unwrap());
    let mut got = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(30)
        && !got.iter().any(|m: &String| m.contains("READY=1"))
    {
        drain(&sock, &mut got);
    }
    let ready = Instant::now();
    std::thread::sleep(Duration::from_millis(4200));
    signal(&child.0, libc::SIGKILL);
    let written_s = ready.elapsed().as_secs_f64();
    let _ = wait_exit(&mut child.0, Duration::from_secs(10));
    let health = health_lines(&out);
    assert!(!health.is_empty());
    let file = mcaps(&tmp.path().join("rec")).remove(0);
    // rigmon's own reader, and the independent Python reader.
    let rec = read_recording(&file).unwrap();
    let py = Command::new("python3")
        .arg(repo().join("tests/python/read_cut_mcap.py"))
        .arg(&file)
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
    // The writer keeps a provisional end (a footer without summary) after every chunk.
    assert_eq!(v["footer"], true, "{v}");
    assert_eq!(v["stopped"], serde_json::Value::Null, "{v}");
    assert_eq!(v["contiguous"], true, "{v}");
    // Issue 25: the Python package's usual reader (make_reader().iter_messages()) returned
    // nothing for such a file; it reads it now, every message the stream reader sees.
    let usual = python_usual(&file);
    assert_eq!(usual["error"], serde_json::Value::Null, "{usual}");
    let stream_messages: u64 = v["messages"]
        .as_object()
        .unwrap()
        .values()
        .map(|n| n.as_u64().unwrap())
        .sum();
    assert_eq!(usual["total"], stream_messages, "{usual} vs {v}");
    let py_s = v["seconds"]["/accel/vertical"].as_f64().unwrap();
    let health_n = v["messages"]["/health"].as_u64().unwrap_or(0);
    // flush_s = 0.5: at most the last 0.5 s (+ a block and the queue) may be lost.
    assert!(
        py_s >= written_s - 1.5,
        "{py_s} s readable of ~{written_s:.1} s: {v}"
    );
    assert!(
        (rec.duration_s() - py_s).abs() < 0.11,
        "rigmon {} s vs python {py_s} s",
        rec.duration_s()
    );
    assert!(health_n > 0, "{v}");
    println!(
        "FIGURE kill -9 after {written_s:.1} s of recording (flush_s 0.5): {py_s:.1} s readable \
         (python mcap; rigmon reads {:.1} s), {} of {} bytes in {} complete chunks, {health_n} \
         health messages",
        rec.duration_s(),
        v["bytes_used"],
        v["bytes"],
        v["complete_chunks"]
    );
}

#[test]
fn sigterm_closes_the_recording_sends_stopping_and_exits_0() {
    let tmp = tempfile::tempdir().unwrap();
    let (sock, sock_path) = notify_socket(tmp.path());
    let cfg = daemon_config(tmp.path(), &healthy_replay(), &model(), "1.0", 7653, true);
    let mut child = spawn_daemon(&cfg, &sock_path, None);
    let out = lines(child.0.stdout.take().unwrap());
    let mut got = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(30)
        && !got.iter().any(|m: &String| m.contains("READY=1"))
    {
        drain(&sock, &mut got);
    }
    std::thread::sleep(Duration::from_millis(2500));
    let t_term = Instant::now();
    signal(&child.0, libc::SIGTERM);
    let st = wait_exit(&mut child.0, Duration::from_secs(20));
    let exit_s = t_term.elapsed().as_secs_f64();
    drain(&sock, &mut got);
    assert!(st.success(), "exit {st:?}");
    assert!(
        got.iter().any(|m| m.lines().any(|l| l == "STOPPING=1")),
        "{got:?}"
    );
    let files = mcaps(&tmp.path().join("rec"));
    assert_eq!(files.len(), 1, "one file per segment: {files:?}");
    let bytes = std::fs::read(&files[0]).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("clean close: summary");
    let topics: Vec<&str> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    for t in ["/accel/vertical", "/tacho/analog", "/features", "/health"] {
        assert!(topics.contains(&t), "{t} missing: {topics:?}");
    }
    let n_health = health_lines(&out).len();
    println!(
        "FIGURE SIGTERM: exit 0 in {exit_s:.2} s, STOPPING=1 sent, {} B file with summary and \
         footer, {n_health} health messages printed",
        bytes.len()
    );
}

/// The Python `mcap` package's usual reader (`make_reader(f).iter_messages()`) on a file.
fn python_usual(path: &Path) -> serde_json::Value {
    let out = Command::new("python3")
        .arg(repo().join("tests/python/read_usual_mcap.py"))
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `rigmon replay <file> --json`: the health messages.
fn replay_json(file: &Path) -> Vec<HealthMessage> {
    let out = Command::new(bin())
        .args(["replay", file.to_str().unwrap(), "--json", "--rig"])
        .arg(rig_path())
        .arg("--model")
        .arg(model())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}: {}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

fn write_faulty(dir: &Path, name: &str, f: impl Fn(&mut Recording)) -> PathBuf {
    let mut rec = read_recording(&healthy_replay()).unwrap();
    f(&mut rec);
    let p = dir.join(format!("{name}.mcap"));
    write_recording(&p, &rec).unwrap();
    p
}

fn channel(rec: &mut Recording, name: &str) -> usize {
    rec.channels.iter().position(|c| c.name == name).unwrap()
}

#[test]
fn signal_faults_raise_quality_flags_and_never_a_fault_alarm() {
    let tmp = tempfile::tempdir().unwrap();
    let fs = read_recording(&healthy_replay()).unwrap().sample_rate;
    let half = |rec: &Recording| rec.len() / 2;
    // (name, recording, flag expected, windows that must carry it at least)
    let cases: Vec<(&str, PathBuf, &str)> = vec![
        ("healthy", healthy_replay(), ""),
        (
            "tacho_lost",
            write_faulty(tmp.path(), "tacho_lost", |r| {
                let h = half(r);
                if let Some(Tacho::Analog { samples, .. }) = &mut r.tacho {
                    samples[h..].iter_mut().for_each(|x| *x = 0.0);
                } else {
                    panic!("the healthy replay has an analog tacho");
                }
            }),
            "tacho",
        ),
        (
            "nan_bursts",
            write_faulty(tmp.path(), "nan_bursts", |r| {
                let k = channel(r, "vertical");
                let n = r.len();
                // 20 ms of NaN and Inf every second.
                for s in (0..n).step_by(fs as usize) {
                    for (j, x) in r.channels[k].samples[s..(s + (0.02 * fs) as usize).min(n)]
                        .iter_mut()
                        .enumerate()
                    {
                        *x = if j % 2 == 0 { f32::NAN } else { f32::INFINITY };
                    }
                }
            }),
            "nan",
        ),
        (
            "clipping",
            write_faulty(tmp.path(), "clipping", |r| {
                let k = channel(r, "vertical");
                let peak = r.channels[k]
                    .samples
                    .iter()
                    .fold(0f32, |m, x| m.max(x.abs()));
                let c = 0.5 * peak;
                r.channels[k]
                    .samples
                    .iter_mut()
                    .for_each(|x| *x = x.clamp(-c, c));
            }),
            "clipping",
        ),
        (
            "partial_clipping_one_channel",
            write_faulty(tmp.path(), "partial_clipping", |r| {
                // Only the positive peaks of the axial channel, only in the second half.
                let k = channel(r, "axial");
                let h = half(r);
                let peak = r.channels[k].samples.iter().fold(0f32, |m, &x| m.max(x));
                let c = 0.6 * peak;
                r.channels[k].samples[h..]
                    .iter_mut()
                    .for_each(|x| *x = x.min(c));
            }),
            "clipping",
        ),
        (
            "dc_offset",
            write_faulty(tmp.path(), "dc_offset", |r| {
                let k = channel(r, "vertical");
                let s = &mut r.channels[k].samples;
                let rms = (s.iter().map(|x| x * x).sum::<f32>() / s.len() as f32).sqrt();
                s.iter_mut().for_each(|x| *x += 3.0 * rms);
            }),
            "dc_offset",
        ),
        (
            "dead_sensor",
            write_faulty(tmp.path(), "dead_sensor", |r| {
                let k = channel(r, "horizontal");
                r.channels[k].samples.iter_mut().for_each(|x| *x = 0.0);
            }),
            "flat",
        ),
    ];
    let mut figures = Vec::new();
    for (name, file, flag) in &cases {
        let msgs = replay_json(file);
        assert!(msgs.len() >= 10, "{name}: {} windows", msgs.len());
        let alarms: Vec<String> = msgs
            .iter()
            .filter(|m| {
                FAULTS.contains(&m.state.as_str()) || FAULTS.contains(&m.window_state.as_str())
            })
            .map(|m| format!("{:.1}s {}/{}", m.window.end_s, m.window_state, m.state))
            .collect();
        assert!(alarms.is_empty(), "{name}: false alarm: {alarms:?}");
        let flagged = msgs
            .iter()
            .filter(|m| !flag.is_empty() && m.quality.flags.iter().any(|f| f.contains(flag)))
            .count();
        if flag.is_empty() {
            let healthy = msgs.iter().filter(|m| m.state == "healthy").count();
            assert!(healthy > 0, "{name}: never healthy");
            figures.push(format!(
                "{name}: 0 alarms, {healthy}/{} windows healthy",
                msgs.len()
            ));
            continue;
        }
        assert!(flagged > 0, "{name}: no window flagged '{flag}'");
        if *name == "tacho_lost" {
            let last = msgs.last().unwrap();
            assert_eq!(last.state, "unknown", "{name}: {last:?}");
            assert_eq!(last.window_state, "unknown");
        }
        if *name == "dead_sensor" {
            assert!(msgs
                .iter()
                .any(|m| m.quality.flat_channels.contains(&"horizontal".to_string())));
        }
        let unknown = msgs.iter().filter(|m| m.window_state == "unknown").count();
        figures.push(format!(
            "{name}: '{flag}' on {flagged}/{} windows, {unknown} unknown, 0 alarms, final state {}",
            msgs.len(),
            msgs.last().unwrap().state
        ));
    }
    for f in figures {
        println!("FIGURE signal fault {f}");
    }
}

/// The wrong-shape model (see tests/common/wrong_shape.rs), checked to load on its own.
fn wrong_shape_model(dir: &Path) -> PathBuf {
    let p = dir.join("orders-0-25.onnx");
    wrong_shape::write_wrong_shape_model(&model(), &p);
    let clf = rigmon::model::onnx::OnnxClassifier::load(&p).unwrap();
    assert_eq!(clf.meta().n_features, wrong_shape::KEEP);
    p
}

#[test]
fn a_missing_corrupt_or_wrong_shape_model_stops_the_start_with_a_clear_error() {
    let tmp = tempfile::tempdir().unwrap();
    let corrupt = tmp.path().join("corrupt.onnx");
    std::fs::write(&corrupt, b"this is not an ONNX file").unwrap();
    let wrong = wrong_shape_model(tmp.path());
    let missing = tmp.path().join("missing.onnx");
    for (what, m, says) in [
        ("missing", &missing, "cannot read model file"),
        ("corrupt", &corrupt, "not an ONNX model"),
        ("wrong shape", &wrong, "model expects 50 bins"),
    ] {
        let cfg = daemon_config(tmp.path(), &healthy_replay(), m, "1.0", 7654, false);
        let t = Instant::now();
        let mut child = Guard(
            Command::new(bin())
                .args(["run", "--config", cfg.to_str().unwrap()])
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap(),
        );
        let err_lines = lines(child.0.stderr.take().unwrap());
        // A daemon that starts anyway is killed after 20 s and fails the test (never hangs).
        let status = wait_exit_or_kill(&mut child.0, Duration::from_secs(20));
        let s = t.elapsed().as_secs_f64();
        let err: String = rest_of(&err_lines).join("\n");
        let status = status.unwrap_or_else(|| panic!("{what}: the daemon started and ran: {err}"));
        assert!(!status.success(), "{what}: the daemon started");
        let name = m.file_name().unwrap().to_str().unwrap();
        assert!(
            err.contains(name),
            "{what}: the error must name {name}: {err}"
        );
        assert!(
            err.contains(says),
            "{what}: the error must say '{says}': {err}"
        );
        let last = err
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        println!(
            "FIGURE model {what}: exit code {:?} after {s:.2} s: {}",
            status.code(),
            last.trim()
        );
    }
}

/// `rigmon bench load` in short: 16 ch x 51.2 kHz through the whole pipeline to a Zenoh
/// subscriber; the benchmark itself checks every sample and every health message and exits 1
/// otherwise. (The 60 s figure in the README comes from a release build.)
#[test]
fn sustained_load_16_channels_at_51k2_loses_nothing() {
    let out = Command::new(bin())
        .args(["bench", "load", "--seconds", "4", "--json"])
        .current_dir(repo())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(v["ok"], true, "{v}");
    assert_eq!(v["samples_lost"], 0, "{v}");
    let windows = v["windows"].as_u64().unwrap();
    assert!(windows >= 2, "{v}");
    assert_eq!(v["windows"], v["windows_expected"], "{v}");
    assert_eq!(v["received"], v["windows"], "{v}");
    assert_eq!(v["samples_generated"], v["samples_in"], "{v}");
    println!(
        "FIGURE load (debug build, 4 s): {:.2}x real time, {} windows, 0 lost, pipeline p99 {:.1} ms",
        v["real_time_factor"].as_f64().unwrap(),
        windows,
        v["latency_ms"]["pipeline_p99"].as_f64().unwrap()
    );
}

// ------------------------------------- damaged, cut and gapped recordings (issue 25)

/// `rigmon replay <file> --json --summary-json`: exit code, health messages, the summary
/// (JSON, the last stderr line) and stderr.
fn replay_with_summary(file: &Path) -> (i32, Vec<HealthMessage>, serde_json::Value, String) {
    let out = Command::new(bin())
        .args([
            "replay",
            file.to_str().unwrap(),
            "--json",
            "--summary-json",
            "--rig",
        ])
        .arg(rig_path())
        .arg("--model")
        .arg(model())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let summary = err
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or(serde_json::Value::Null);
    let health = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    (out.status.code().unwrap_or(-1), health, summary, err)
}

/// Issue 25, finding 6: blocks a recorder dropped (1.5 s in the probe) were replayed as
/// zeros with "0 lost on the sample clock". A 0.5 s gap (shorter than a window) in the shipped
/// healthy replay: the windows over it are flagged `dropout`, the sample clock counts the 5000
/// samples as lost, and the summary names the gap.
#[test]
fn a_recorder_gap_is_a_dropout_counted_lost_never_silence() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = read_recording(&healthy_replay()).unwrap();
    let p = tmp.path().join("gap.mcap");
    let info = rigmon::recording::mcap::RecordingInfo::of(&rec);
    let mut w = rigmon::recording::mcap::RecordingWriter::create(&p, &info).unwrap();
    let Some(Tacho::Analog { samples: tacho, .. }) = &rec.tacho else {
        panic!("analog tacho")
    };
    let bl = 1000;
    for b in (0..rec.len() / bl).filter(|b| !(40..45).contains(b)) {
        let r = b * bl..(b + 1) * bl;
        let chans: Vec<&[f32]> = rec.channels.iter().map(|c| &c.samples[r.clone()]).collect();
        w.write_block(r.start as u64, &chans, Some(&tacho[r]), &[])
            .unwrap();
    }
    w.finish().unwrap();
    let (rc, health, summary, err) = replay_with_summary(&p);
    assert_eq!(rc, 0, "{err}");
    assert_eq!(summary["samples_lost"], 5000, "{summary}");
    assert_eq!(
        summary["file_losses"]["gaps"][0]["cause"], "not_recorded",
        "{summary}"
    );
    assert_eq!(
        summary["file_losses"]["gaps"][0]["samples"], 5000,
        "{summary}"
    );
    let (gap0, gap1) = (4.0, 4.5);
    let over: Vec<&HealthMessage> = health
        .iter()
        .filter(|m| m.window.start_s < gap1 && m.window.end_s > gap0)
        .collect();
    assert!(!over.is_empty(), "windows over the gap");
    for m in &health {
        let overlaps = m.window.start_s < gap1 && m.window.end_s > gap0;
        let dropout = m.quality.flags.iter().any(|f| f == "dropout");
        assert_eq!(
            overlaps, dropout,
            "window {:?}: flags {:?}",
            m.window, m.quality.flags
        );
        if overlaps {
            assert!(m.quality.dropout_samples > 0);
        }
    }
    println!(
        "FIGURE recorder gap 0.5 s: {} of {} windows flagged dropout, samples_lost {}",
        over.len(),
        health.len(),
        summary["samples_lost"]
    );
}

/// Issue 25, findings 4 and 5, as `replay` sees them: a damaged middle chunk and a file cut
/// at 50 %. Replay goes on after the damaged chunk and both summaries say what was lost.
#[test]
fn a_damaged_or_cut_replay_reports_its_losses() {
    let tmp = tempfile::tempdir().unwrap();
    let src = repo().join("replay/lut-outer_race-588rpm.mcap");
    let bytes = std::fs::read(&src).unwrap();
    // The second of the three chunks (chunk 1 ends where chunk 2's record starts).
    let mut at = 8;
    let mut chunks = Vec::new();
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if bytes[at] == 0x06 {
            chunks.push((at, len));
        }
        at += 9 + len;
    }
    let mut flipped = bytes.clone();
    flipped[chunks[1].0 + 9 + 60 + chunks[1].1 / 2] ^= 0xFF;
    let damaged = tmp.path().join("damaged.mcap");
    std::fs::write(&damaged, &flipped).unwrap();
    let cut = tmp.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();

    let (rc, health, summary, err) = replay_with_summary(&damaged);
    assert_eq!(rc, 0, "{err}");
    assert!(
        health.iter().any(|m| m.window.end_s > 7.5),
        "windows after the damaged chunk: {:?}",
        health.iter().map(|m| m.window.end_s).collect::<Vec<_>>()
    );
    assert_eq!(summary["samples_lost"], 33_000, "{summary}");
    assert_eq!(summary["file_losses"]["seconds_lost"], 3.3, "{summary}");
    assert_eq!(
        summary["file_losses"]["damaged"][0]["at_byte"], chunks[1].0,
        "{summary}"
    );
    assert!(
        err.contains("damaged stretch at byte") && err.contains("3.300 s"),
        "{err}"
    );

    let (rc, _, summary, err) = replay_with_summary(&cut);
    assert_eq!(rc, 0, "{err}");
    let t = &summary["file_losses"]["truncated"];
    assert_eq!(t["readable_s"], 3.2, "{summary}");
    assert_eq!(t["lost_s_at_least"], 3.2, "{summary}");
    assert!(err.contains("cut short at byte"), "{err}");
}

/// Issue 25, finding 12: a 1-sample WAV replayed with rc 0 and "0 windows". A recording too
/// short for one window is refused, naming the length one window needs: at once when its
/// length is known (WAV), at its end otherwise (an MCAP file that never had a summary).
#[test]
fn a_recording_too_short_for_one_window_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let wav = tmp.path().join("one.wav");
    let spec = hound::WavSpec {
        channels: 4,
        sample_rate: 10_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&wav, spec).unwrap();
    for x in [1i16, 2, 3, 4] {
        w.write_sample(x).unwrap();
    }
    w.finalize().unwrap();
    // 0.5 s of the healthy replay, written by a writer that was then killed.
    let rec = read_recording(&healthy_replay()).unwrap();
    let short = tmp.path().join("short.mcap");
    let mut mw = rigmon::recording::mcap::RecordingWriter::create(
        &short,
        &rigmon::recording::mcap::RecordingInfo::of(&rec),
    )
    .unwrap();
    let Some(Tacho::Analog { samples: tacho, .. }) = &rec.tacho else {
        panic!("analog tacho")
    };
    let chans: Vec<&[f32]> = rec.channels.iter().map(|c| &c.samples[..5000]).collect();
    mw.write_block(0, &chans, Some(&tacho[..5000]), &[])
        .unwrap();
    mw.flush().unwrap();
    std::mem::forget(mw);
    for (file, n) in [(&wav, "1 sample(s)"), (&short, "5000 sample(s)")] {
        let t0 = Instant::now();
        let (rc, health, _, err) = replay_with_summary(file);
        assert_ne!(rc, 0, "{}: {err}", file.display());
        assert!(health.is_empty());
        for want in [
            n,
            "too short for one window",
            "window_s = 1 s",
            "needs 10000 samples",
        ] {
            assert!(err.contains(want), "{want:?} not in {err}");
        }
        println!(
            "FIGURE {}: refused in {:.2} s: {}",
            file.display(),
            t0.elapsed().as_secs_f64(),
            err.lines().last().unwrap_or("")
        );
    }
}

/// Issue 25, finding 12: segments overshot `max_file_mb` by up to 50 % at full speed (the
/// size was looked at every 500 ms). The recorder keeps an upper bound of each segment's
/// finished size and closes it before a write would pass the limit.
#[test]
fn segments_never_pass_max_file_mb() {
    use rigmon::recorder::{RecordConfig, RecordEvent, Recorder};
    use rigmon::recording::mcap::{ChannelInfo, RecordingInfo, TachoInfo};
    use rigmon::recording::SampleBlock;
    use std::sync::Arc;
    let tmp = tempfile::tempdir().unwrap();
    let max_bytes = 300_000u64;
    let cfg = RecordConfig {
        enabled: true,
        dir: tmp.path().join("rec"),
        max_file_mb: max_bytes as f64 / 1e6,
        chunk_kb: 64,
        ..RecordConfig::default()
    };
    let info = RecordingInfo {
        sample_rate: 10_000.0,
        start_time_ns: 1_795_314_780_000_000_000,
        channels: ["axial", "vertical", "horizontal"]
            .iter()
            .map(|n| ChannelInfo {
                name: n.to_string(),
                axis: n.to_string(),
                unit: "m/s^2".into(),
            })
            .collect(),
        tacho: TachoInfo::Analog { unit: "V".into() },
        rpm: None,
        provenance: Default::default(),
        metadata: Default::default(),
    };
    let mut r = Recorder::new(cfg, info, "rig").unwrap();
    // Noise compresses poorly: the worst case for the size bound. As fast as it goes.
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut noise = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let blocks = 400u64;
    for k in 0..blocks {
        let b = SampleBlock {
            first_sample: k * 1000,
            sample_rate: 10_000.0,
            channels: (0..3)
                .map(|_| (0..1000).map(|_| noise()).collect())
                .collect(),
            tacho_analog: Some((0..1000).map(|i| if i < 100 { 5.0 } else { 0.0 }).collect()),
            tacho_edges: Vec::new(),
        };
        r.handle(RecordEvent::Block(Arc::new(b)));
        r.handle(RecordEvent::Health {
            t_ns: k,
            json: br#"{"state":"healthy"}"#.to_vec(),
        });
    }
    let st = r.finish();
    assert_eq!(st.write_errors, 0, "{st:?}");
    let files = mcaps(&tmp.path().join("rec"));
    let sizes: Vec<u64> = files
        .iter()
        .map(|f| std::fs::metadata(f).unwrap().len())
        .collect();
    println!(
        "FIGURE max_file_mb {}: {} segments, sizes {sizes:?}",
        max_bytes as f64 / 1e6,
        files.len()
    );
    assert!(files.len() >= 10, "{sizes:?}");
    for (f, &n) in files.iter().zip(&sizes) {
        assert!(n <= max_bytes, "{}: {n} bytes > {max_bytes}", f.display());
    }
    // Not wastefully small either: every segment but the last one written is at least 80 %
    // full (names sort by time stamp, then `-2`, `-10`...: not in writing order).
    let small = sizes.iter().filter(|&&n| n < max_bytes * 8 / 10).count();
    assert!(small <= 1, "{sizes:?}");
    let total: usize = files.iter().map(|f| read_recording(f).unwrap().len()).sum();
    assert_eq!(total as u64, blocks * 1000, "nothing lost between segments");
}

/// Issue 25, finding 12: with the disk full, every 5 s retry left another empty file (~720 an
/// hour). With `RLIMIT_FSIZE` below the size of one chunk every write fails; the daemon keeps
/// monitoring and retrying, and removes each segment that holds no complete chunk.
#[test]
fn disk_full_leaves_no_file_without_data() {
    let tmp = tempfile::tempdir().unwrap();
    let (sock, sock_path) = notify_socket(tmp.path());
    let cfg = daemon_config(tmp.path(), &healthy_replay(), &model(), "1.0", 7654, true);
    let mut child = spawn_daemon(&cfg, &sock_path, Some(4096));
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let mut got = Vec::new();
    let t0 = Instant::now();
    let mut health = Vec::new();
    // Three attempts: at the first block, and after two 5 s retries.
    while t0.elapsed() < Duration::from_secs(12) {
        drain(&sock, &mut got);
        health.extend(health_lines(&out));
    }
    assert!(child.0.try_wait().unwrap().is_none(), "the daemon died");
    signal(&child.0, libc::SIGTERM);
    let st = wait_exit(&mut child.0, Duration::from_secs(20));
    assert!(st.success(), "exit {st:?}");
    let stderr: Vec<String> = rest_of(&err);
    let removed = stderr
        .iter()
        .filter(|l| l.contains("holds no complete chunk"))
        .count();
    let files = mcaps(&tmp.path().join("rec"));
    let leftovers: Vec<String> = files
        .iter()
        .filter(|f| read_recording(f).map_or(true, |r| r.is_empty()))
        .map(|f| {
            format!(
                "{} ({} B)",
                f.display(),
                std::fs::metadata(f).unwrap().len()
            )
        })
        .collect();
    println!(
        "FIGURE disk full (RLIMIT_FSIZE 4096 B) for 12 s: {} health messages, {removed} empty segments removed, {} files left",
        health.len(),
        files.len()
    );
    assert!(
        got.iter().any(|m| m.contains("RECORDING FAILED")),
        "{got:?}"
    );
    assert!(
        health.len() >= 15,
        "monitoring continued: {} health messages",
        health.len()
    );
    assert!(
        leftovers.is_empty(),
        "files without data left behind: {leftovers:?}"
    );
    assert!(removed >= 2, "retries happened and cleaned up: {stderr:?}");
}

/// Issue 25: "recording problems never stop monitoring" — a recording folder that cannot be
/// created made `run` exit 1 before monitoring started. It is now a recording failure like a
/// full disk: counted, in the status, retried, and monitoring runs.
#[test]
fn a_recording_folder_that_cannot_be_created_never_stops_monitoring() {
    let tmp = tempfile::tempdir().unwrap();
    let (sock, sock_path) = notify_socket(tmp.path());
    let cfg = daemon_config(tmp.path(), &healthy_replay(), &model(), "1.0", 7655, true);
    // `rec` is a file: `rec/` cannot be created.
    std::fs::write(tmp.path().join("rec"), b"a file, not a folder").unwrap();
    let mut child = spawn_daemon(&cfg, &sock_path, None);
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let mut got = Vec::new();
    let mut health = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(6) {
        drain(&sock, &mut got);
        health.extend(health_lines(&out));
        if child.0.try_wait().unwrap().is_some() {
            break;
        }
    }
    assert!(
        child.0.try_wait().unwrap().is_none(),
        "the daemon stopped: {:?}",
        rest_of(&err)
    );
    signal(&child.0, libc::SIGTERM);
    let st = wait_exit(&mut child.0, Duration::from_secs(20));
    assert!(st.success(), "exit {st:?}");
    let failed = got
        .iter()
        .flat_map(|m| m.lines())
        .find(|l| l.contains("RECORDING FAILED"))
        .unwrap_or_else(|| panic!("no RECORDING FAILED in {got:?}"))
        .to_string();
    assert!(failed.contains("cannot create the folder"), "{failed}");
    assert!(health.len() >= 6, "{} health messages", health.len());
}
