//! The in-memory recording shared by importers, sources, the simulator, the feature pipeline
//! and the sinks: acceleration channels on one sample clock, the tacho (analog or edges),
//! a stored speed if the file has one, and provenance.
//!
//! The MCAP layout that stores a recording on disk is in [`mcap`]; a block of samples
//! as it streams from a source is a [`SampleBlock`] ([`block`]); what a reader could not
//! deliver from a damaged or cut file is a [`Losses`] report ([`losses`]); a recording made of
//! periodic captures says where each starts ([`captures`]).

pub mod block;
pub mod captures;
pub mod losses;
pub mod mcap;
pub mod stream;

pub use block::SampleBlock;
pub use losses::{LossReport, Losses};

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One acceleration channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Name from the rig file (e.g. "vertical", "DE").
    pub name: String,
    /// Axis from the rig file (axial, vertical, horizontal, radial...).
    pub axis: String,
    /// Engineering unit of `samples` (m/s^2, g).
    pub unit: String,
    /// Samples in `unit`, one per sample-clock tick.
    pub samples: Vec<f32>,
}

/// The speed reference of a recording.
#[derive(Debug, Clone, PartialEq)]
pub enum Tacho {
    /// An analog tacho voltage on the same sample clock as the channels.
    Analog { samples: Vec<f32>, unit: String },
    /// Edge (pulse) times in seconds since the first sample.
    Edges { times_s: Vec<f64> },
}

/// Where a recording came from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The file it was read from (as given by the user).
    pub source_path: String,
    /// Format name: "cwru-mat", "mfpt-mat", "wav", "csv", "mcap", "simulated", ...
    pub format: String,
    /// Free-form notes (e.g. "sample rate from CWRU catalog, file 105").
    #[serde(default)]
    pub notes: Vec<String>,
}

/// A nominal shaft speed declared for a recording, and where it was declared.
#[derive(Debug, Clone, PartialEq)]
pub struct NominalSpeed {
    pub rpm: f64,
    /// "labels.csv line 4, column rpm".
    pub declared_at: String,
}

/// A recording held in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Sample rate of every channel, Hz.
    pub sample_rate: f64,
    /// Time of the first sample, ns since the Unix epoch (0 when unknown).
    pub start_time_ns: u64,
    /// Acceleration channels (all the same length).
    pub channels: Vec<Channel>,
    /// The speed reference, if the recording has one.
    pub tacho: Option<Tacho>,
    /// A stored nominal speed (e.g. CWRU's `X<nnn>RPM`).
    pub rpm: Option<f64>,
    /// A nominal speed declared beside the file (a manifest's `rpm` column): a hint for the
    /// speed stage to check against the vibration, never used unchecked.
    pub nominal_rpm: Option<NominalSpeed>,
    pub provenance: Provenance,
    /// Free key/value metadata: labels (`label`, `fault`, `seed`...), rig id, config text.
    pub metadata: BTreeMap<String, String>,
}

impl Recording {
    /// True when rigmon's simulator produced it (also after a round trip through a file:
    /// its metadata keeps the scenario).
    pub fn is_simulated(&self) -> bool {
        self.provenance.format.contains("simulat")
            || self
                .metadata
                .keys()
                .any(|k| k.starts_with("sim") || k == "scenario")
            || self
                .metadata
                .get("source")
                .is_some_and(|s| s.contains("simulat"))
    }

    /// Number of samples per channel.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, |c| c.samples.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Duration in seconds.
    pub fn duration_s(&self) -> f64 {
        self.len() as f64 / self.sample_rate
    }

    /// A channel by name, or else by axis.
    pub fn channel(&self, name_or_axis: &str) -> Option<&Channel> {
        self.channels
            .iter()
            .find(|c| c.name == name_or_axis)
            .or_else(|| self.channels.iter().find(|c| c.axis == name_or_axis))
    }

    /// The label stored in metadata (`healthy`, `outer_race`, ...), if any.
    pub fn label(&self) -> Option<&str> {
        self.metadata.get("label").map(String::as_str)
    }
}
