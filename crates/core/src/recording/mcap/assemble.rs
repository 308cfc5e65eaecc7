//! Putting the per-topic sample blocks of a rigmon MCAP file back together on the sample
//! clock, as a stream ([`Assembler`]): the channels' (and the analog tacho's) runs of samples
//! are merged into [`SampleBlock`]s holding every channel; a stretch some channel lacks is a
//! gap for all of them ([`Out::Gap`]), never filled. Messages are expected in the order the
//! rigmon writer puts them (block by block); memory stays at a few blocks per topic.
//!
//! A block is handed out once a message of a later block has been read (so the tacho edges
//! written after its samples are in) or the file has ended.

use crate::recording::SampleBlock;
use std::collections::VecDeque;

/// What the assembler hands out next.
#[derive(Debug)]
pub enum Out {
    /// Samples every channel has, `[first_sample, first_sample + len)`.
    Block(SampleBlock),
    /// Samples missing on the sample clock (in at least one channel) before the next block.
    Gap { first: u64, samples: u64 },
    /// At the end: samples some channels have but not all (channels ending at different
    /// samples), dropped.
    Unmatched { samples: u64 },
}

/// The stream assembler.
#[derive(Debug)]
pub struct Assembler {
    fs: f64,
    /// Runs of samples per topic (channels in order, then the analog tacho): (first, samples).
    topics: Vec<VecDeque<(u64, Vec<f32>)>>,
    analog: bool,
    /// Tacho edge times (s since the recording start) not yet handed out.
    edges: VecDeque<f64>,
    /// Next sample to hand out.
    cursor: u64,
    /// The largest first sample of any message read (samples or edges).
    frontier: Option<u64>,
    /// The longest run seen (how far topics may lag each other in a well-formed file).
    max_run: u64,
    /// Samples overlapping ones already handed out, dropped.
    pub overlapped: u64,
}

impl Assembler {
    /// `channels` acceleration topics, plus one for the analog tacho when `analog`.
    pub fn new(fs: f64, channels: usize, analog: bool) -> Self {
        Assembler {
            fs,
            topics: (0..channels + usize::from(analog))
                .map(|_| VecDeque::new())
                .collect(),
            analog,
            edges: VecDeque::new(),
            cursor: 0,
            frontier: None,
            max_run: 0,
            overlapped: 0,
        }
    }

    fn saw(&mut self, first: u64) {
        self.frontier = Some(self.frontier.map_or(first, |f| f.max(first)));
    }

    /// The largest first sample of any message read so far.
    pub fn frontier(&self) -> Option<u64> {
        self.frontier
    }

    /// The longest run of samples seen (about a block).
    pub fn max_run(&self) -> u64 {
        self.max_run
    }

    /// A run of samples of topic `topic` (index as in [`Assembler::new`]).
    pub fn push(&mut self, topic: usize, first: u64, samples: Vec<f32>) {
        self.saw(first);
        if samples.is_empty() || topic >= self.topics.len() {
            return;
        }
        self.max_run = self.max_run.max(samples.len() as u64);
        self.topics[topic].push_back((first, samples));
    }

    /// Tacho edges (s since the recording start) that came with the block at `first`.
    pub fn push_edges(&mut self, first: u64, times: &[f64]) {
        self.saw(first);
        for &t in times {
            // Edges come in order; one out of order goes to its place.
            let at = self.edges.partition_point(|&e| e <= t);
            self.edges.insert(at, t);
        }
    }

    /// Edges left after the last block (a writer may store edges past the last sample).
    pub fn take_edges(&mut self) -> Vec<f64> {
        self.edges.drain(..).collect()
    }

    /// Drop what lies before the cursor.
    fn trim(&mut self) {
        let c = self.cursor;
        for q in &mut self.topics {
            while let Some((first, run)) = q.front_mut() {
                let end = *first + run.len() as u64;
                if end <= c {
                    self.overlapped += run.len() as u64;
                    q.pop_front();
                } else if *first < c {
                    let cut = (c - *first) as usize;
                    self.overlapped += cut as u64;
                    run.drain(..cut);
                    *first = c;
                    break;
                } else {
                    break;
                }
            }
        }
    }

    /// The next block or gap; `None` when more messages are needed (or, once `finished`,
    /// when everything has been handed out).
    pub fn pop(&mut self, finished: bool) -> Option<Out> {
        self.trim();
        let c = self.cursor;
        if self.topics.iter().any(VecDeque::is_empty) {
            let longest = self
                .topics
                .iter()
                .filter_map(|q| q.back().map(|(f, r)| f + r.len() as u64))
                .max()?;
            if finished {
                // Some channels end earlier than others: the rest cannot be matched.
                let samples = longest.saturating_sub(c);
                self.topics.iter_mut().for_each(VecDeque::clear);
                self.cursor = longest;
                return (samples > 0).then_some(Out::Unmatched { samples });
            }
            // A topic with nothing at the cursor while later blocks have been read lacks the
            // samples up to them (the writer puts a block's messages together).
            let frontier = self.frontier.unwrap_or(c);
            if frontier > c + 2 * self.max_run {
                self.cursor = frontier;
                self.trim();
                return Some(Out::Gap {
                    first: c,
                    samples: frontier - c,
                });
            }
            return None;
        }
        let start = self
            .topics
            .iter()
            .filter_map(|q| q.front())
            .map(|r| r.0)
            .max()?;
        if start > c {
            self.cursor = start;
            self.trim();
            return Some(Out::Gap {
                first: c,
                samples: start - c,
            });
        }
        let len = self
            .topics
            .iter()
            .filter_map(|q| q.front())
            .map(|(f, r)| f + r.len() as u64 - c)
            .min()?;
        if !finished && self.frontier.is_none_or(|f| f < c + len) {
            return None;
        }
        Some(Out::Block(self.take_block(len as usize)))
    }

    /// Take `len` samples from the front of every topic (all start at the cursor).
    fn take_block(&mut self, len: usize) -> SampleBlock {
        let c = self.cursor;
        let mut cols: Vec<Vec<f32>> = self
            .topics
            .iter_mut()
            .map(|q| {
                let (first, run) = q.front_mut().expect("every topic has a run at the cursor");
                if run.len() == len {
                    q.pop_front().map(|(_, r)| r).unwrap_or_default()
                } else {
                    let head: Vec<f32> = run.drain(..len).collect();
                    *first += len as u64;
                    head
                }
            })
            .collect();
        let tacho_analog = if self.analog { cols.pop() } else { None };
        let (t0, t1) = (c as f64 / self.fs, (c + len as u64) as f64 / self.fs);
        while self.edges.front().is_some_and(|&t| t < t0) {
            self.edges.pop_front();
        }
        let n = self.edges.partition_point(|&t| t < t1);
        let tacho_edges = self.edges.drain(..n).collect();
        self.cursor = c + len as u64;
        SampleBlock {
            first_sample: c,
            sample_rate: self.fs,
            channels: cols,
            tacho_analog,
            tacho_edges,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(first: u64, n: usize) -> Vec<f32> {
        (0..n).map(|i| (first + i as u64) as f32).collect()
    }

    /// Feed blocks of 100 samples on two topics (block-major, like the writer), `skip` lists
    /// blocks missing on topic 1 only, `absent` blocks missing on both.
    fn feed(a: &mut Assembler, blocks: u64, skip: &[u64], absent: &[u64]) -> Vec<Out> {
        let mut out = Vec::new();
        for k in 0..blocks {
            if !absent.contains(&k) {
                a.push(0, k * 100, run(k * 100, 100));
                if !skip.contains(&k) {
                    a.push(1, k * 100, run(k * 100, 100));
                }
                a.push_edges(k * 100, &[(k * 100 + 50) as f64 / 1000.0]);
            }
            while let Some(o) = a.pop(false) {
                out.push(o);
            }
        }
        while let Some(o) = a.pop(true) {
            out.push(o);
        }
        out
    }

    fn summary(out: &[Out]) -> Vec<(char, u64, u64)> {
        out.iter()
            .map(|o| match o {
                Out::Block(b) => ('b', b.first_sample, b.len() as u64),
                Out::Gap { first, samples } => ('g', *first, *samples),
                Out::Unmatched { samples } => ('u', 0, *samples),
            })
            .collect()
    }

    #[test]
    fn blocks_come_out_whole_with_their_edges() {
        let mut a = Assembler::new(1000.0, 2, false);
        let out = feed(&mut a, 4, &[], &[]);
        assert_eq!(
            summary(&out),
            [
                ('b', 0, 100),
                ('b', 100, 100),
                ('b', 200, 100),
                ('b', 300, 100)
            ]
        );
        let Out::Block(b) = &out[2] else { panic!() };
        assert_eq!(b.channels[1][7], 207.0);
        assert_eq!(b.tacho_edges, [0.25]);
    }

    #[test]
    fn missing_blocks_are_gaps_for_every_channel() {
        let mut a = Assembler::new(1000.0, 2, false);
        let out = feed(&mut a, 8, &[2], &[4, 5]);
        assert_eq!(
            summary(&out),
            [
                ('b', 0, 100),
                ('b', 100, 100),
                ('g', 200, 100),
                ('b', 300, 100),
                ('g', 400, 200),
                ('b', 600, 100),
                ('b', 700, 100)
            ]
        );
        // The edge of the block one channel lacks is dropped with it.
        let Out::Block(b) = &out[3] else { panic!() };
        assert_eq!(b.tacho_edges, [0.35]);
    }

    #[test]
    fn a_late_topic_and_unequal_ends() {
        let mut a = Assembler::new(1000.0, 2, true);
        // Topic 2 (analog tacho) comes in one run after the others.
        a.push(0, 0, run(0, 300));
        a.push(1, 0, run(0, 300));
        assert!(a.pop(false).is_none(), "waits for the tacho");
        a.push(2, 0, run(0, 250));
        let Some(Out::Block(b)) = a.pop(true) else {
            panic!()
        };
        assert_eq!((b.first_sample, b.len()), (0, 250));
        assert_eq!(b.tacho_analog.as_ref().unwrap()[249], 249.0);
        assert!(matches!(a.pop(true), Some(Out::Unmatched { samples: 50 })));
        assert!(a.pop(true).is_none());
    }
}
