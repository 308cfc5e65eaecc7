//! The names and descriptions of the rigmon MCAP layout: profile, encoding, schemas and
//! topics, the schema texts, and the `rigmon.recording` metadata record ([`RecordingInfo`]:
//! everything about a recording except its samples).

use crate::recording::{Provenance, Recording, Tacho};
use anyhow::Result;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// MCAP profile written in the header.
pub const PROFILE: &str = "rigmon";
/// Version of this layout (in `rigmon.recording`).
pub const LAYOUT_VERSION: &str = "1";
/// Message encoding and schema encoding of every rigmon channel.
pub const ENCODING: &str = "rigmon-le";
pub const SAMPLE_BLOCK_SCHEMA: &str = "rigmon.SampleBlock";
pub const TACHO_EDGES_SCHEMA: &str = "rigmon.TachoEdges";
pub const ACCEL_TOPIC_PREFIX: &str = "/accel/";
pub const TACHO_ANALOG_TOPIC: &str = "/tacho/analog";
pub const TACHO_EDGES_TOPIC: &str = "/tacho/edges";
/// Name of the metadata record describing the recording.
pub const RECORDING_METADATA: &str = "rigmon.recording";
/// Name of the metadata record holding the recording's key/value metadata (labels...).
pub const LABELS_METADATA: &str = "rigmon.metadata";

/// Schema data of `rigmon.SampleBlock` (a text copy of the layout).
pub const SAMPLE_BLOCK_LAYOUT: &str = "rigmon.SampleBlock (little-endian)\n\
offset      type        field\n\
0           u64         first_sample     index of the first sample since the recording start\n\
8           f64         t0_s             first_sample / sample_rate_hz, seconds\n\
16          f64         sample_rate_hz\n\
24          u32         n                number of samples\n\
28          u16         unit_len\n\
30          u8[unit_len] unit            UTF-8, e.g. m/s^2, g, V\n\
30+unit_len f32[n]      samples          in unit\n";

/// Schema data of `rigmon.TachoEdges`.
pub const TACHO_EDGES_LAYOUT: &str = "rigmon.TachoEdges (little-endian)\n\
offset  type    field\n\
0       u64     first_sample     first sample of the block these edges came with\n\
8       f64     sample_rate_hz\n\
16      u32     n                number of edges\n\
20      f64[n]  times_s          edge times, seconds since the recording start\n";

/// Name, axis and unit of one acceleration channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelInfo {
    pub name: String,
    #[serde(default)]
    pub axis: String,
    pub unit: String,
}

/// The kind of speed reference a stream carries.
#[derive(Debug, Clone, PartialEq)]
pub enum TachoInfo {
    None,
    /// Analog voltage in `unit`, on the sample clock.
    Analog {
        unit: String,
    },
    /// Edge times.
    Edges,
}

/// Everything about a recording except its samples: what the streaming writer needs up front.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingInfo {
    pub sample_rate: f64,
    pub start_time_ns: u64,
    pub channels: Vec<ChannelInfo>,
    pub tacho: TachoInfo,
    pub rpm: Option<f64>,
    pub provenance: Provenance,
    pub metadata: BTreeMap<String, String>,
}

impl RecordingInfo {
    /// The description of an in-memory recording.
    pub fn of(rec: &Recording) -> Self {
        RecordingInfo {
            sample_rate: rec.sample_rate,
            start_time_ns: rec.start_time_ns,
            channels: rec
                .channels
                .iter()
                .map(|c| ChannelInfo {
                    name: c.name.clone(),
                    axis: c.axis.clone(),
                    unit: c.unit.clone(),
                })
                .collect(),
            tacho: match &rec.tacho {
                None => TachoInfo::None,
                Some(Tacho::Analog { unit, .. }) => TachoInfo::Analog { unit: unit.clone() },
                Some(Tacho::Edges { .. }) => TachoInfo::Edges,
            },
            rpm: rec.rpm,
            provenance: rec.provenance.clone(),
            metadata: rec.metadata.clone(),
        }
    }
}

/// The `rigmon.recording` metadata record of a stream.
pub(super) fn recording_record(info: &RecordingInfo) -> Result<BTreeMap<String, String>> {
    let mut m = BTreeMap::new();
    m.insert("layout_version".into(), LAYOUT_VERSION.into());
    m.insert("sample_rate_hz".into(), info.sample_rate.to_string());
    m.insert("start_time_ns".into(), info.start_time_ns.to_string());
    if let Some(rpm) = info.rpm {
        m.insert("rpm".into(), rpm.to_string());
    }
    m.insert("channels".into(), serde_json::to_string(&info.channels)?);
    let (kind, unit) = match &info.tacho {
        TachoInfo::None => ("none", None),
        TachoInfo::Analog { unit } => ("analog", Some(unit.clone())),
        TachoInfo::Edges => ("edges", None),
    };
    m.insert("tacho".into(), kind.into());
    if let Some(u) = unit {
        m.insert("tacho_unit".into(), u);
    }
    m.insert(
        "provenance".into(),
        serde_json::to_string(&info.provenance)?,
    );
    Ok(m)
}
