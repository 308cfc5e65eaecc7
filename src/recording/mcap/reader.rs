//! Reading a rigmon MCAP file back into a [`Recording`], tolerant of damage: a file cut short
//! or corrupted yields every complete chunk whose CRC checks (with a provenance note), lost
//! blocks are zero-filled and noted, and damaged length fields give errors, not huge
//! allocations or panics.

use super::codec::{decode_block, decode_edges};
use super::layout::*;
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Largest record (or decompressed chunk) the reader accepts, bytes: a damaged length field
/// gives an error instead of a huge allocation (the reader allocates a chunk's declared
/// uncompressed size up front). Writers close chunks at 512 KiB; blocks are ~0.1 s.
const MAX_RECORD_BYTES: usize = 64 << 20;
/// Lost blocks are zero-filled, up to this many times the samples a stream really holds ...
const MAX_FILL_RATIO: u64 = 16;
/// ... plus this many samples.
const MAX_FILL_EXTRA: u64 = 1 << 20;

/// Read a rigmon MCAP file. A file cut short yields everything up to its last complete chunk
/// (with a provenance note).
pub fn read_recording(path: &Path) -> Result<Recording> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    read_recording_bytes(&bytes).with_context(|| format!("{}", path.display()))
}

struct Stream {
    blocks: Vec<(u64, Vec<f32>)>,
}

/// The `mcap` crate allocates a string's or map's declared length before reading it, so a
/// damaged length prefix could ask for gigabytes (found by fuzzing). Check every length prefix
/// of the records [`read_recording_bytes`] parses (Schema, Channel, Metadata) against the
/// record's own size first.
fn lengths_fit(opcode: u8, d: &[u8]) -> std::result::Result<(), String> {
    fn skip(d: &[u8], at: &mut usize, n: usize) -> bool {
        match at.checked_add(n) {
            Some(e) if e <= d.len() => {
                *at = e;
                true
            }
            _ => false,
        }
    }
    fn len(d: &[u8], at: &mut usize) -> Option<usize> {
        let b = d.get(*at..*at + 4)?;
        *at += 4;
        Some(u32::from_le_bytes(b.try_into().unwrap()) as usize)
    }
    fn string(d: &[u8], at: &mut usize) -> bool {
        len(d, at).is_some_and(|n| skip(d, at, n))
    }
    fn map(d: &[u8], at: &mut usize) -> bool {
        let Some(n) = len(d, at) else { return false };
        let end = match at.checked_add(n) {
            Some(e) if e <= d.len() => e,
            _ => return false,
        };
        while *at < end {
            if !(string(d, at) && string(d, at)) {
                return false;
            }
        }
        *at == end
    }
    let mut at = 0;
    use mcap::records::op;
    let ok = match opcode {
        // Schema: id, name, encoding, data.
        op::SCHEMA => {
            skip(d, &mut at, 2) && string(d, &mut at) && string(d, &mut at) && string(d, &mut at)
        }
        // Channel: id, schema id, topic, message encoding, metadata.
        op::CHANNEL => {
            skip(d, &mut at, 4) && string(d, &mut at) && string(d, &mut at) && map(d, &mut at)
        }
        // Metadata: name, metadata.
        op::METADATA => string(d, &mut at) && map(d, &mut at),
        _ => true,
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "record (opcode 0x{opcode:02x}, {} bytes) declares a field longer than itself",
            d.len()
        ))
    }
}

/// The offset of the first uncompressed chunk whose inner records overrun the chunk, with a
/// reason. `mcap` 0.26's reader panics on such a chunk (an unchecked subtraction, found by
/// fuzzing), so the bytes from there on are treated like a file cut short.
fn first_overrunning_chunk(bytes: &[u8]) -> Option<(usize, String)> {
    let u64_at = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(
            bytes.get(at..at.checked_add(8)?)?.try_into().unwrap(),
        ))
    };
    let u32_at = |at: usize| -> Option<u32> {
        Some(u32::from_le_bytes(
            bytes.get(at..at.checked_add(4)?)?.try_into().unwrap(),
        ))
    };
    let mut at = mcap::MAGIC.len();
    while at < bytes.len() {
        let op = bytes[at];
        let len = usize::try_from(u64_at(at + 1)?).ok()?;
        let body = at + 9;
        let end = body.checked_add(len)?;
        if end > bytes.len() {
            return None; // cut short: the reader reports it
        }
        if op == mcap::records::op::CHUNK {
            // start time, end time, uncompressed size, uncompressed crc, compression, records
            let c_len = u32_at(body + 28)? as usize;
            let recs_len_at = (body + 32).checked_add(c_len)?;
            let recs_len = usize::try_from(u64_at(recs_len_at)?).ok()?;
            let recs = recs_len_at + 8;
            if c_len == 0 && recs.checked_add(recs_len).is_some_and(|e| e <= end) {
                let mut r = 0usize;
                while r < recs_len {
                    let inner = u64_at(recs + r + 1).filter(|_| r + 9 <= recs_len);
                    match inner.and_then(|l| usize::try_from(l).ok()) {
                        Some(l) if l <= recs_len - r - 9 => r += 9 + l,
                        _ => {
                            return Some((
                                at,
                                format!(
                                    "chunk at byte {at}: a record inside overruns the chunk's \
                                     {recs_len} bytes"
                                ),
                            ))
                        }
                    }
                }
            }
        }
        at = end;
    }
    None
}

/// [`read_recording`] from bytes in memory.
pub fn read_recording_bytes(bytes: &[u8]) -> Result<Recording> {
    if bytes.is_empty() {
        bail!("the file is empty (0 bytes)");
    }
    if !bytes.starts_with(mcap::MAGIC) {
        bail!("not an MCAP file (no MCAP magic at the start)");
    }
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut topics: BTreeMap<u16, (String, u16)> = BTreeMap::new();
    let mut metadata: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    let mut streams: BTreeMap<String, Stream> = BTreeMap::new();
    let mut edges: Vec<f64> = Vec::new();
    let mut cut_short: Option<String> = None;
    let mut seen_footer = false;
    // The sans-io reader, with every chunk decompressed and its CRC checked before any of its
    // records is used: a chunk cut short (or damaged) contributes nothing.
    let mut reader = mcap::sans_io::LinearReader::new_with_options(
        mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    let mut rest = bytes;
    if let Some((at, why)) = first_overrunning_chunk(bytes) {
        cut_short = Some(why);
        rest = &bytes[..at];
    }
    while let Some(event) = reader.next_event() {
        let (opcode, data) = match event {
            Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                let len = need.min(rest.len());
                reader.insert(len).copy_from_slice(&rest[..len]);
                reader.notify_read(len);
                rest = &rest[len..];
                continue;
            }
            Ok(mcap::sans_io::LinearReadEvent::Record { opcode, data }) => (opcode, data),
            Err(e) => {
                cut_short.get_or_insert(e.to_string());
                break;
            }
        };
        // Only the records this reader uses are parsed (others cannot stop the read).
        use mcap::records::op;
        if !matches!(
            opcode,
            op::FOOTER | op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA
        ) {
            continue;
        }
        if let Err(e) = lengths_fit(opcode, data) {
            cut_short.get_or_insert(e);
            break;
        }
        let rec = match mcap::parse_record(opcode, data) {
            Ok(r) => r,
            Err(e) => {
                cut_short.get_or_insert(e.to_string());
                break;
            }
        };
        use mcap::records::Record;
        match rec {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                topics.insert(c.id, (c.topic, c.schema_id));
            }
            Record::Metadata(m) => {
                metadata.insert(m.name, m.metadata);
            }
            Record::Message { header, data } => {
                let Some((topic, schema_id)) = topics.get(&header.channel_id) else {
                    bail!("message on unknown channel id {}", header.channel_id);
                };
                let schema = schemas.get(schema_id).map(String::as_str).unwrap_or("");
                if schema == SAMPLE_BLOCK_SCHEMA {
                    let b = decode_block(&data).with_context(|| format!("topic {topic}"))?;
                    streams
                        .entry(topic.clone())
                        .or_insert_with(|| Stream { blocks: Vec::new() })
                        .blocks
                        .push((b.first_sample, b.samples));
                } else if schema == TACHO_EDGES_SCHEMA {
                    let (_, _, t) =
                        decode_edges(&data).with_context(|| format!("topic {topic}"))?;
                    edges.extend(t);
                }
            }
            Record::Footer(_) => seen_footer = true,
            _ => {}
        }
    }
    let Some(info) = metadata.get(RECORDING_METADATA) else {
        match cut_short {
            Some(e) => bail!(
                "truncated or damaged before the `{RECORDING_METADATA}` metadata record ({e})"
            ),
            None => bail!("not a rigmon recording: no `{RECORDING_METADATA}` metadata record"),
        }
    };
    let get = |k: &str| {
        info.get(k)
            .with_context(|| format!("`{RECORDING_METADATA}` record lacks `{k}`"))
    };
    let version = get("layout_version")?;
    if version != LAYOUT_VERSION {
        bail!("rigmon MCAP layout version {version} is not supported (this rigmon reads version {LAYOUT_VERSION})");
    }
    let sample_rate: f64 = get("sample_rate_hz")?.parse().context("sample_rate_hz")?;
    let start_time_ns: u64 = get("start_time_ns")?.parse().context("start_time_ns")?;
    let rpm = info
        .get("rpm")
        .map(|s| s.parse::<f64>())
        .transpose()
        .context("rpm")?;
    let infos: Vec<ChannelInfo> = serde_json::from_str(get("channels")?).context("channels")?;
    let mut provenance: Provenance =
        serde_json::from_str(get("provenance")?).context("provenance")?;
    let tacho_kind = info.get("tacho").map(String::as_str).unwrap_or("none");
    let labels = metadata.get(LABELS_METADATA).cloned().unwrap_or_default();
    if let Some(e) = &cut_short {
        provenance.notes.push(format!(
            "MCAP file cut short or damaged ({e}); read up to its last complete, intact chunk"
        ));
    } else if !seen_footer {
        provenance
            .notes
            .push("MCAP file has no footer (not finished); read all complete chunks".into());
    }

    // Assemble each stream on the sample clock; gaps are zero-filled.
    let mut assemble = |topic: &str, notes: &mut Vec<String>| -> Result<Vec<f32>> {
        let Some(mut s) = streams.remove(topic) else {
            return Ok(Vec::new());
        };
        s.blocks.sort_by_key(|b| b.0);
        let total = s
            .blocks
            .last()
            .map_or(0, |(f, v)| f.saturating_add(v.len() as u64));
        // Zero-filling is for lost blocks; a damaged first_sample must not make a tiny file
        // claim gigabytes (found by fuzzing).
        let present: u64 = s.blocks.iter().map(|(_, v)| v.len() as u64).sum();
        let fill_limit = present.saturating_mul(MAX_FILL_RATIO) + MAX_FILL_EXTRA;
        if total - present.min(total) > fill_limit {
            bail!(
                "{topic}: a block starts at sample {} but only {present} samples are recorded: \
                 filling the gap with zeros would exceed {fill_limit} samples; the file is damaged",
                s.blocks.last().map_or(0, |b| b.0)
            );
        }
        let mut out = Vec::with_capacity(total as usize);
        for (first, v) in s.blocks {
            let first = first as usize;
            if first < out.len() {
                bail!(
                    "{topic}: blocks overlap at sample {first} (already have {} samples)",
                    out.len()
                );
            }
            if first > out.len() {
                notes.push(format!(
                    "{topic}: {} samples missing before sample {first}, filled with zeros",
                    first - out.len()
                ));
                out.resize(first, 0.0);
            }
            out.extend_from_slice(&v);
        }
        Ok(out)
    };
    let mut notes = Vec::new();
    let mut channels = Vec::new();
    for c in &infos {
        let samples = assemble(&format!("{ACCEL_TOPIC_PREFIX}{}", c.name), &mut notes)?;
        channels.push(Channel {
            name: c.name.clone(),
            axis: c.axis.clone(),
            unit: c.unit.clone(),
            samples,
        });
    }
    let mut analog = if tacho_kind == "analog" {
        Some(assemble(TACHO_ANALOG_TOPIC, &mut notes)?)
    } else {
        None
    };
    // Equal lengths: a file cut short may end channels at different blocks.
    let mut n = channels.iter().map(|c| c.samples.len()).min().unwrap_or(0);
    if let Some(a) = &analog {
        n = n.min(a.len());
    }
    let longest = channels
        .iter()
        .map(|c| c.samples.len())
        .chain(analog.as_ref().map(Vec::len))
        .max()
        .unwrap_or(0);
    if longest != n {
        notes.push(format!(
            "channels end at different samples (shortest {n}, longest {longest}); all cut to {n}"
        ));
        channels.iter_mut().for_each(|c| c.samples.truncate(n));
        if let Some(a) = analog.as_mut() {
            a.truncate(n);
        }
    }
    if n == 0 {
        match cut_short {
            Some(e) => bail!("cut short before the first complete chunk of samples ({e})"),
            None => bail!("the recording holds no samples"),
        }
    }
    provenance.notes.extend(notes);
    let tacho = match tacho_kind {
        "analog" => Some(Tacho::Analog {
            samples: analog.unwrap_or_default(),
            unit: info.get("tacho_unit").cloned().unwrap_or_default(),
        }),
        "edges" => {
            edges.sort_by(f64::total_cmp);
            if cut_short.is_some() {
                let t_end = n as f64 / sample_rate;
                edges.retain(|&t| t < t_end);
            }
            Some(Tacho::Edges { times_s: edges })
        }
        _ => None,
    };
    Ok(Recording {
        sample_rate,
        start_time_ns,
        channels,
        tacho,
        rpm,
        nominal_rpm: None,
        provenance,
        metadata: labels,
    })
}
