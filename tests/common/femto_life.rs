//! A synthetic run to failure built from the physics of a bearing on the FEMTO rig
//! (`config/femto.toml`: 13 balls of 3.5 mm on a 25.6 mm pitch, 1800 rpm, 0.1 s captures at
//! 25.6 kHz every 10 s): shaft lines and broadband noise, a run-in (the first captures louder,
//! settling), a slow drift of the noise level, one capture twenty times as loud, and from
//! capture [`ONSET`] on an outer-race defect whose impacts, at the ball-pass frequency, ring a
//! 4 kHz structural resonance and grow. Written as a FEMTO folder (headerless CSVs with the
//! capture clock). Used by the fast tier's `early_warning` and the heavy tier's `adapt`.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::Path;

pub const FS: f64 = 25_600.0;
pub const N: usize = 2560;
/// Captures in the life, in the baseline (the first fifth), the defect's first one and the
/// loud one.
pub const CAPTURES: usize = 200;
pub const BASELINE: usize = 40;
pub const ONSET: usize = 100;
pub const LOUD: usize = 70;

/// A deterministic Gaussian-like noise sample (sum of 4 uniform hashes, unit variance).
fn noise(i: usize, k: usize) -> f64 {
    let mut s = 0.0;
    for j in 0..4usize {
        let h = (i.wrapping_mul(2_654_435_761) ^ k.wrapping_mul(40_503) ^ j.wrapping_mul(97_531))
            .wrapping_mul(0x9E37_79B9)
            % 1_000_003;
        s += h as f64 / 1_000_003.0 - 0.5;
    }
    s * (12.0f64 / 4.0).sqrt()
}

/// Capture `k`'s horizontal signal, g (with or without the defect).
fn capture(k: usize, with_defect: bool) -> Vec<f64> {
    let tau = 2.0 * std::f64::consts::PI;
    let shaft = 30.0; // 1800 rpm
    let bpfo = shaft * 6.5 * (1.0 - 3.5 / 25.6); // 168 Hz
    let run_in = 1.0 + 0.6 * (-(k as f64) / 8.0).exp();
    let drift = 1.0 + 0.0004 * k as f64;
    let loud = if k == LOUD { 20.0 } else { 1.0 };
    let defect = if with_defect && k >= ONSET {
        0.15 * (k - ONSET + 1) as f64
    } else {
        0.0
    };
    (0..N)
        .map(|i| {
            let t = (k as f64 * 10.0) + i as f64 / FS;
            let lines = 0.2 * (tau * shaft * t).sin() + 0.05 * (tau * 2.0 * shaft * t).sin();
            // the last impact before t rings the 4 kHz resonance (damping 3 %)
            let since = t % (1.0 / bpfo);
            let ring = (-0.03 * tau * 4000.0 * since).exp() * (tau * 4000.0 * since).sin();
            loud * (run_in * drift * (lines + 0.3 * noise(i, k)) + defect * ring)
        })
        .collect()
}

/// The life as a FEMTO folder: headerless CSVs with the capture clock.
pub fn life(dir: &Path, with_defect: bool) {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..CAPTURES {
        let secs = 8 * 3600 + 10 * k;
        let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
        let mut text = String::with_capacity(N * 32);
        for (i, x) in capture(k, with_defect).into_iter().enumerate() {
            let us = i as f64 * 39.0625;
            text.push_str(&format!("{h},{m},{s},{us:e},{x:.4},{:.4}\n", 0.5 * x));
        }
        std::fs::write(dir.join(format!("acc_{:05}.csv", k + 1)), text).unwrap();
    }
}

/// Capture index of a time on the capture clock (s since the first capture).
pub fn capture_at(t: f64) -> usize {
    (t / 10.0).floor() as usize
}

/// A manifest (in `tmp`) naming the life's folder `d` as healthy over its first [`BASELINE`]
/// captures, at 1800 rpm.
pub fn baseline_manifest(tmp: &Path, d: &str) -> std::path::PathBuf {
    let manifest = tmp.join("healthy.csv");
    let end = BASELINE as f64 * 10.0;
    std::fs::write(
        &manifest,
        format!("path,label,rpm,start_s,end_s\n{d},healthy,1800,0,{end}\n"),
    )
    .unwrap();
    manifest
}
