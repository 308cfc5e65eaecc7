//! Gathers the small pieces live sources receive (serial frames, CAN frames, sound-card
//! callbacks) into [`SampleBlock`]s of about `block_ms`, cutting a block early wherever the
//! sample clock jumps so every block is contiguous.

use super::SampleBlock;

/// Builds contiguous [`SampleBlock`]s from pieces. Each finished block hands its buffers
/// downstream, so one allocation per channel per block (about ten a second), none per piece.
#[derive(Debug)]
pub struct BlockAssembler {
    sample_rate: f64,
    target: usize,
    analog_tacho: bool,
    first: Option<u64>,
    channels: Vec<Vec<f32>>,
    tacho: Vec<f32>,
    edges: Vec<f64>,
    ready: Vec<SampleBlock>,
}

impl BlockAssembler {
    /// `n_channels` acceleration channels, an analog tacho vector when `analog_tacho`, and
    /// blocks of at least `block_samples` samples (1 or more).
    pub fn new(
        sample_rate: f64,
        n_channels: usize,
        analog_tacho: bool,
        block_samples: usize,
    ) -> Self {
        let target = block_samples.max(1);
        BlockAssembler {
            sample_rate,
            target,
            analog_tacho,
            first: None,
            channels: (0..n_channels)
                .map(|_| Vec::with_capacity(target * 2))
                .collect(),
            tacho: Vec::new(),
            edges: Vec::new(),
            ready: Vec::new(),
        }
    }

    /// Samples per block for a block length in milliseconds.
    pub fn samples_for_ms(sample_rate: f64, block_ms: f64) -> usize {
        ((sample_rate * block_ms / 1000.0).round() as usize).max(1)
    }

    /// Samples waiting in the unfinished block.
    pub fn pending(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    /// Append a piece starting at `first_sample`: `channels[c][i]` per acceleration channel
    /// (all the same length), the analog tacho if the assembler carries one, and tacho edge
    /// times in seconds on the sample clock. A jump in the sample clock closes the pending
    /// block first. Finished blocks are collected by [`BlockAssembler::take_ready`].
    pub fn push<C: AsRef<[f32]>>(
        &mut self,
        first_sample: u64,
        channels: &[C],
        tacho: Option<&[f32]>,
        edges_s: &[f64],
    ) {
        let n = channels.first().map_or(0, |c| c.as_ref().len());
        if n == 0 {
            // Edges alone (e.g. a CAN tacho frame): they ride with the next block.
            self.edges.extend_from_slice(edges_s);
            return;
        }
        if let Some(f) = self.first {
            if f + self.pending() as u64 != first_sample {
                self.close();
            }
        }
        if self.first.is_none() {
            self.first = Some(first_sample);
        }
        for (c, dst) in self.channels.iter_mut().enumerate() {
            let src = channels.get(c).map_or(&[][..], |s| s.as_ref());
            let m = n.min(src.len());
            dst.extend_from_slice(&src[..m]);
            dst.resize(dst.len() + (n - m), f32::NAN);
        }
        if self.analog_tacho {
            let src = tacho.unwrap_or(&[]);
            let m = n.min(src.len());
            self.tacho.extend_from_slice(&src[..m]);
            self.tacho.resize(self.tacho.len() + (n - m), f32::NAN);
        }
        self.edges.extend_from_slice(edges_s);
        if self.pending() >= self.target {
            self.close();
        }
    }

    /// Close the pending block (end of stream, or before a known gap).
    pub fn close(&mut self) {
        let Some(first) = self.first.take() else {
            return;
        };
        let len = self.pending();
        let block = SampleBlock {
            first_sample: first,
            sample_rate: self.sample_rate,
            channels: self
                .channels
                .iter_mut()
                .map(|c| std::mem::replace(c, Vec::with_capacity(len)))
                .collect(),
            tacho_analog: self
                .analog_tacho
                .then(|| std::mem::replace(&mut self.tacho, Vec::with_capacity(len))),
            tacho_edges: std::mem::take(&mut self.edges),
        };
        self.ready.push(block);
    }

    /// Blocks finished since the last call, oldest first.
    pub fn take_ready(&mut self) -> std::vec::Drain<'_, SampleBlock> {
        self.ready.drain(..)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contiguous_pieces_make_blocks_of_the_target_length() {
        let mut a = BlockAssembler::new(1000.0, 2, true, 10);
        let mut got = Vec::new();
        for k in 0..7u64 {
            let c0: Vec<f32> = (0..4).map(|i| (k * 4 + i) as f32).collect();
            let c1: Vec<f32> = c0.iter().map(|v| -v).collect();
            a.push(k * 4, &[c0.clone(), c1], Some(&c0), &[k as f64]);
            got.extend(a.take_ready());
        }
        a.close();
        got.extend(a.take_ready());
        assert_eq!(got.iter().map(|b| b.len()).collect::<Vec<_>>(), [12, 12, 4]);
        assert_eq!(got[1].first_sample, 12);
        assert_eq!(got[1].channels[1][0], -12.0);
        assert_eq!(got[1].tacho_analog.as_ref().unwrap()[3], 15.0);
        assert_eq!(got[0].tacho_edges, [0.0, 1.0, 2.0]);
    }

    #[test]
    fn a_clock_jump_closes_the_block() {
        let mut a = BlockAssembler::new(1000.0, 1, false, 100);
        a.push(0, &[vec![1.0f32; 5]], None, &[]);
        a.push(50, &[vec![2.0f32; 5]], None, &[]);
        a.close();
        let got: Vec<_> = a.take_ready().collect();
        assert_eq!(got.len(), 2);
        assert_eq!((got[0].first_sample, got[0].len()), (0, 5));
        assert_eq!((got[1].first_sample, got[1].len()), (50, 5));
        assert!(got[0].tacho_analog.is_none());
    }
}
