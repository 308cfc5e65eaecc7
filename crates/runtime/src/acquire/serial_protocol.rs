//! The rigmon serial DAQ protocol, version 1: a framed binary stream (encoder and a streaming
//! decoder). The decoder resynchronises after garbage, never panics, bounds every length it
//! reads, and counts CRC errors, bad headers, sequence gaps and lost samples.
//!
//! Frame layout (all integers little-endian; CRC-32 is the zlib/IEEE CRC, `CRC_32_ISO_HDLC`):
//!
//! | offset        | size    | field |
//! |---------------|---------|-------|
//! | 0             | 4       | sync word `A5 5A 52 4D` |
//! | 4             | 1       | protocol version = 1 |
//! | 5             | 1       | sample format: 1 = int16, 2 = int24, 3 = float32 |
//! | 6             | 1       | channel count C (1..=64) |
//! | 7             | 1       | flags (reserved: senders write 0, receivers ignore) |
//! | 8             | 2       | samples per channel N (1..=4096) |
//! | 10            | 2       | tacho edge count E (0..=1024) |
//! | 12            | 4       | sequence number (u32, +1 per frame, wraps) |
//! | 16            | 8       | sample-clock timestamp: index of the frame's first sample (u64) |
//! | 24            | 4       | sample rate, Hz (f32) |
//! | 28            | 4       | header CRC-32 of bytes 0..28 |
//! | 32            | 4·C     | per-channel scale (f32): value = raw × scale |
//! | 32+4C         | N·C·B   | samples interleaved by sample (s0c0 s0c1 … s1c0 …), B = 2/3/4 bytes, two's complement or IEEE f32 |
//! | 32+4C+NCB     | 8·E     | tacho edges: sample-clock position of each edge, u64 fixed point Q48.16 (position = q / 65536 samples) |
//! | end−4         | 4       | frame CRC-32 of every byte before it |
//!
//! A frame carries at most [`MAX_SAMPLE_BYTES`] of samples, so the largest frame is
//! [`MAX_FRAME_BYTES`]. Channels are the rig file's `channels` in order (an analog tacho is one
//! of them); the rig's `sensitivity` is applied on top of `scale`.

use crc::{Crc, CRC_32_ISO_HDLC};
use std::fmt;

/// The CRC both CRCs of a frame use (zlib's `crc32`).
pub const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
/// First four bytes of every frame.
pub const SYNC: [u8; 4] = [0xA5, 0x5A, 0x52, 0x4D];
/// Protocol version this module reads and writes.
pub const VERSION: u8 = 1;
/// Header length, bytes (sync to header CRC).
pub const HEADER_BYTES: usize = 32;
pub const MAX_CHANNELS: usize = 64;
pub const MAX_SAMPLES: usize = 4096;
pub const MAX_EDGES: usize = 1024;
/// Upper bound on the sample bytes (N·C·B) of one frame.
pub const MAX_SAMPLE_BYTES: usize = 256 * 1024;
/// Upper bound on a whole frame.
pub const MAX_FRAME_BYTES: usize =
    HEADER_BYTES + 4 * MAX_CHANNELS + MAX_SAMPLE_BYTES + 8 * MAX_EDGES + 4;
/// Fixed-point scale of edge positions (Q48.16).
pub const EDGE_FRACTION: f64 = 65536.0;

/// How samples are coded on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleFormat {
    I16,
    I24,
    F32,
}

impl SampleFormat {
    pub fn code(self) -> u8 {
        match self {
            SampleFormat::I16 => 1,
            SampleFormat::I24 => 2,
            SampleFormat::F32 => 3,
        }
    }

    pub fn from_code(c: u8) -> Option<Self> {
        match c {
            1 => Some(SampleFormat::I16),
            2 => Some(SampleFormat::I24),
            3 => Some(SampleFormat::F32),
            _ => None,
        }
    }

    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            SampleFormat::I16 => 2,
            SampleFormat::I24 => 3,
            SampleFormat::F32 => 4,
        }
    }

    /// Largest raw integer (for choosing a scale); `None` for float.
    pub fn full_scale(self) -> Option<f64> {
        match self {
            SampleFormat::I16 => Some(32767.0),
            SampleFormat::I24 => Some(8_388_607.0),
            SampleFormat::F32 => None,
        }
    }
}

impl std::str::FromStr for SampleFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "i16" | "int16" => Ok(SampleFormat::I16),
            "i24" | "int24" => Ok(SampleFormat::I24),
            "f32" | "float32" => Ok(SampleFormat::F32),
            _ => Err(format!("sample format {s:?}: expected i16, i24 or f32")),
        }
    }
}

impl fmt::Display for SampleFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SampleFormat::I16 => "i16",
            SampleFormat::I24 => "i24",
            SampleFormat::F32 => "f32",
        })
    }
}

/// One decoded frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub sequence: u32,
    /// Sample-clock index of the first sample.
    pub first_sample: u64,
    pub sample_rate: f32,
    pub format: SampleFormat,
    pub scales: Vec<f32>,
    /// Scaled values, one vector per channel (raw × scale).
    pub channels: Vec<Vec<f32>>,
    /// Tacho edge positions in samples on the sample clock (fractional).
    pub edges: Vec<f64>,
}

impl Frame {
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Why a frame could not be encoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    #[error("{0} channels: a frame carries 1 to 64")]
    Channels(usize),
    #[error("{0} samples per channel: a frame carries 1 to 4096")]
    Samples(usize),
    #[error("{0} tacho edges: a frame carries at most 1024")]
    Edges(usize),
    #[error("{0} sample bytes: a frame carries at most 262144; send fewer samples per frame")]
    TooLarge(usize),
    #[error("channel {0} has {1} samples, channel 0 has {2}")]
    Ragged(usize, usize, usize),
    #[error("{0} scales for {1} channels")]
    Scales(usize, usize),
}

/// Sample rate, format and scales of an encoder; [`FrameEncoder::encode`] appends frames.
#[derive(Debug, Clone)]
pub struct FrameEncoder {
    pub sample_rate: f32,
    pub format: SampleFormat,
    /// value = raw × scale, per channel.
    pub scales: Vec<f32>,
    pub flags: u8,
}

impl FrameEncoder {
    /// Append one frame to `out`. `channels[c]` are values (raw × scale); integer formats
    /// round to the nearest step and clamp at full scale. `edges` are sample-clock positions
    /// (fractional samples).
    pub fn encode(
        &self,
        out: &mut Vec<u8>,
        sequence: u32,
        first_sample: u64,
        channels: &[&[f32]],
        edges: &[f64],
    ) -> Result<(), EncodeError> {
        let c = channels.len();
        if c == 0 || c > MAX_CHANNELS {
            return Err(EncodeError::Channels(c));
        }
        if self.scales.len() != c {
            return Err(EncodeError::Scales(self.scales.len(), c));
        }
        let n = channels[0].len();
        if n == 0 || n > MAX_SAMPLES {
            return Err(EncodeError::Samples(n));
        }
        if let Some((i, ch)) = channels.iter().enumerate().find(|(_, ch)| ch.len() != n) {
            return Err(EncodeError::Ragged(i, ch.len(), n));
        }
        if edges.len() > MAX_EDGES {
            return Err(EncodeError::Edges(edges.len()));
        }
        let b = self.format.bytes();
        if n * c * b > MAX_SAMPLE_BYTES {
            return Err(EncodeError::TooLarge(n * c * b));
        }
        let start = out.len();
        out.reserve(HEADER_BYTES + 4 * c + n * c * b + 8 * edges.len() + 4);
        out.extend_from_slice(&SYNC);
        out.push(VERSION);
        out.push(self.format.code());
        out.push(c as u8);
        out.push(self.flags);
        out.extend_from_slice(&(n as u16).to_le_bytes());
        out.extend_from_slice(&(edges.len() as u16).to_le_bytes());
        out.extend_from_slice(&sequence.to_le_bytes());
        out.extend_from_slice(&first_sample.to_le_bytes());
        out.extend_from_slice(&self.sample_rate.to_le_bytes());
        let hcrc = CRC32.checksum(&out[start..start + 28]);
        out.extend_from_slice(&hcrc.to_le_bytes());
        for s in &self.scales {
            out.extend_from_slice(&s.to_le_bytes());
        }
        for i in 0..n {
            for (ch, &scale) in channels.iter().zip(&self.scales) {
                let v = ch[i];
                match self.format {
                    SampleFormat::F32 => out.extend_from_slice(&(v / scale).to_le_bytes()),
                    SampleFormat::I16 => {
                        out.extend_from_slice(&(quantise(v, scale, 32767.0) as i16).to_le_bytes())
                    }
                    SampleFormat::I24 => {
                        out.extend_from_slice(&quantise(v, scale, 8_388_607.0).to_le_bytes()[..3])
                    }
                }
            }
        }
        for &e in edges {
            let q = (e.max(0.0) * EDGE_FRACTION).round();
            out.extend_from_slice(&(q.min(u64::MAX as f64) as u64).to_le_bytes());
        }
        let crc = CRC32.checksum(&out[start..]);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(())
    }
}

fn quantise(v: f32, scale: f32, full: f64) -> i32 {
    let r = (v as f64 / scale as f64).round();
    if r.is_nan() {
        0
    } else {
        r.clamp(-full - 1.0, full) as i32
    }
}

/// What the decoder has seen so far.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DecoderCounters {
    /// Good frames decoded.
    pub frames: u64,
    /// Frames whose header was sound but whose frame CRC failed (corrupt or truncated).
    pub crc_errors: u64,
    /// Sync words followed by a header that failed its CRC or held impossible values.
    pub bad_headers: u64,
    /// Frames of a protocol version this decoder does not read.
    pub unsupported_version: u64,
    /// Bytes thrown away while looking for a sync word.
    pub skipped_bytes: u64,
    /// Times the sequence number did not follow the previous frame's.
    pub sequence_gaps: u64,
    /// Samples missing on the sample clock between consecutive good frames.
    pub samples_lost: u64,
    /// Times the sample clock went backwards (the DAQ restarted).
    pub clock_resets: u64,
}

impl DecoderCounters {
    /// Frames rejected for any reason.
    pub fn bad_frames(&self) -> u64 {
        self.crc_errors + self.bad_headers + self.unsupported_version
    }
}

/// A streaming decoder: [`Decoder::feed`] bytes as they arrive, then call
/// [`Decoder::next_frame`] until it returns `None`. Memory stays below
/// 2 × [`MAX_FRAME_BYTES`] whatever it is fed.
#[derive(Debug, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    pos: usize,
    counters: DecoderCounters,
    expect_sequence: Option<u32>,
    expect_sample: Option<u64>,
}

enum Header {
    /// Not a frame start here; skip one byte.
    Bad,
    Version,
    /// A sound header: total frame length and its fields.
    Good {
        total: usize,
        format: SampleFormat,
        c: usize,
        n: usize,
        e: usize,
        sequence: u32,
        first_sample: u64,
        sample_rate: f32,
    },
}

impl Decoder {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn counters(&self) -> &DecoderCounters {
        &self.counters
    }

    /// Bytes waiting to be decoded.
    pub fn buffered(&self) -> usize {
        self.buf.len() - self.pos
    }

    /// Append received bytes.
    pub fn feed(&mut self, data: &[u8]) {
        if self.pos > 0
            && (self.pos >= self.buf.len() / 2 || self.buf.len() + data.len() > 2 * MAX_FRAME_BYTES)
        {
            self.buf.drain(..self.pos);
            self.pos = 0;
        }
        // Bound memory: a valid frame never needs more than MAX_FRAME_BYTES of lookahead.
        let room = (2 * MAX_FRAME_BYTES).saturating_sub(self.buf.len());
        if data.len() > room {
            let drop = (data.len() - room).min(self.buf.len());
            self.counters.skipped_bytes += drop as u64;
            self.buf.drain(..drop);
        }
        let data = if data.len() > 2 * MAX_FRAME_BYTES {
            self.counters.skipped_bytes += (data.len() - 2 * MAX_FRAME_BYTES) as u64;
            &data[data.len() - 2 * MAX_FRAME_BYTES..]
        } else {
            data
        };
        self.buf.extend_from_slice(data);
    }

    /// Forget buffered bytes (after the device was reopened: a partial frame from before
    /// cannot continue). Sequence and sample-clock expectations are kept, so the samples
    /// missed while disconnected are counted as lost.
    pub fn discard_buffered(&mut self) {
        self.counters.skipped_bytes += self.buffered() as u64;
        self.buf.clear();
        self.pos = 0;
    }

    /// The next good frame in the buffered bytes, or `None` until more bytes arrive.
    pub fn next_frame(&mut self) -> Option<Frame> {
        loop {
            let avail = &self.buf[self.pos..];
            let Some(at) = find_sync(avail) else {
                // Keep a possible partial sync word at the end.
                let keep = avail.len().min(SYNC.len() - 1);
                let keep = (1..=keep)
                    .rev()
                    .find(|&k| avail[avail.len() - k..] == SYNC[..k])
                    .unwrap_or(0);
                let drop = avail.len() - keep;
                self.counters.skipped_bytes += drop as u64;
                self.pos += drop;
                return None;
            };
            self.counters.skipped_bytes += at as u64;
            self.pos += at;
            let avail = &self.buf[self.pos..];
            if avail.len() < HEADER_BYTES {
                return None;
            }
            match parse_header(&avail[..HEADER_BYTES]) {
                Header::Bad => {
                    self.counters.bad_headers += 1;
                    self.skip_one();
                }
                Header::Version => {
                    self.counters.unsupported_version += 1;
                    self.skip_one();
                }
                Header::Good {
                    total,
                    format,
                    c,
                    n,
                    e,
                    sequence,
                    first_sample,
                    sample_rate,
                } => {
                    if avail.len() < total {
                        return None;
                    }
                    let frame = &avail[..total];
                    let want = u32::from_le_bytes(frame[total - 4..].try_into().unwrap());
                    if CRC32.checksum(&frame[..total - 4]) != want {
                        self.counters.crc_errors += 1;
                        self.skip_one();
                        continue;
                    }
                    let out =
                        decode_body(frame, format, c, n, e, sequence, first_sample, sample_rate);
                    self.pos += total;
                    self.account(&out);
                    return Some(out);
                }
            }
        }
    }

    fn skip_one(&mut self) {
        self.pos += 1;
        self.counters.skipped_bytes += 1;
    }

    fn account(&mut self, f: &Frame) {
        self.counters.frames += 1;
        if let Some(s) = self.expect_sequence {
            if s != f.sequence {
                self.counters.sequence_gaps += 1;
            }
        }
        if let Some(x) = self.expect_sample {
            if f.first_sample > x {
                self.counters.samples_lost = self
                    .counters
                    .samples_lost
                    .saturating_add(f.first_sample - x);
            } else if f.first_sample < x {
                self.counters.clock_resets += 1;
            }
        }
        self.expect_sequence = Some(f.sequence.wrapping_add(1));
        self.expect_sample = Some(f.first_sample.saturating_add(f.len() as u64));
    }
}

fn find_sync(b: &[u8]) -> Option<usize> {
    b.windows(SYNC.len()).position(|w| w == SYNC)
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}
fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(b[i..i + 4].try_into().unwrap())
}
fn u64_at(b: &[u8], i: usize) -> u64 {
    u64::from_le_bytes(b[i..i + 8].try_into().unwrap())
}
fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes(b[i..i + 4].try_into().unwrap())
}

fn parse_header(h: &[u8]) -> Header {
    if CRC32.checksum(&h[..28]) != u32_at(h, 28) {
        return Header::Bad;
    }
    if h[4] != VERSION {
        return Header::Version;
    }
    let Some(format) = SampleFormat::from_code(h[5]) else {
        return Header::Bad;
    };
    let c = h[6] as usize;
    let n = u16_at(h, 8) as usize;
    let e = u16_at(h, 10) as usize;
    let sample_rate = f32_at(h, 24);
    let sample_bytes = n * c * format.bytes();
    if !(1..=MAX_CHANNELS).contains(&c)
        || !(1..=MAX_SAMPLES).contains(&n)
        || e > MAX_EDGES
        || sample_bytes > MAX_SAMPLE_BYTES
        || !(sample_rate.is_finite() && sample_rate > 0.0)
    {
        return Header::Bad;
    }
    let total = HEADER_BYTES + 4 * c + sample_bytes + 8 * e + 4;
    Header::Good {
        total,
        format,
        c,
        n,
        e,
        sequence: u32_at(h, 12),
        first_sample: u64_at(h, 16),
        sample_rate,
    }
}

#[allow(clippy::too_many_arguments)]
fn decode_body(
    frame: &[u8],
    format: SampleFormat,
    c: usize,
    n: usize,
    e: usize,
    sequence: u32,
    first_sample: u64,
    sample_rate: f32,
) -> Frame {
    let scales: Vec<f32> = (0..c)
        .map(|k| f32_at(frame, HEADER_BYTES + 4 * k))
        .collect();
    let mut channels: Vec<Vec<f32>> = (0..c).map(|_| Vec::with_capacity(n)).collect();
    let b = format.bytes();
    let data = &frame[HEADER_BYTES + 4 * c..HEADER_BYTES + 4 * c + n * c * b];
    for (k, raw) in data.chunks_exact(b).enumerate() {
        let ch = k % c;
        let v = match format {
            SampleFormat::I16 => i16::from_le_bytes([raw[0], raw[1]]) as f32 * scales[ch],
            SampleFormat::I24 => {
                (i32::from_le_bytes([0, raw[0], raw[1], raw[2]]) >> 8) as f32 * scales[ch]
            }
            SampleFormat::F32 => f32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]) * scales[ch],
        };
        channels[ch].push(v);
    }
    let eo = HEADER_BYTES + 4 * c + n * c * b;
    let edges = (0..e)
        .map(|k| u64_at(frame, eo + 8 * k) as f64 / EDGE_FRACTION)
        .collect();
    Frame {
        sequence,
        first_sample,
        sample_rate,
        format,
        scales,
        channels,
        edges,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn enc(format: SampleFormat, scales: Vec<f32>) -> FrameEncoder {
        FrameEncoder {
            sample_rate: 10_000.0,
            format,
            scales,
            flags: 0,
        }
    }

    fn signal(c: usize, n: usize, first: u64) -> Vec<Vec<f32>> {
        (0..c)
            .map(|ch| {
                (0..n)
                    .map(|i| ((first as usize + i) as f32 * 0.37 + ch as f32).sin() * 3.0)
                    .collect()
            })
            .collect()
    }

    fn frames(e: &FrameEncoder, count: usize, n: usize) -> (Vec<u8>, Vec<Vec<Vec<f32>>>) {
        let mut out = Vec::new();
        let mut sent = Vec::new();
        for k in 0..count {
            let s = signal(e.scales.len(), n, (k * n) as u64);
            let refs: Vec<&[f32]> = s.iter().map(Vec::as_slice).collect();
            e.encode(
                &mut out,
                k as u32,
                (k * n) as u64,
                &refs,
                &[(k * n) as f64 + 0.25],
            )
            .unwrap();
            sent.push(s);
        }
        (out, sent)
    }

    fn decode_all(d: &mut Decoder) -> Vec<Frame> {
        std::iter::from_fn(|| d.next_frame()).collect()
    }

    #[test]
    fn f32_round_trip_is_bit_exact_and_fields_survive() {
        let e = enc(SampleFormat::F32, vec![1.0, 1.0, 1.0, 1.0]);
        let (bytes, sent) = frames(&e, 3, 100);
        assert_eq!(bytes.len(), 3 * (32 + 16 + 100 * 4 * 4 + 8 + 4));
        let mut d = Decoder::new();
        d.feed(&bytes);
        let got = decode_all(&mut d);
        assert_eq!(got.len(), 3);
        for (k, f) in got.iter().enumerate() {
            assert_eq!(f.sequence, k as u32);
            assert_eq!(f.first_sample, k as u64 * 100);
            assert_eq!(f.sample_rate, 10_000.0);
            assert_eq!(f.channels, sent[k]);
            assert_eq!(f.edges, [k as f64 * 100.0 + 0.25]);
        }
        assert_eq!(
            *d.counters(),
            DecoderCounters {
                frames: 3,
                ..Default::default()
            }
        );
    }

    #[test]
    fn integer_formats_are_within_half_a_step() {
        for (format, full) in [
            (SampleFormat::I16, 32767.0f32),
            (SampleFormat::I24, 8_388_607.0),
        ] {
            let scale = 3.0 / full;
            let e = enc(format, vec![scale, scale]);
            let (bytes, sent) = frames(&e, 2, 50);
            let mut d = Decoder::new();
            d.feed(&bytes);
            let got = decode_all(&mut d);
            assert_eq!(got.len(), 2, "{format}");
            for (f, s) in got.iter().zip(&sent) {
                for (a, b) in f.channels.iter().flatten().zip(s.iter().flatten()) {
                    assert!(
                        (a - b).abs() <= scale * 0.5 + 1e-6 * b.abs(),
                        "{format}: {a} vs {b}"
                    );
                }
            }
            // Negative full scale survives the 24-bit sign extension.
            let mut out = Vec::new();
            e.encode(&mut out, 0, 0, &[&[-3.0], &[3.0]], &[]).unwrap();
            let mut d = Decoder::new();
            d.feed(&out);
            let f = d.next_frame().unwrap();
            assert!(
                (f.channels[0][0] + 3.0).abs() < 1e-4 && (f.channels[1][0] - 3.0).abs() < 1e-4,
                "{format} {:?}",
                f.channels
            );
        }
    }

    #[test]
    fn byte_at_a_time_and_garbage_between_frames() {
        let e = enc(SampleFormat::I16, vec![0.001]);
        let (bytes, _) = frames(&e, 5, 20);
        let per = bytes.len() / 5;
        let mut stream = b"noise\xA5\x5A\x52".to_vec(); // includes a partial sync word
        for k in 0..5 {
            stream.extend_from_slice(&bytes[k * per..(k + 1) * per]);
            stream.extend_from_slice(&[0xA5, 0x5A, 0x52, 0x4D, 1, 2, 3]); // false sync
        }
        let mut d = Decoder::new();
        let mut got = Vec::new();
        for b in &stream {
            d.feed(std::slice::from_ref(b));
            got.extend(decode_all(&mut d));
        }
        assert_eq!(got.len(), 5);
        assert_eq!(d.counters().sequence_gaps, 0);
        assert_eq!(d.counters().crc_errors, 0);
        assert_eq!(d.counters().bad_headers, 4); // the false syncs followed by a whole frame
    }

    #[test]
    fn corrupt_frames_are_counted_and_skipped_and_the_gap_is_measured() {
        let e = enc(SampleFormat::I24, vec![1e-6, 1e-6]);
        let (mut bytes, _) = frames(&e, 10, 40);
        let per = bytes.len() / 10;
        bytes[3 * per + 100] ^= 0x10; // payload of frame 3
        bytes[7 * per + 13] ^= 0x01; // header (sequence) of frame 7
        let mut d = Decoder::new();
        d.feed(&bytes);
        let got = decode_all(&mut d);
        assert_eq!(
            got.iter().map(|f| f.sequence).collect::<Vec<_>>(),
            [0, 1, 2, 4, 5, 6, 8, 9]
        );
        let c = d.counters();
        assert_eq!(
            (c.crc_errors, c.bad_headers, c.sequence_gaps, c.samples_lost),
            (1, 1, 2, 80)
        );
        assert_eq!(c.bad_frames(), 2);
    }

    #[test]
    fn truncated_frame_then_good_frames() {
        let e = enc(SampleFormat::F32, vec![1.0]);
        let (bytes, _) = frames(&e, 4, 30);
        let per = bytes.len() / 4;
        let mut stream = bytes[..per + per / 2].to_vec(); // frame 1 cut in half
        stream.extend_from_slice(&bytes[2 * per..]);
        let mut d = Decoder::new();
        d.feed(&stream);
        let got = decode_all(&mut d);
        assert_eq!(
            got.iter().map(|f| f.sequence).collect::<Vec<_>>(),
            [0, 2, 3]
        );
        assert_eq!(d.counters().crc_errors, 1);
        assert_eq!(d.counters().samples_lost, 30);
    }

    #[test]
    fn other_versions_and_impossible_headers_are_rejected() {
        let mut h = vec![0u8; 32];
        h[..4].copy_from_slice(&SYNC);
        h[4] = 2;
        let crc = CRC32.checksum(&h[..28]);
        h[28..].copy_from_slice(&crc.to_le_bytes());
        let mut d = Decoder::new();
        d.feed(&h);
        assert!(d.next_frame().is_none());
        assert_eq!(d.counters().unsupported_version, 1);
        // Version 1 with 0 channels.
        h[4] = 1;
        h[5] = 3;
        let crc = CRC32.checksum(&h[..28]);
        h[28..].copy_from_slice(&crc.to_le_bytes());
        let mut d = Decoder::new();
        d.feed(&h);
        assert!(d.next_frame().is_none());
        assert_eq!(d.counters().bad_headers, 1);
        assert!(matches!(
            enc(SampleFormat::F32, vec![1.0; 64]).encode(
                &mut Vec::new(),
                0,
                0,
                &vec![&[0.0f32; 4096][..]; 64],
                &[]
            ),
            Err(EncodeError::TooLarge(_))
        ));
    }

    #[test]
    fn random_bytes_never_panic_and_memory_stays_bounded() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let e = enc(SampleFormat::I16, vec![0.01; 3]);
        let (good, _) = frames(&e, 3, 64);
        let mut d = Decoder::new();
        for round in 0..300 {
            let len = rng.random_range(0..4000);
            let mut junk: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            if round % 3 == 0 {
                // Sync words with random headers, and good frames with random bit flips.
                junk.extend_from_slice(&SYNC);
                let mut g = good.clone();
                let i = rng.random_range(0..g.len());
                g[i] ^= 1 << rng.random_range(0..8);
                junk.extend_from_slice(&g);
            }
            d.feed(&junk);
            while d.next_frame().is_some() {}
            assert!(d.buf.len() <= 2 * MAX_FRAME_BYTES + 4000);
        }
        // Each flipped frame group still yields most good frames.
        assert!(d.counters().frames >= 150, "{:?}", d.counters());
        // A huge burst is bounded too.
        d.feed(&vec![0xA5; 3 * MAX_FRAME_BYTES]);
        while d.next_frame().is_some() {}
        assert!(d.buf.len() <= 2 * MAX_FRAME_BYTES);
    }
}
