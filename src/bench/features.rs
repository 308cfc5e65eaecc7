//! `rigmon bench features`: envelope-order-spectrum feature throughput in channel-seconds per
//! wall-second (1 s windows at 10 kHz, order tracking from an analog tacho, one thread), against
//! a baseline in the same run that builds a fresh pipeline (new FFT plans, new buffers) for
//! every window — the same arithmetic, so the outputs are compared too.

use super::{machine_line, thread_cpu_s, BenchOptions};
use crate::config::RigConfig;
use crate::dsp::synthetic::Synthetic;
use crate::dsp::{FeaturePipeline, SpeedTrack};
use crate::usage::load_averages;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn default_rig() -> PathBuf {
    let local = PathBuf::from("config/lut-rig.toml");
    if local.exists() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml")
    }
}

struct Pass {
    channel_seconds: f64,
    wall_s: f64,
    cpu_s: f64,
    checksum: f64,
}

pub fn run(opts: &BenchOptions) -> Result<()> {
    let rig_path = opts.rig.clone().unwrap_or_else(default_rig);
    let mut rig = RigConfig::load(&rig_path)?;
    let fs = 10_000.0;
    rig.features.window_s = 1.0;
    rig.features.hop_s = 1.0;
    let (tacho_thr, tacho_hyst) = (2.5, 0.5);
    // 20 s of three channels, speed ramp 8 -> 12 Hz
    let syn = Synthetic {
        seconds: 20.0,
        ..Synthetic::default()
    };
    let run = syn.generate();
    let channel_names: Vec<String> = rig
        .acceleration_channels()
        .map(|c| c.name.clone())
        .collect();
    let chans: Vec<Vec<f32>> = (0..channel_names.len())
        .map(|k| {
            run.vibration
                .iter()
                .enumerate()
                .map(|(i, v)| v * (1.0 + 0.1 * k as f32) + 0.01 * ((i * (k + 3)) % 17) as f32)
                .collect()
        })
        .collect();
    let n = (rig.features.window_s * fs) as usize;
    let windows = run.vibration.len() / n;

    let one_pass = |fresh_per_window: bool, pipe: &mut FeaturePipeline| -> Result<Pass> {
        let t0 = Instant::now();
        let c0 = thread_cpu_s();
        let speed = SpeedTrack::from_analog(&run.tacho, fs, tacho_thr, tacho_hyst, 1)?;
        let mut checksum = 0.0;
        let mut views: Vec<(&str, &[f32])> = Vec::with_capacity(chans.len());
        for w in 0..windows {
            views.clear();
            views.extend(
                channel_names
                    .iter()
                    .zip(&chans)
                    .map(|(name, c)| (name.as_str(), &c[w * n..(w + 1) * n])),
            );
            let t = (w * n) as f64 / fs;
            let fw = if fresh_per_window {
                FeaturePipeline::new(&rig, fs)?.process_window(t, &views, &speed)?
            } else {
                pipe.process_window(t, &views, &speed)?
            };
            checksum += fw
                .features
                .values()
                .flatten()
                .map(|&v| v as f64)
                .sum::<f64>();
        }
        Ok(Pass {
            channel_seconds: (windows * chans.len()) as f64 * rig.features.window_s,
            wall_s: t0.elapsed().as_secs_f64(),
            cpu_s: thread_cpu_s() - c0,
            checksum,
        })
    };
    // (x real time per channel by wall clock, by thread CPU time, checksum)
    let measure = |fresh: bool, budget_s: f64| -> Result<(f64, f64, f64)> {
        let mut pipe = FeaturePipeline::new(&rig, fs)?;
        one_pass(fresh, &mut pipe)?; // warm-up
        let (mut cs, mut wall, mut cpu, mut check) = (0.0, 0.0, 0.0, 0.0);
        while wall < budget_s {
            let p = one_pass(fresh, &mut pipe)?;
            cs += p.channel_seconds;
            wall += p.wall_s;
            cpu += p.cpu_s;
            check = p.checksum;
        }
        Ok((cs / wall, cs / cpu, check))
    };
    let budget = opts.seconds.max(0.5);
    let (fast, fast_cpu, check_fast) =
        measure(false, budget * 0.75).context("optimised pipeline")?;
    let (naive, naive_cpu, check_naive) =
        measure(true, budget * 0.25).context("baseline pipeline")?;
    if ((check_fast - check_naive) / check_naive).abs() > 1e-5 {
        bail!("the optimised and baseline pipelines disagree (checksums {check_fast} vs {check_naive})");
    }
    let machine = format!("{}; load average {}", machine_line(), load_averages());
    if opts.json {
        println!(
            "{}",
            serde_json::json!({
                "benchmark": "features",
                "x_real_time_per_channel": fast,
                "baseline_x_real_time_per_channel": naive,
                "ratio_vs_baseline": fast / naive,
                "x_real_time_per_channel_cpu": fast_cpu,
                "baseline_x_real_time_per_channel_cpu": naive_cpu,
                "goal_x_real_time": 4000.0,
                "window_s": rig.features.window_s,
                "sample_rate_hz": fs,
                "channels": chans.len(),
                "machine": machine,
            })
        );
    } else {
        println!("rigmon bench features: 1 s windows at 10 kHz, {} channels, tacho order tracking (8 -> 12 Hz ramp), 1 thread", chans.len());
        println!("                                        wall clock   thread CPU time");
        println!("  pipeline (plans + buffers reused):   {fast:>9.0}x  {fast_cpu:>9.0}x real time per channel");
        println!("  baseline (re-plan + allocate/window): {naive:>8.0}x  {naive_cpu:>9.0}x real time per channel");
        println!("  ratio vs baseline: {:.2}x (wall), {:.2}x (CPU)   goal: >= 4000x real time per channel", fast / naive, fast_cpu / naive_cpu);
        println!("  (on a busy machine the wall-clock figure understates the pipeline; the CPU-time one does not)");
        println!("  machine: {machine}");
    }
    Ok(())
}
