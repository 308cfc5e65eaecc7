//! Multi-channel WAV (float32, int8/16/24/32 PCM) via `hound`.
//!
//! WAV channels map onto the rig's `channels` in order (acceleration and tacho alike); the
//! counts must match. Integer samples are read as full-scale fractions (-1 .. 1), float samples
//! as they are; both are then multiplied by the channel's `sensitivity` to give `unit`. A tacho
//! channel becomes [`Tacho::Analog`].

use super::{check_classifier_channel, resolve_sample_rate, ImportOptions};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Read a WAV file into a [`Recording`].
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let p = path.display();
    let mut reader = hound::WavReader::open(path)
        .map_err(|e| anyhow::anyhow!("{p}: not a readable WAV file: {e}"))?;
    let spec = reader.spec();
    let n_ch = spec.channels as usize;
    if n_ch != rig.channels.len() {
        bail!(
            "{p}: the WAV has {n_ch} channel(s) but the rig file lists {} ({:?}); the rig's `channels` give the WAV channel order",
            rig.channels.len(),
            rig.channel_names()
        );
    }
    let frames = reader.duration() as usize;
    // The header's length is bounded by the file size (hound checks the data chunk).
    let file_len = std::fs::metadata(path)?.len() as usize;
    let bytes_per_sample = (spec.bits_per_sample as usize).div_ceil(8).max(1);
    if frames.saturating_mul(n_ch).saturating_mul(bytes_per_sample) > file_len {
        bail!("{p}: truncated: the WAV header announces {frames} frames but the file holds only {file_len} bytes");
    }
    let mut cols: Vec<Vec<f32>> = (0..n_ch).map(|_| Vec::with_capacity(frames)).collect();
    let mut k = 0usize;
    let mut push = |x: f32, k: &mut usize| {
        cols[*k % n_ch].push(x);
        *k += 1;
    };
    let sample_err = |k: usize, e: hound::Error| {
        anyhow::anyhow!(
            "{p}: truncated or damaged WAV at frame {} (channel {}): {e}",
            k / n_ch,
            k % n_ch
        )
    };
    match spec.sample_format {
        hound::SampleFormat::Float => {
            if spec.bits_per_sample != 32 {
                bail!(
                    "{p}: {}-bit float WAV is not supported (use 32-bit float)",
                    spec.bits_per_sample
                );
            }
            for s in reader.samples::<f32>() {
                let x = s.map_err(|e| sample_err(k, e))?;
                push(x, &mut k);
            }
        }
        hound::SampleFormat::Int => {
            let bits = spec.bits_per_sample;
            if !(1..=32).contains(&bits) {
                bail!("{p}: {bits}-bit integer WAV is not supported");
            }
            let full_scale = (1u64 << (bits - 1)) as f64;
            for s in reader.samples::<i32>() {
                let x = s.map_err(|e| sample_err(k, e))?;
                push((x as f64 / full_scale) as f32, &mut k);
            }
        }
    }
    if k % n_ch != 0 {
        bail!("{p}: truncated: the data ends in the middle of a frame ({k} samples for {n_ch} channels)");
    }
    if k == 0 {
        bail!("{p}: the WAV holds no samples");
    }
    let (sample_rate, note) = resolve_sample_rate(
        path,
        Some((spec.sample_rate as f64, "WAV header".to_string())),
        &rig.acquisition,
        opts,
    )?;
    let mut channels = Vec::new();
    let mut tacho = None;
    for (cfg, mut col) in rig.channels.iter().zip(cols) {
        if cfg.sensitivity != 1.0 {
            let s = cfg.sensitivity as f32;
            col.iter_mut().for_each(|x| *x *= s);
        }
        match cfg.kind {
            ChannelKind::Acceleration => channels.push(Channel {
                name: cfg.name.clone(),
                axis: cfg.axis.clone(),
                unit: cfg.unit.clone(),
                samples: col,
            }),
            ChannelKind::Tacho => {
                if tacho.is_some() {
                    bail!("{p}: the rig file lists more than one tacho channel; rigmon uses one");
                }
                tacho = Some(Tacho::Analog {
                    samples: col,
                    unit: cfg.unit.clone(),
                });
            }
        }
    }
    let format = match spec.sample_format {
        hound::SampleFormat::Float => "float32".to_string(),
        hound::SampleFormat::Int => format!("int{}", spec.bits_per_sample),
    };
    let rec = Recording {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: opts.rpm,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: p.to_string(),
            format: "wav".into(),
            notes: vec![format!("{n_ch}-channel {format} WAV"), note],
        },
        metadata: BTreeMap::new(),
    };
    check_classifier_channel(path, rig, &rec, "WAV channel")?;
    Ok(rec)
}
