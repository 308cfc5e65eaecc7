//! Writing a whole in-memory [`Recording`] to a rigmon MCAP file, cut into blocks of about
//! 0.1 s with the tacho edges each block holds.

use super::layout::RecordingInfo;
use super::stream_writer::RecordingWriter;
use crate::recording::{Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::path::Path;

/// Samples per message when [`write_recording`] splits a recording into blocks: about 0.1 s.
pub fn default_block_len(sample_rate: f64) -> usize {
    ((sample_rate * 0.1).round() as usize).clamp(64, 1 << 16)
}

/// Write a whole recording (blocks of ~0.1 s).
pub fn write_recording(path: &Path, rec: &Recording) -> Result<()> {
    let mut w = RecordingWriter::create(path, &RecordingInfo::of(rec))?;
    let n = rec.len();
    if let Some(c) = rec.channels.iter().find(|c| c.samples.len() != n) {
        bail!(
            "{}: channel {:?} has {} samples but {:?} has {n}",
            path.display(),
            c.name,
            c.samples.len(),
            rec.channels[0].name
        );
    }
    let analog = match &rec.tacho {
        Some(Tacho::Analog { samples, .. }) => {
            if samples.len() != n {
                bail!(
                    "{}: the analog tacho has {} samples but the channels have {n}",
                    path.display(),
                    samples.len()
                );
            }
            Some(samples.as_slice())
        }
        _ => None,
    };
    let edges: &[f64] = match &rec.tacho {
        Some(Tacho::Edges { times_s }) => times_s,
        _ => &[],
    };
    let block = default_block_len(rec.sample_rate);
    let mut e = 0;
    let mut start = 0;
    let mut slices: Vec<&[f32]> = Vec::with_capacity(rec.channels.len());
    while start < n {
        let end = (start + block).min(n);
        slices.clear();
        slices.extend(rec.channels.iter().map(|c| &c.samples[start..end]));
        // Edges up to the end of this block (the last block takes all that remain).
        let t_end = end as f64 / rec.sample_rate;
        let e0 = e;
        while e < edges.len() && (edges[e] < t_end || end == n) {
            e += 1;
        }
        w.write_block(
            start as u64,
            &slices,
            analog.map(|a| &a[start..end]),
            &edges[e0..e],
        )
        .with_context(|| format!("{}: writing block at sample {start}", path.display()))?;
        start = end;
    }
    if n == 0 && !edges.is_empty() {
        w.write_block(0, &vec![&[][..]; rec.channels.len()], analog, edges)?;
    }
    w.finish()
        .with_context(|| format!("{}: finishing MCAP", path.display()))?;
    Ok(())
}
