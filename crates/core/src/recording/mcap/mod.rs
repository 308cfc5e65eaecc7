//! The rigmon MCAP layout: how a [`Recording`](super::Recording) is stored in an MCAP file.
//! (Owned by the importers; documented in the README.) In parts: the names and metadata
//! ([`layout`]), the payload codec ([`codec`]), the streaming writer ([`stream_writer`]), the
//! whole-recording writer ([`file_writer`]) and the tolerant reader ([`reader`]).
//!
//! Profile `rigmon`, zstd chunks. All message payloads are little-endian binary with message
//! encoding [`ENCODING`] (`rigmon-le`); each schema's data is a UTF-8 text copy of its layout
//! table, so a file documents itself.
//!
//! | topic | schema | one message = |
//! |---|---|---|
//! | `/accel/<channel name>` | `rigmon.SampleBlock` | a block of consecutive samples of one acceleration channel |
//! | `/tacho/analog` | `rigmon.SampleBlock` | a block of the analog tacho voltage, same clock as the channels |
//! | `/tacho/edges` | `rigmon.TachoEdges` | the tacho edge times delivered with one block |
//!
//! `rigmon.SampleBlock`: `u64 first_sample` (sample index since the recording start),
//! `f64 t0_s` (= first_sample / sample_rate_hz), `f64 sample_rate_hz`, `u32 n`,
//! `u16 unit_len`, `unit_len` bytes UTF-8 unit, then `n` x `f32` samples in that unit.
//!
//! `rigmon.TachoEdges`: `u64 first_sample` (of the block they came with), `f64 sample_rate_hz`,
//! `u32 n`, then `n` x `f64` edge times in seconds since the recording start.
//!
//! Two MCAP Metadata records, written before any chunk (so a file cut short keeps them):
//! `rigmon.recording` (layout_version, sample_rate_hz, start_time_ns, rpm, channels as JSON,
//! tacho kind and unit, provenance as JSON) and `rigmon.metadata` (the recording's metadata map
//! verbatim: `label`, ..., and `rig_id`/`rig_config` (rig TOML) when an importer set them).
//!
//! Message log/publish time = start_time_ns + first_sample / sample_rate_hz in ns.
//!
//! Writing keeps the file a complete MCAP after every chunk ([`durable_file`]): a writer killed
//! leaves a file every standard reader reads up to its last chunk. Reading tolerates a file
//! cut short or damaged ([`scan`], [`reader`]): a chunk whose CRC fails is skipped and reading
//! resumes at the next intact one; gaps on the sample clock are never filled with silence
//! (a jump of `first_sample` in the stream, NaN in a whole recording); what was lost is
//! reported ([`crate::recording::Losses`]). [`repair`] rewrites a damaged or unfinished file
//! as a clean, finished one.

pub(crate) mod assemble;
pub mod codec;
pub(crate) mod durable_file;
pub(crate) mod file_writer;
pub mod layout;
pub mod reader;
pub mod repair;
pub(crate) mod scan;
pub(crate) mod stream_writer;

pub use codec::{decode_block, decode_edges, DecodedBlock};
pub use durable_file::{McapFile, McapFileOptions};
pub use file_writer::write_recording;
pub use layout::*;
pub use reader::{
    read_recording, read_recording_bytes, read_recording_bytes_with_losses,
    read_recording_with_losses, RecordingReader,
};
pub use stream_writer::{RecordingWriter, WriterSettings};
