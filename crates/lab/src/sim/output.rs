//! Writing simulated recordings: MCAP (the rigmon layout, labels in MCAP metadata) or WAV in
//! the rig file's channel order (float32; acceleration in the channel's unit, the tacho in
//! volts) so any audio or analysis tool can read it.

use crate::config::{ChannelConfig, ChannelKind, RigConfig};
use crate::recording::{Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::path::Path;

/// Write by extension: `.mcap` or `.wav`.
pub fn write(path: &Path, rec: &Recording, rig: &RigConfig) -> Result<()> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("mcap") => crate::recording::mcap::write_recording(path, rec)
            .with_context(|| format!("writing {}", path.display())),
        Some("wav") => write_wav(path, rec, &rig.channels),
        _ => bail!("output {}: use a .mcap or .wav file name", path.display()),
    }
}

/// WAV (IEEE float32) with one channel per rig channel (`channels`, the rig file's
/// `[[channels]]`), in the rig file's order.
pub fn write_wav(path: &Path, rec: &Recording, channels: &[ChannelConfig]) -> Result<()> {
    let mut cols: Vec<&[f32]> = Vec::new();
    for c in channels {
        match c.kind {
            ChannelKind::Acceleration => match rec.channels.iter().find(|x| x.name == c.name) {
                Some(ch) => cols.push(&ch.samples),
                None => bail!("WAV output: the recording has no channel {:?} (the rig lists it); map it in [simulation.channel_map] or write MCAP", c.name),
            },
            ChannelKind::Tacho => match &rec.tacho {
                Some(Tacho::Analog { samples, .. }) => cols.push(samples),
                _ => bail!("WAV output: the rig has a tacho channel {:?} but the recording has no analog tacho", c.name),
            },
        }
    }
    let fs = rec.sample_rate.round();
    if (fs - rec.sample_rate).abs() > 1e-9 || fs < 1.0 || fs > u32::MAX as f64 {
        bail!(
            "WAV needs a whole-number sample rate; this recording has {} Hz",
            rec.sample_rate
        );
    }
    let spec = hound::WavSpec {
        channels: cols.len() as u16,
        sample_rate: fs as u32,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec)
        .with_context(|| format!("cannot create {}", path.display()))?;
    let n = rec.len();
    for i in 0..n {
        for c in &cols {
            w.write_sample(c[i])?;
        }
    }
    w.finalize()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
