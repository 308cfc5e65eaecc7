//! A recording read block by block ([`BlockStream`]), so a file of any size is replayed or
//! converted with memory that does not grow with it: rigmon MCAP files
//! ([`RecordingReader`](super::mcap::RecordingReader)) and WAV files stream from disk, other
//! formats are read whole and handed out from memory ([`MemoryStream`]). Blocks carry the
//! stream's channels in [`RecordingInfo`] order; a jump of `first_sample` is a gap (samples
//! the file does not hold), reported in [`BlockStream::losses`].

use super::mcap::{RecordingInfo, RecordingReader};
use super::{Losses, Recording, SampleBlock, Tacho};
use anyhow::Result;
use std::io::{Read, Seek};

/// A recording read block by block.
pub trait BlockStream: Send {
    /// Everything about the recording but its samples.
    fn info(&self) -> &RecordingInfo;
    /// The length in seconds when known before reading (a WAV header, MCAP chunk headers).
    fn duration_hint_s(&self) -> Option<f64>;
    /// Samples per channel, when known exactly before reading.
    fn exact_len(&self) -> Option<u64> {
        None
    }
    /// The next block, `None` at the end. Its `first_sample` jumps where samples are missing.
    fn next_block(&mut self) -> Result<Option<SampleBlock>>;
    /// Start again from the first sample (a looping replay).
    fn rewind(&mut self) -> Result<()>;
    /// What could not be read so far (complete at the end of the first pass).
    fn losses(&self) -> Losses {
        Losses::default()
    }
    /// Provenance notes of the stream (the reader's, beyond `info().provenance`).
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }
}

/// A rigmon MCAP file streamed from disk.
pub struct McapStream<R> {
    reader: RecordingReader<R>,
    duration_s: Option<f64>,
}

impl<R: Read + Seek> McapStream<R> {
    pub fn new(mut reader: RecordingReader<R>) -> Result<Self> {
        // The chunk headers give the start of the last message; a block lasts about as long
        // as the first one.
        let last_start = reader.declared_duration_s()?;
        let first = reader.next_block()?;
        reader.rewind()?;
        let block_s = first.map_or(0.0, |b| b.len() as f64 / b.sample_rate);
        let duration_s = last_start.map(|s| s + block_s);
        Ok(McapStream { reader, duration_s })
    }

    /// The information, writable (overrides from the command line).
    pub fn info_mut(&mut self) -> &mut RecordingInfo {
        self.reader.info_mut()
    }
}

impl<R: Read + Seek + Send> BlockStream for McapStream<R> {
    fn info(&self) -> &RecordingInfo {
        self.reader.info()
    }
    fn duration_hint_s(&self) -> Option<f64> {
        self.duration_s
    }
    fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        let fs = self.reader.info().sample_rate;
        Ok(self.reader.next_block()?.map(|mut b| {
            // A sample-rate override (`--sample-rate`) applies to every block.
            b.sample_rate = fs;
            b
        }))
    }
    fn rewind(&mut self) -> Result<()> {
        self.reader.rewind()
    }
    fn losses(&self) -> Losses {
        self.reader.losses().clone()
    }
    fn notes(&self) -> Vec<String> {
        self.reader.notes()
    }
}

/// A recording held in memory, handed out in blocks of `block` samples.
pub struct MemoryStream {
    rec: Recording,
    info: RecordingInfo,
    block: usize,
    next: usize,
}

impl MemoryStream {
    pub fn new(rec: Recording, block: usize) -> Self {
        MemoryStream {
            info: RecordingInfo::of(&rec),
            rec,
            block: block.max(1),
            next: 0,
        }
    }

    /// The recording.
    pub fn recording(&self) -> &Recording {
        &self.rec
    }
}

/// Samples `[start, end)` of a recording as a block, with the tacho edges in their span
/// (`all_edges_at_end`: the last block also takes edges stored past the last sample).
pub fn block_of(rec: &Recording, start: usize, end: usize) -> SampleBlock {
    let fs = rec.sample_rate;
    let (tacho_analog, tacho_edges) = match &rec.tacho {
        Some(Tacho::Analog { samples, .. }) => (Some(samples[start..end].to_vec()), Vec::new()),
        Some(Tacho::Edges { times_s }) => {
            let (t0, t1) = (start as f64 / fs, end as f64 / fs);
            let lo = times_s.partition_point(|&t| t < t0);
            let hi = times_s.partition_point(|&t| t < t1);
            (None, times_s[lo..hi].to_vec())
        }
        None => (None, Vec::new()),
    };
    SampleBlock {
        first_sample: start as u64,
        sample_rate: fs,
        channels: rec
            .channels
            .iter()
            .map(|c| c.samples[start..end].to_vec())
            .collect(),
        tacho_analog,
        tacho_edges,
    }
}

impl BlockStream for MemoryStream {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
    fn duration_hint_s(&self) -> Option<f64> {
        Some(self.rec.duration_s())
    }
    fn exact_len(&self) -> Option<u64> {
        Some(self.rec.len() as u64)
    }
    fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        let n = self.rec.len();
        if self.next >= n {
            return Ok(None);
        }
        let end = (self.next + self.block).min(n);
        let b = block_of(&self.rec, self.next, end);
        self.next = end;
        Ok(Some(b))
    }
    fn rewind(&mut self) -> Result<()> {
        self.next = 0;
        Ok(())
    }
}
