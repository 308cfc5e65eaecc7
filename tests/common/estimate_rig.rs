//! Issue 23's machine with only an accelerometer, for the estimate-mode tests of both tiers:
//! the LUT rig without its tacho channel, `[speed] estimate` over 500-1500 rpm, and the shaft
//! lines a real rotor shows (residual unbalance and misalignment, 1x-5x falling as 1/k); the
//! rotor model's own unbalance alone is invisible below ~1000 rpm. Recordings are simulated
//! to WAV, which carries no revolution times: the speed can only come from the vibration.

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The rig file text; `shaft_lines` false leaves the rotor without them.
pub fn rig_text(shaft_lines: bool) -> String {
    let s = std::fs::read_to_string(repo().join("config/lut-rig.toml")).unwrap();
    let tacho = "[[channels]]\nname = \"tacho\"\nkind = \"tacho\"\nunit = \"V\"\n\n";
    assert!(
        s.contains(tacho),
        "config/lut-rig.toml changed: no tacho channel block"
    );
    let a = s.find("[speed]\n").unwrap();
    let b = a + s[a..].find("\n\n").unwrap() + 2;
    let mut s = format!(
        "{}[speed]\nsource = \"estimate\"\nmin_rpm = 500.0\nmax_rpm = 1500.0\n\n{}",
        &s[..a],
        &s[b..]
    )
    .replace(tacho, "");
    if shaft_lines {
        s.push_str(
            "\n[simulation.shaft_lines]\nref_rpm = 1000.0\nexponent = 1.0\n\
             amplitudes_m_s2 = [0.2, 0.1, 0.067, 0.05, 0.04]\nphase_deg = 0.0\n",
        );
    }
    s
}

/// `rigmon <args>` from the repository root; (success, stdout, stderr).
pub fn rigmon_in(dir: &Path, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `rigmon <args>` that must succeed; its stdout.
pub fn ok(dir: &Path, args: &[&str]) -> String {
    let (good, out, err) = rigmon_in(dir, args);
    assert!(good, "rigmon {args:?} failed:\n{out}{err}");
    out
}

/// Write `rig.toml` (with shaft lines) and simulate `<fault>.wav` at `rpm` for `seconds` in
/// `dir`; returns the rig file.
pub fn machine(dir: &Path, faults: &[&str], rpm: f64, seconds: f64) -> PathBuf {
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, rig_text(true)).unwrap();
    for f in faults {
        ok(
            dir,
            &[
                "simulate",
                "--rig",
                "rig.toml",
                "--fault",
                f,
                "--rpm",
                &rpm.to_string(),
                "--seconds",
                &seconds.to_string(),
                "--seed",
                "3",
                "-o",
                &format!("{f}.wav"),
            ],
        );
    }
    rig
}
