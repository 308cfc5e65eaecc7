//! The rigmon CAN layout, version 1 (classic CAN 8-byte and CAN FD 64-byte frames): an
//! encoder, and a decoder that checks every frame, unwraps the 24-bit sample-clock stamps,
//! aligns the channels on the sample clock and counts bad frames, sequence gaps and lost
//! samples. Transport-free: frames are `(11-bit id, payload)`; `can.rs` does the sockets.
//!
//! IDs are standard 11-bit IDs relative to `base_id` (default 0x100); all integers
//! little-endian:
//!
//! | ID            | frame | payload |
//! |---------------|-------|---------|
//! | base + 0x00   | INFO    | `u8 channel`, `u8 format` (1 = int16), `f32 scale` (value = raw × scale), `u16 sample rate, Hz` — 8 bytes, sent for every channel at start and about once a second |
//! | base + 0x01 + c (c = 0..31) | SAMPLES of channel c | `u8 sequence` (+1 per frame of this ID, wraps), `u24 sample-clock index of the first sample` (mod 2^24), then k × `i16` samples: k = 2 in a classic 8-byte frame, 30 in a 64-byte FD frame (any even payload of 6 or more bytes is read) |
//! | base + 0x21   | EDGES   | `u8 sequence`, `u8 n`, 2 bytes reserved, n × `u32` edge position: sample-clock index mod 2^24 in the upper 24 bits, 1/256-sample fraction in the lower 8 (n = 1 classic, up to 15 FD) |
//!
//! Channels are the rig file's `channels` in order (an analog tacho is one of them). The
//! receiver's clock starts at the first stamp it sees and unwraps later stamps to the value
//! nearest its running clock (the stamps wrap every 2^24 samples: 28 min at 10 kHz).
//! A lost SAMPLES frame leaves NaN in its channel and is counted; a channel more than
//! `max_lag` samples behind the others is padded with NaN so the rest keeps flowing.

/// Frame ID offsets from `base_id`.
pub const ID_INFO: u32 = 0x00;
pub const ID_SAMPLES: u32 = 0x01;
pub const ID_EDGES: u32 = 0x21;
/// Highest channel count the layout has IDs for.
pub const MAX_CAN_CHANNELS: usize = 32;
/// Stamps are 24-bit.
pub const STAMP_MOD: u64 = 1 << 24;
/// Bytes before the samples in a SAMPLES frame.
pub const SAMPLES_HEADER: usize = 4;
/// int16 format code in INFO.
pub const FORMAT_I16: u8 = 1;

/// Samples per SAMPLES frame for a payload size (8 classic, 64 FD).
pub fn samples_per_frame(payload: usize) -> usize {
    payload.saturating_sub(SAMPLES_HEADER) / 2
}

/// Largest base ID that leaves room for the whole layout in 11 bits.
pub const MAX_BASE_ID: u32 = 0x7FF - ID_EDGES;

/// Encodes a stream of samples into CAN frames (used by tests and adapters' firmware
/// authors as the reference).
#[derive(Debug, Clone)]
pub struct CanEncoder {
    pub base_id: u32,
    /// 8 for classic CAN, 64 for CAN FD.
    pub payload: usize,
    pub sample_rate: u16,
    /// value = raw × scale, per channel.
    pub scales: Vec<f32>,
    seq: Vec<u8>,
    edge_seq: u8,
}

impl CanEncoder {
    pub fn new(base_id: u32, payload: usize, sample_rate: u16, scales: Vec<f32>) -> Self {
        assert!(
            payload == 8 || payload == 64,
            "payload is 8 (classic) or 64 (FD)"
        );
        assert!(!scales.is_empty() && scales.len() <= MAX_CAN_CHANNELS && base_id <= MAX_BASE_ID);
        let seq = vec![0; scales.len()];
        CanEncoder {
            base_id,
            payload,
            sample_rate,
            scales,
            seq,
            edge_seq: 0,
        }
    }

    /// INFO frames for every channel.
    pub fn info(&self) -> Vec<(u32, Vec<u8>)> {
        self.scales
            .iter()
            .enumerate()
            .map(|(c, s)| {
                let mut d = vec![c as u8, FORMAT_I16];
                d.extend_from_slice(&s.to_le_bytes());
                d.extend_from_slice(&self.sample_rate.to_le_bytes());
                (self.base_id + ID_INFO, d)
            })
            .collect()
    }

    /// SAMPLES frames for `channels[c][..]` starting at sample-clock index `first`, channel
    /// by channel in chunks of [`samples_per_frame`] (the last chunk may be shorter).
    pub fn samples(&mut self, first: u64, channels: &[&[f32]]) -> Vec<(u32, Vec<u8>)> {
        let k = samples_per_frame(self.payload);
        let n = channels.first().map_or(0, |c| c.len());
        let mut out = Vec::new();
        let mut at = 0;
        while at < n {
            let m = k.min(n - at);
            for (c, ch) in channels.iter().enumerate() {
                let mut d = Vec::with_capacity(self.payload);
                d.push(self.seq[c]);
                self.seq[c] = self.seq[c].wrapping_add(1);
                d.extend_from_slice(&((first + at as u64) % STAMP_MOD).to_le_bytes()[..3]);
                for &v in &ch[at..at + m] {
                    let r = (v as f64 / self.scales[c] as f64).round();
                    let r = if r.is_nan() {
                        0.0
                    } else {
                        r.clamp(-32768.0, 32767.0)
                    };
                    d.extend_from_slice(&(r as i16).to_le_bytes());
                }
                out.push((self.base_id + ID_SAMPLES + c as u32, d));
            }
            at += m;
        }
        out
    }

    /// EDGES frames for edge positions in samples on the sample clock.
    pub fn edges(&mut self, positions: &[f64]) -> Vec<(u32, Vec<u8>)> {
        let per = (self.payload - 4) / 4;
        positions
            .chunks(per)
            .map(|chunk| {
                let mut d = vec![self.edge_seq, chunk.len() as u8, 0, 0];
                self.edge_seq = self.edge_seq.wrapping_add(1);
                for &p in chunk {
                    let q = (p.max(0.0) * 256.0).round() as u64 % (STAMP_MOD << 8);
                    d.extend_from_slice(&(q as u32).to_le_bytes());
                }
                (self.base_id + ID_EDGES, d)
            })
            .collect()
    }
}

/// What the decoder has seen.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CanCounters {
    /// Frames of this layout accepted.
    pub frames: u64,
    /// Frames of this layout that were malformed (length, channel, format, rate).
    pub bad_frames: u64,
    /// Frames with IDs outside the layout (other traffic on the bus), ignored.
    pub foreign: u64,
    /// SAMPLES frames dropped because their channel's INFO frame had not arrived yet.
    pub unscaled: u64,
    /// SAMPLES frames that arrived after their place had been filled (too late), dropped.
    pub late: u64,
    pub sequence_gaps: u64,
    /// Times the clock jumped too far to fill (adapter restart): buffers restart there.
    pub clock_resets: u64,
    /// Samples filled with NaN (lost frames, lagging channels).
    pub samples_lost: u64,
}

#[derive(Debug, Clone, Default)]
struct Chan {
    scale: Option<f32>,
    seq: Option<u8>,
    /// Samples from the decoder's `emitted` index on.
    buf: Vec<f32>,
}

/// Samples every channel has, ready to be handed on.
#[derive(Debug, Clone, PartialEq)]
pub struct Aligned {
    pub first_sample: u64,
    /// One vector per device channel, all the same length (values = raw × scale).
    pub channels: Vec<Vec<f32>>,
    /// Tacho edge positions in samples on the sample clock.
    pub edges: Vec<f64>,
}

/// Turns CAN frames back into aligned samples.
#[derive(Debug)]
pub struct CanDecoder {
    base_id: u32,
    sample_rate: f64,
    max_lag: usize,
    chans: Vec<Chan>,
    /// Index of `buf[0]` of every channel; `None` until the first SAMPLES frame.
    emitted: Option<u64>,
    edge_seq: Option<u8>,
    edges: Vec<f64>,
    counters: CanCounters,
}

impl CanDecoder {
    /// `n_channels` device channels at `sample_rate`; a channel more than `max_lag`
    /// samples behind the most advanced one is padded with NaN.
    pub fn new(base_id: u32, n_channels: usize, sample_rate: f64, max_lag: usize) -> Self {
        CanDecoder {
            base_id,
            sample_rate,
            max_lag: max_lag.max(1),
            chans: vec![Chan::default(); n_channels.min(MAX_CAN_CHANNELS)],
            emitted: None,
            edge_seq: None,
            edges: Vec::new(),
            counters: CanCounters::default(),
        }
    }

    pub fn counters(&self) -> &CanCounters {
        &self.counters
    }

    /// Unwrap a 24-bit stamp to the absolute index nearest `reference`.
    fn unwrap(stamp: u64, reference: u64) -> u64 {
        let here = (reference & !(STAMP_MOD - 1)) | (stamp & (STAMP_MOD - 1));
        [here.checked_sub(STAMP_MOD), here.checked_add(STAMP_MOD)]
            .into_iter()
            .flatten()
            .fold(here, |best, c| {
                if c.abs_diff(reference) < best.abs_diff(reference) {
                    c
                } else {
                    best
                }
            })
    }

    /// Gaps longer than this restart the clock instead of being filled with NaN.
    fn max_gap(&self) -> u64 {
        (self.max_lag as u64 * 4).max(self.sample_rate as u64 * 2)
    }

    /// Take one frame. Anything malformed is counted, never an error.
    pub fn push(&mut self, id: u32, data: &[u8]) {
        let Some(off) = id.checked_sub(self.base_id).filter(|&o| o <= ID_EDGES) else {
            self.counters.foreign += 1;
            return;
        };
        match off {
            ID_INFO => self.info(data),
            ID_EDGES => self.edge_frame(data),
            _ => self.samples(off - ID_SAMPLES, data),
        }
    }

    fn info(&mut self, d: &[u8]) {
        if d.len() < 8 || d[1] != FORMAT_I16 || d[0] as usize >= self.chans.len() {
            self.counters.bad_frames += 1;
            return;
        }
        let scale = f32::from_le_bytes([d[2], d[3], d[4], d[5]]);
        let rate = u16::from_le_bytes([d[6], d[7]]) as f64;
        if !(scale.is_finite() && scale != 0.0) || (rate - self.sample_rate).abs() > 0.5 {
            self.counters.bad_frames += 1;
            return;
        }
        self.counters.frames += 1;
        self.chans[d[0] as usize].scale = Some(scale);
    }

    fn edge_frame(&mut self, d: &[u8]) {
        if d.len() < 4 || d.len() < 4 + 4 * d[1] as usize {
            self.counters.bad_frames += 1;
            return;
        }
        self.counters.frames += 1;
        if self.edge_seq.is_some_and(|s| s != d[0]) {
            self.counters.sequence_gaps += 1;
        }
        self.edge_seq = Some(d[0].wrapping_add(1));
        let reference = self.clock_end();
        for k in 0..d[1] as usize {
            let q = u32::from_le_bytes(d[4 + 4 * k..8 + 4 * k].try_into().unwrap()) as u64;
            let whole = Self::unwrap(q >> 8, reference);
            self.edges.push(whole as f64 + (q & 0xFF) as f64 / 256.0);
        }
    }

    /// The furthest sample-clock index any channel has reached.
    fn clock_end(&self) -> u64 {
        let e = self.emitted.unwrap_or(0);
        e + self
            .chans
            .iter()
            .map(|c| c.buf.len() as u64)
            .max()
            .unwrap_or(0)
    }

    fn samples(&mut self, c: u32, d: &[u8]) {
        let c = c as usize;
        if c >= self.chans.len()
            || d.len() < SAMPLES_HEADER + 2
            || (d.len() - SAMPLES_HEADER) % 2 != 0
        {
            self.counters.bad_frames += 1;
            return;
        }
        self.counters.frames += 1;
        let ch = &mut self.chans[c];
        if ch.seq.is_some_and(|s| s != d[0]) {
            self.counters.sequence_gaps += 1;
        }
        ch.seq = Some(d[0].wrapping_add(1));
        let Some(scale) = ch.scale else {
            self.counters.unscaled += 1;
            return;
        };
        let stamp = u32::from_le_bytes([d[1], d[2], d[3], 0]) as u64;
        let emitted = *self.emitted.get_or_insert(stamp);
        let max_gap = self.max_gap();
        let end = emitted + self.chans[c].buf.len() as u64;
        let first = Self::unwrap(stamp, end);
        if first < end {
            // Already filled (NaN padding or a duplicate): too late.
            self.counters.late += 1;
            return;
        }
        let gap = first - end;
        if gap > max_gap {
            // The adapter restarted or the bus was away for long: start over at this frame.
            self.counters.clock_resets += 1;
            self.emitted = Some(first);
            self.chans.iter_mut().for_each(|c| c.buf.clear());
        } else if gap > 0 {
            let ch = &mut self.chans[c];
            ch.buf.resize(ch.buf.len() + gap as usize, f32::NAN);
            self.counters.samples_lost += gap;
        }
        let ch = &mut self.chans[c];
        ch.buf.extend(
            d[SAMPLES_HEADER..]
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]]) as f32 * scale),
        );
    }

    /// Everything all channels have (after padding channels that lag by more than
    /// `max_lag`), or `None`.
    pub fn take_aligned(&mut self) -> Option<Aligned> {
        let emitted = self.emitted?;
        let longest = self.chans.iter().map(|c| c.buf.len()).max().unwrap_or(0);
        for ch in &mut self.chans {
            if longest - ch.buf.len() > self.max_lag {
                let pad = longest - self.max_lag - ch.buf.len();
                ch.buf.resize(ch.buf.len() + pad, f32::NAN);
                self.counters.samples_lost += pad as u64;
            }
        }
        let n = self.chans.iter().map(|c| c.buf.len()).min().unwrap_or(0);
        let end = emitted as f64 + n as f64;
        // Nothing to hand out: no samples, and no edge that is already due (edges ahead of
        // the samples wait for them; returning an empty block here would spin the caller).
        if n == 0 && !self.edges.iter().any(|&e| e < end) {
            return None;
        }
        let (now, later): (Vec<f64>, Vec<f64>) = self.edges.drain(..).partition(|&e| e < end);
        self.edges = later;
        self.emitted = Some(emitted + n as u64);
        Some(Aligned {
            first_sample: emitted,
            channels: self
                .chans
                .iter_mut()
                .map(|c| c.buf.drain(..n).collect())
                .collect(),
            edges: now,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sig(c: usize, n: usize) -> Vec<f32> {
        (0..n)
            .map(|i| ((i * 7 + c * 13) % 200) as f32 * 0.01 - 1.0)
            .collect()
    }

    fn run(
        payload: usize,
        n: usize,
        drop: impl Fn(usize, u32) -> bool,
    ) -> (Vec<Aligned>, CanCounters, Vec<Vec<f32>>) {
        let scales = vec![0.01f32; 3];
        let mut enc = CanEncoder::new(0x100, payload, 10_000, scales);
        let data: Vec<Vec<f32>> = (0..3).map(|c| sig(c, n)).collect();
        let refs: Vec<&[f32]> = data.iter().map(Vec::as_slice).collect();
        let mut frames = enc.info();
        frames.extend(enc.samples(STAMP_MOD - 50, &refs)); // starts just before a stamp wrap
        frames.extend(enc.edges(&[STAMP_MOD as f64 - 40.5, STAMP_MOD as f64 + 3.25]));
        let mut dec = CanDecoder::new(0x100, 3, 10_000.0, 10_000);
        let mut out = Vec::new();
        for (k, (id, d)) in frames.iter().enumerate() {
            if !drop(k, *id) {
                dec.push(*id, d);
            }
            out.extend(dec.take_aligned());
        }
        (out, dec.counters().clone(), data)
    }

    fn joined(out: &[Aligned], c: usize) -> Vec<f32> {
        out.iter().flat_map(|a| a.channels[c].clone()).collect()
    }

    #[test]
    fn classic_and_fd_round_trip_across_a_stamp_wrap() {
        for payload in [8, 64] {
            let (out, counters, data) = run(payload, 300, |_, _| false);
            assert_eq!(out[0].first_sample, STAMP_MOD - 50, "payload {payload}");
            let mut next = out[0].first_sample;
            for a in &out {
                assert_eq!(a.first_sample, next);
                next += a.channels[0].len() as u64;
            }
            for c in 0..3 {
                let got = joined(&out, c);
                assert_eq!(got.len(), 300);
                for (g, w) in got.iter().zip(&data[c]) {
                    assert!((g - w).abs() <= 0.005 + 1e-6, "{g} vs {w}");
                }
            }
            let edges: Vec<f64> = out.iter().flat_map(|a| a.edges.clone()).collect();
            assert_eq!(
                edges,
                [STAMP_MOD as f64 - 40.5, STAMP_MOD as f64 + 3.25],
                "payload {payload}"
            );
            assert_eq!(
                (
                    counters.sequence_gaps,
                    counters.samples_lost,
                    counters.bad_frames
                ),
                (0, 0, 0)
            );
        }
    }

    #[test]
    fn a_lost_frame_becomes_nan_and_is_counted() {
        // FD: frames 3.. are samples; drop the 2nd SAMPLES frame of channel 1.
        let (out, c, data) = run(64, 300, |k, id| k == 3 + 3 + 1 && id == 0x102);
        let got = joined(&out, 1);
        assert_eq!(got.len(), 300);
        assert!(got[30..60].iter().all(|v| v.is_nan()));
        assert!((got[60] - data[1][60]).abs() < 0.006);
        assert_eq!((c.sequence_gaps, c.samples_lost), (1, 30));
    }

    #[test]
    fn malformed_foreign_and_unscaled_frames_are_counted_not_fatal() {
        let mut dec = CanDecoder::new(0x100, 2, 10_000.0, 100);
        dec.push(0x7FF, &[1, 2, 3]); // foreign
        dec.push(0x101, &[0, 0, 0, 0, 1, 0]); // no INFO yet
        dec.push(0x100, &[5, 1, 0, 0, 128, 63, 16, 39]); // channel 5 of 2
        dec.push(0x100, &[0, 1, 0, 0, 128, 63, 0x44, 0xAC]); // 44100 Hz, not 10000
        dec.push(0x101, &[0, 0, 0]); // too short
        dec.push(0x121, &[0, 9, 0, 0]); // 9 edges announced, none present
        let c = dec.counters();
        assert_eq!(
            (c.foreign, c.unscaled, c.bad_frames, c.frames),
            (1, 1, 4, 1)
        );
        assert!(dec.take_aligned().is_none());
    }

    #[test]
    fn a_silent_channel_is_padded_after_max_lag() {
        let mut enc = CanEncoder::new(0x100, 64, 10_000, vec![1.0, 1.0]);
        let mut dec = CanDecoder::new(0x100, 2, 10_000.0, 60);
        for (id, d) in enc.info() {
            dec.push(id, &d);
        }
        let x = vec![1.0f32; 150];
        for (id, d) in enc.samples(0, &[&x, &x]) {
            if id == 0x101 {
                dec.push(id, &d); // channel 1 never arrives
            }
        }
        let a = dec.take_aligned().unwrap();
        assert_eq!(a.channels[0].len(), 150 - 60);
        assert!(a.channels[1].iter().all(|v| v.is_nan()));
        assert_eq!(dec.counters().samples_lost, 90);
    }

    #[test]
    fn random_frames_never_panic() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut dec = CanDecoder::new(0x100, 4, 10_000.0, 1000);
        for _ in 0..20_000 {
            let len = rng.random_range(0..=64);
            let d: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            dec.push(rng.random_range(0x0F0..0x130), &d);
            let _ = dec.take_aligned();
        }
        assert!(dec.counters().bad_frames > 0);
    }
}
