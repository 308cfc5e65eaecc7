//! The RIFF/WAVE header, read by hand so that nothing in it is trusted: the `fmt ` chunk
//! (PCM, IEEE float and WAVE_FORMAT_EXTENSIBLE with its valid bits, container size and
//! channel mask), and where the samples lie (the `data` chunk), checked against the file size.
//!
//! What a lying or unusual header did is said, never hidden (issue 38, F4/F15):
//! - samples are read by their container (24 valid bits in 32-bit containers are 32-bit
//!   integers with zero low bits, as scipy reads them), the valid bits are noted;
//! - a chunk of odd size is followed by its pad byte, as RIFF requires (a writer that left the
//!   pad out is tolerated when the next chunk shows it);
//! - a data size of 0 or 0xFFFFFFFF with bytes after it is an unfinalised header (a recorder
//!   stopped before writing the sizes): the data is read to the end of the file, with a warning;
//! - a data size smaller than what follows it (bytes that are not a chunk) is read as declared,
//!   with a warning saying how many bytes were left unread;
//! - a data size larger than the file is refused as truncated.

use super::WARNING;
use anyhow::{bail, Result};
use std::io::{Read, Seek, SeekFrom};

/// How the samples are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleKind {
    /// Signed integers (unsigned for 8-bit), read as fractions of the container's full scale.
    Int,
    Float,
}

/// What the header says, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct WavHeader {
    pub kind: SampleKind,
    pub channels: usize,
    pub sample_rate: u32,
    /// Bytes of one sample's container (1, 2, 3 or 4; 4 or 8 for float).
    pub container: usize,
    /// Bits that carry the signal (`wValidBitsPerSample`; the container's bits otherwise).
    pub valid_bits: u16,
    /// `dwChannelMask` of WAVE_FORMAT_EXTENSIBLE.
    pub channel_mask: Option<u32>,
    /// File offset of the first sample.
    pub data_offset: u64,
    /// Whole frames in the data.
    pub frames: u64,
    /// "int24 in 32-bit containers (WAVE_FORMAT_EXTENSIBLE, channel mask 0x4)", for the notes.
    pub format_text: String,
    /// Provenance notes; those starting with [`WARNING`] say what a header got wrong.
    pub notes: Vec<String>,
}

impl WavHeader {
    /// Bytes of one frame.
    pub fn frame_bytes(&self) -> usize {
        self.container * self.channels
    }
}

/// The KSDATAFORMAT_SUBTYPE GUID after its first two bytes (PCM = 1, IEEE float = 3).
const GUID_TAIL: [u8; 14] = [
    0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71,
];

/// Read the header of the WAV file `f` (of `file_len` bytes); `p` names it in errors.
pub fn read<F: Read + Seek>(f: &mut F, file_len: u64, p: &str) -> Result<WavHeader> {
    let mut head = [0u8; 12];
    f.read_exact(&mut head).map_err(|_| {
        anyhow::anyhow!(
            "{p}: not a WAV file: {file_len} bytes, shorter than the 12-byte RIFF header"
        )
    })?;
    match &head[..4] {
        b"RIFF" => {}
        b"RIFX" => bail!("{p}: big-endian RIFX WAV is not supported; convert it to little-endian RIFF (sox, ffmpeg)"),
        b"RF64" => bail!("{p}: RF64 (WAV over 4 GiB) is not supported; split the file or convert it to rigmon MCAP with another tool"),
        _ => bail!("{p}: not a WAV file (no RIFF header at the start)"),
    }
    if &head[8..12] != b"WAVE" {
        bail!(
            "{p}: a RIFF file but not WAVE (form type {:?})",
            String::from_utf8_lossy(&head[8..12])
        );
    }
    let mut notes = Vec::new();
    let riff = u32::from_le_bytes(head[4..8].try_into().unwrap());
    if riff == 0 || riff == u32::MAX {
        notes.push(format!("{WARNING}the RIFF size is {riff:#x}: the header was never finalised (a recording stopped before its sizes were written)"));
    }
    let mut fmt: Option<WavHeader> = None;
    let mut off = 12u64;
    loop {
        let Some((id, len)) = chunk_at(f, off, file_len)? else {
            bail!("{p}: no data chunk: the chunks end at byte {off} of {file_len} without one (truncated or not a sampled WAV?)");
        };
        let body = off + 8;
        if &id == b"data" {
            let Some(mut h) = fmt.take() else {
                bail!("{p}: the data chunk (byte {off}) comes before any fmt chunk; the sample format is unknown");
            };
            h.notes.splice(0..0, notes);
            settle_data(f, &mut h, body, len, file_len, p)?;
            return Ok(h);
        }
        if &id == b"fmt " {
            let take = u64::from(len).min(64).min(file_len.saturating_sub(body));
            let mut b = vec![0u8; take as usize];
            f.seek(SeekFrom::Start(body))?;
            f.read_exact(&mut b)?;
            if (len as usize) < 16 || b.len() < 16 {
                bail!("{p}: the fmt chunk (byte {off}) holds {len} bytes, fewer than the 16 every WAV needs (truncated?)");
            }
            fmt = Some(parse_fmt(&b, p)?);
        }
        off = next_chunk(f, body, len, file_len)?;
    }
}

/// The chunk id and length at `off`; `None` when fewer than 8 bytes remain.
fn chunk_at<F: Read + Seek>(f: &mut F, off: u64, file_len: u64) -> Result<Option<([u8; 4], u32)>> {
    if off.saturating_add(8) > file_len {
        return Ok(None);
    }
    let mut b = [0u8; 8];
    f.seek(SeekFrom::Start(off))?;
    f.read_exact(&mut b)?;
    Ok(Some((
        b[..4].try_into().unwrap(),
        u32::from_le_bytes(b[4..].try_into().unwrap()),
    )))
}

/// A chunk id is four printable ASCII characters.
fn plausible_id(id: &[u8; 4]) -> bool {
    id.iter().all(|c| (0x20..0x7f).contains(c))
}

/// Where the chunk after one whose body starts at `body` with `len` bytes begins: after its pad
/// byte when `len` is odd, unless the pad is missing (no chunk id there, one a byte earlier).
fn next_chunk<F: Read + Seek>(f: &mut F, body: u64, len: u32, file_len: u64) -> Result<u64> {
    let end = body + u64::from(len);
    if len % 2 == 0 {
        return Ok(end);
    }
    let padded = chunk_at(f, end + 1, file_len)?;
    if padded.is_some_and(|(id, _)| plausible_id(&id)) {
        return Ok(end + 1);
    }
    if chunk_at(f, end, file_len)?.is_some_and(|(id, _)| plausible_id(&id)) {
        return Ok(end);
    }
    Ok(end + 1)
}

/// The fmt chunk's first bytes (16, 18 or 40 and more).
fn parse_fmt(b: &[u8], p: &str) -> Result<WavHeader> {
    let u16_at = |k: usize| u16::from_le_bytes([b[k], b[k + 1]]);
    let u32_at = |k: usize| u32::from_le_bytes(b[k..k + 4].try_into().unwrap());
    let (tag, channels, rate) = (u16_at(0), u16_at(2) as usize, u32_at(4));
    let (align, bits) = (u16_at(12) as usize, u16_at(14));
    if channels == 0 {
        bail!("{p}: the fmt chunk declares 0 channels");
    }
    let (code, valid, mask) = if tag == 0xFFFE {
        if b.len() < 40 {
            bail!("{p}: WAVE_FORMAT_EXTENSIBLE fmt chunk of {} bytes (it needs 40); the header is damaged", b.len());
        }
        if b[25] != 0 || b[26..40] != GUID_TAIL {
            bail!("{p}: WAVE_FORMAT_EXTENSIBLE with an unknown sub-format GUID (only PCM and IEEE float are read); convert it to PCM or float WAV");
        }
        (u16::from(b[24]), u16_at(18), Some(u32_at(20)))
    } else {
        (tag, 0, None)
    };
    let kind = match code {
        1 => SampleKind::Int,
        3 => SampleKind::Float,
        other => bail!(
            "{p}: WAV {} {other:#06x} is not supported (PCM and IEEE float are; convert it, e.g. with sox or ffmpeg)",
            if mask.is_some() { "WAVE_FORMAT_EXTENSIBLE sub-format" } else { "format code" }
        ),
    };
    if align == 0 || align % channels != 0 {
        bail!("{p}: the fmt chunk's block align {align} is not a whole number of bytes per channel for {channels} channels; the header is damaged");
    }
    let container = align / channels;
    let ok = match kind {
        SampleKind::Int => (1..=4).contains(&container),
        SampleKind::Float => container == 4 || container == 8,
    };
    if !ok || usize::from(bits) > 8 * container || bits == 0 {
        bail!("{p}: {bits}-bit {} samples in {container}-byte containers are not supported (integers of 1-4 bytes, float of 4 or 8)", if kind == SampleKind::Int { "integer" } else { "float" });
    }
    let valid = if valid == 0 { bits } else { valid };
    if usize::from(valid) > 8 * container {
        bail!("{p}: WAVE_FORMAT_EXTENSIBLE declares {valid} valid bits in {}-bit containers; the header is damaged", 8 * container);
    }
    let mut notes = Vec::new();
    if let Some(m) = mask.filter(|&m| m != 0 && m.count_ones() as usize != channels) {
        notes.push(format!("{WARNING}the channel mask {m:#x} names {} speaker positions for {channels} channels; channels are mapped in file order", m.count_ones()));
    }
    let name = match kind {
        SampleKind::Float => format!("float{}", 8 * container),
        SampleKind::Int if usize::from(valid) == 8 * container => format!("int{}", 8 * container),
        SampleKind::Int => format!("int{valid} in {}-bit containers", 8 * container),
    };
    let format_text = match mask {
        Some(m) => format!("{name} (WAVE_FORMAT_EXTENSIBLE, channel mask {m:#x})"),
        None => name,
    };
    Ok(WavHeader {
        kind,
        channels,
        sample_rate: rate,
        container,
        valid_bits: valid,
        channel_mask: mask,
        data_offset: 0,
        frames: 0,
        format_text,
        notes,
    })
}

/// Settle where the samples are from the data chunk at `body` declaring `len` bytes.
fn settle_data<F: Read + Seek>(
    f: &mut F,
    h: &mut WavHeader,
    body: u64,
    len: u32,
    file_len: u64,
    p: &str,
) -> Result<()> {
    let rest = file_len.saturating_sub(body);
    let fb = h.frame_bytes() as u64;
    let mut bytes = u64::from(len);
    if (len == 0 || len == u32::MAX) && rest > 0 {
        bytes = rest;
        h.notes.push(format!("{WARNING}the data chunk's size is {len:#x}: the header was never finalised (a recording stopped before its sizes were written); read the {rest} bytes to the end of the file"));
    } else if bytes > rest {
        bail!("{p}: truncated: the WAV header announces {} frames ({bytes} bytes of data) but the file holds only {rest} bytes after the header ({file_len} in all)", bytes / fb);
    } else {
        let after = body + bytes + bytes % 2;
        let follows = file_len.saturating_sub(after);
        if follows > 0
            && !chunk_at(f, after, file_len)?
                .is_some_and(|(id, l)| plausible_id(&id) && u64::from(l) <= follows - 8)
        {
            h.notes.push(format!("{WARNING}the data chunk declares {bytes} bytes ({} frames) but {follows} more bytes follow it that are not a chunk: the header may understate the data (a writer that did not update it?); only the declared frames were read", bytes / fb));
        }
    }
    if bytes % fb != 0 {
        h.notes.push(format!("{WARNING}the data holds {bytes} bytes, not a whole number of {fb}-byte frames: the last {} bytes were ignored", bytes % fb));
    }
    h.data_offset = body;
    h.frames = bytes / fb;
    Ok(())
}

/// Decode `bytes` (whole frames, interleaved) into full-scale fractions (float samples as
/// they are), appended to `out`.
pub fn decode(h: &WavHeader, bytes: &[u8], out: &mut Vec<f64>) {
    const S8: f64 = 128.0;
    const S16: f64 = 32768.0;
    const S24: f64 = 8_388_608.0;
    const S32: f64 = 2_147_483_648.0;
    let c = h.container;
    out.reserve(bytes.len() / c);
    let it = bytes.chunks_exact(c);
    match (h.kind, c) {
        (SampleKind::Int, 1) => out.extend(it.map(|b| (f64::from(b[0]) - 128.0) / S8)),
        (SampleKind::Int, 2) => {
            out.extend(it.map(|b| f64::from(i16::from_le_bytes([b[0], b[1]])) / S16))
        }
        (SampleKind::Int, 3) => {
            out.extend(it.map(|b| f64::from(i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8) / S24))
        }
        (SampleKind::Int, _) => {
            out.extend(it.map(|b| f64::from(i32::from_le_bytes(b.try_into().unwrap())) / S32))
        }
        (SampleKind::Float, 4) => {
            out.extend(it.map(|b| f64::from(f32::from_le_bytes(b.try_into().unwrap()))))
        }
        (SampleKind::Float, _) => out.extend(it.map(|b| f64::from_le_bytes(b.try_into().unwrap()))),
    }
}
