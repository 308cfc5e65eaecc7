//! The lean service binary `rigmon-daemon` (issue 36): the binary `systemd/rigmon.service`
//! starts links the core and the runtime only (no PostgreSQL client, no plotting, no
//! simulator, trainer or calibration), and it runs the daemon exactly as `rigmon run` does:
//! the same arguments, the same health for the same recording.

use crate::daemon_harness::{bin, daemon_config, lines, model, rest_of, wait_exit, Guard};
use rigmon::wire::health::HealthMessage;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

/// The service binary (a second binary of the `rigmon` package).
fn service_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rigmon-daemon"))
}

/// How many times each needle occurs in the haystack (byte strings).
fn count(hay: &[u8], needle: &str) -> usize {
    hay.windows(needle.len())
        .filter(|w| *w == needle.as_bytes())
        .count()
}

#[test]
fn the_service_binary_links_no_postgres_client_plotting_or_lab_code() {
    let lean = std::fs::read(service_bin()).unwrap();
    let full = std::fs::read(bin()).unwrap();
    // Crate names appear in every symbol and panic location a linked crate brings along.
    for banned in [
        "tokio_postgres",
        "postgres_protocol",
        "plotters",
        "rigmon_lab",
        "rigmon_historian",
    ] {
        assert!(
            count(&full, banned) > 0,
            "the full `rigmon` binary shows no `{banned}`: this check would see nothing"
        );
        assert_eq!(
            count(&lean, banned),
            0,
            "rigmon-daemon links `{banned}`: the service binary must stay on rigmon-core and rigmon-runtime"
        );
    }
    for needed in ["rigmon_runtime", "rigmon_core", "tract"] {
        assert!(
            count(&lean, needed) > 0,
            "rigmon-daemon shows no `{needed}`"
        );
    }
    assert!(
        lean.len() * 10 < full.len() * 9,
        "rigmon-daemon ({} bytes) is not smaller than rigmon ({} bytes)",
        lean.len(),
        full.len()
    );
}

/// Every health message of one pass over a shipped replay, printed as JSON by `exe args`.
fn health_of(exe: &std::path::Path, args: &[&str]) -> Vec<HealthMessage> {
    let child = Command::new(exe)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut child = Guard(child);
    let out = lines(child.0.stdout.take().unwrap());
    let err = lines(child.0.stderr.take().unwrap());
    let status = wait_exit(&mut child.0, Duration::from_secs(120));
    assert!(
        status.success(),
        "{} {args:?} failed: {}",
        exe.display(),
        rest_of(&err).join("\n")
    );
    rest_of(&out)
        .iter()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect()
}

#[test]
fn the_service_binary_runs_the_daemon_as_rigmon_run_does() {
    let tmp = tempfile::tempdir().unwrap();
    let file = crate::daemon_harness::repo().join("replay/lut-outer_race-588rpm.mcap");
    let port = crate::daemon::free_port();
    let cfg = daemon_config(tmp.path(), &file, &model(), "20.0", port, false);
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(&cfg, text.replace("loop = true", "loop = false")).unwrap();
    let cfg = cfg.to_str().unwrap();
    let lean = health_of(&service_bin(), &["--config", cfg, "--print", "json"]);
    let full = health_of(
        std::path::Path::new(bin()),
        &["run", "--config", cfg, "--print", "json"],
    );
    assert!(
        lean.len() > 10,
        "rigmon-daemon printed {} windows",
        lean.len()
    );
    // Window times are wall-clock (a live replay): compare them from each run's first window.
    let view = |all: &[HealthMessage]| -> Vec<(u64, u64, String, String)> {
        let t0 = all[0].window.end_ns;
        all.iter()
            .map(|m| {
                (
                    m.seq,
                    m.window.end_ns - t0,
                    m.window_state.clone(),
                    m.state.clone(),
                )
            })
            .collect()
    };
    assert_eq!(
        view(&lean),
        view(&full),
        "rigmon-daemon and `rigmon run` must give the same health for the same recording"
    );
    let help = Command::new(service_bin()).arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--config",
        "--replay",
        "--check",
        "--print",
        "--allow-foreign-model",
    ] {
        assert!(
            help.contains(flag),
            "rigmon-daemon --help lacks {flag}:\n{help}"
        );
    }
}
