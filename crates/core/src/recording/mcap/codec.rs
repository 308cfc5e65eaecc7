//! The binary payloads of the rigmon MCAP layout (little-endian): `rigmon.SampleBlock` and
//! `rigmon.TachoEdges` messages, encoded by the writer and decoded by the reader.

use anyhow::{bail, Result};

/// Encode a `rigmon.SampleBlock` payload into `buf` (cleared first).
pub(super) fn encode_block(
    buf: &mut Vec<u8>,
    first_sample: u64,
    fs: f64,
    unit: &str,
    samples: &[f32],
) {
    buf.clear();
    buf.reserve(30 + unit.len() + 4 * samples.len());
    buf.extend_from_slice(&first_sample.to_le_bytes());
    buf.extend_from_slice(&(first_sample as f64 / fs).to_le_bytes());
    buf.extend_from_slice(&fs.to_le_bytes());
    buf.extend_from_slice(&(samples.len() as u32).to_le_bytes());
    let unit = &unit.as_bytes()[..unit.len().min(u16::MAX as usize)];
    buf.extend_from_slice(&(unit.len() as u16).to_le_bytes());
    buf.extend_from_slice(unit);
    for x in samples {
        buf.extend_from_slice(&x.to_le_bytes());
    }
}

/// Encode a `rigmon.TachoEdges` payload into `buf` (cleared first).
pub(super) fn encode_edges(buf: &mut Vec<u8>, first_sample: u64, fs: f64, times: &[f64]) {
    buf.clear();
    buf.extend_from_slice(&first_sample.to_le_bytes());
    buf.extend_from_slice(&fs.to_le_bytes());
    buf.extend_from_slice(&(times.len() as u32).to_le_bytes());
    for t in times {
        buf.extend_from_slice(&t.to_le_bytes());
    }
}

/// A decoded `rigmon.SampleBlock`.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodedBlock {
    pub first_sample: u64,
    pub t0_s: f64,
    pub sample_rate_hz: f64,
    pub unit: String,
    pub samples: Vec<f32>,
}

fn le<const N: usize>(b: &[u8], at: usize) -> Option<[u8; N]> {
    b.get(at..at + N).map(|s| s.try_into().unwrap())
}

/// Decode a `rigmon.SampleBlock` payload.
/// Sample positions past 2^53 (no longer exact as f64 seconds; ~28,000 years at 10 kHz) are
/// damage, not a recording: refused so that no position arithmetic overflows downstream.
fn check_position(first_sample: u64, n: u64, what: &str) -> Result<()> {
    const MAX_SAMPLE: u64 = 1 << 53;
    match first_sample.checked_add(n) {
        Some(end) if end <= MAX_SAMPLE => Ok(()),
        _ => bail!("{what} at sample {first_sample} (+{n}): beyond any recording (2^53 samples); the message is damaged"),
    }
}

pub fn decode_block(b: &[u8]) -> Result<DecodedBlock> {
    let short = || {
        anyhow::anyhow!(
            "SampleBlock of {} bytes is shorter than its header",
            b.len()
        )
    };
    let first_sample = u64::from_le_bytes(le(b, 0).ok_or_else(short)?);
    let t0_s = f64::from_le_bytes(le(b, 8).ok_or_else(short)?);
    let sample_rate_hz = f64::from_le_bytes(le(b, 16).ok_or_else(short)?);
    let n = u32::from_le_bytes(le(b, 24).ok_or_else(short)?) as usize;
    let unit_len = u16::from_le_bytes(le(b, 28).ok_or_else(short)?) as usize;
    let data = 30 + unit_len;
    if b.len() != data + 4 * n {
        bail!("SampleBlock at sample {first_sample}: {} bytes, but n = {n} and unit_len = {unit_len} need {}", b.len(), data + 4 * n);
    }
    check_position(first_sample, n as u64, "SampleBlock")?;
    let unit = String::from_utf8_lossy(&b[30..data]).into_owned();
    let samples = b[data..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    Ok(DecodedBlock {
        first_sample,
        t0_s,
        sample_rate_hz,
        unit,
        samples,
    })
}

/// Decode a `rigmon.TachoEdges` payload: (first_sample, sample_rate_hz, edge times).
pub fn decode_edges(b: &[u8]) -> Result<(u64, f64, Vec<f64>)> {
    let short = || anyhow::anyhow!("TachoEdges of {} bytes is shorter than its header", b.len());
    let first_sample = u64::from_le_bytes(le(b, 0).ok_or_else(short)?);
    let fs = f64::from_le_bytes(le(b, 8).ok_or_else(short)?);
    let n = u32::from_le_bytes(le(b, 16).ok_or_else(short)?) as usize;
    if b.len() != 20 + 8 * n {
        bail!(
            "TachoEdges at sample {first_sample}: {} bytes, but n = {n} needs {}",
            b.len(),
            20 + 8 * n
        );
    }
    check_position(first_sample, 0, "TachoEdges")?;
    Ok((
        first_sample,
        fs,
        b[20..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by `tests/heavy/fuzz.rs` (fuzz_mcap_reader): a block at sample 2^64 - 1 overflowed the
    /// assembler's position arithmetic. Positions past 2^53 are refused as damage.
    #[test]
    fn a_block_past_any_recording_is_damage_not_an_overflow() {
        let mut buf = Vec::new();
        encode_block(&mut buf, u64::MAX - 1, 10_000.0, "g", &[1.0, 2.0]);
        let e = format!("{:#}", decode_block(&buf).unwrap_err());
        assert!(
            e.contains("beyond any recording") && e.contains("damaged"),
            "{e}"
        );
        encode_block(&mut buf, 1_000_000, 10_000.0, "g", &[1.0, 2.0]);
        assert_eq!(decode_block(&buf).unwrap().first_sample, 1_000_000);
        encode_edges(&mut buf, u64::MAX, 10_000.0, &[0.5]);
        assert!(decode_edges(&buf).is_err());
    }
}
