//! [`SampleBlock`]: a block of consecutive samples on the sample clock, the unit every
//! source produces and the pipeline and the MCAP recorder consume.

/// A block of consecutive samples from a source, on the source's sample clock.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleBlock {
    /// Index of the first sample on the sample clock. A jump from the previous block's end
    /// means samples were lost (and the pipeline counts them).
    pub first_sample: u64,
    /// Sample rate, Hz.
    pub sample_rate: f64,
    /// One vector per acceleration channel, in rig channel order, all the same length.
    pub channels: Vec<Vec<f32>>,
    /// Analog tacho samples (same length as the channels) when the tacho is a voltage.
    pub tacho_analog: Option<Vec<f32>>,
    /// Tacho edge times in seconds on the sample clock (sample index / sample rate).
    pub tacho_edges: Vec<f64>,
}

impl SampleBlock {
    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
