//! `rigmon repair`: rewrite a damaged, cut or unfinished MCAP file (any layout) as a clean,
//! finished one ([`repair`]): every intact record is copied in order (schemas and channels
//! under their ids, messages, metadata), damaged chunks are skipped ([`Scanner`]), and the new
//! file gets its summary, chunk indexes and footer, so every MCAP reader (indexed or linear,
//! in any language) reads it. Attachments are not copied. Memory stays at one chunk.

use super::durable_file::{McapFile, McapFileOptions};
use super::scan::{lengths_fit, Item, Scanner};
use crate::recording::losses::Damage;
use anyhow::{Context, Result};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// What [`repair`] did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RepairReport {
    /// Messages copied per topic.
    pub messages: BTreeMap<String, u64>,
    /// Messages whose channel definition was lost (in a damaged chunk), not copied.
    pub orphan_messages: u64,
    pub metadata_records: u64,
    /// Stretches of the input skipped.
    pub damaged: Vec<Damage>,
    /// Where the input was cut (byte, what is there), when it was.
    pub cut_at: Option<(u64, String)>,
    /// The input ended with a footer without a summary (its writer had not finished it).
    pub unfinished: bool,
    /// Sizes in and out, bytes.
    pub bytes_in: u64,
    pub bytes_out: u64,
}

impl RepairReport {
    /// One line for the terminal.
    pub fn line(&self) -> String {
        let total: u64 = self.messages.values().sum();
        let mut s = format!(
            "{total} messages on {} topics and {} metadata records copied ({} -> {} bytes)",
            self.messages.len(),
            self.metadata_records,
            self.bytes_in,
            self.bytes_out
        );
        if !self.damaged.is_empty() {
            let bytes: u64 = self.damaged.iter().map(|d| d.bytes).sum();
            s.push_str(&format!(
                "; {} damaged stretch(es), {bytes} bytes, skipped (first at byte {}: {})",
                self.damaged.len(),
                self.damaged[0].at_byte,
                self.damaged[0].what
            ));
        }
        if let Some((at, what)) = &self.cut_at {
            s.push_str(&format!("; the input is cut at byte {at} ({what})"));
        }
        if self.unfinished {
            s.push_str("; the input had no summary (its writer had not finished it)");
        }
        if self.orphan_messages > 0 {
            s.push_str(&format!(
                "; {} messages on channels whose definition was lost not copied",
                self.orphan_messages
            ));
        }
        s
    }
}

/// Copy every intact record of `input` into a new, finished MCAP file `output`.
pub fn repair(input: &Path, output: &Path) -> Result<RepairReport> {
    let f =
        std::fs::File::open(input).with_context(|| format!("{}: cannot read", input.display()))?;
    let mut scan = Scanner::new(f).with_context(|| format!("{}", input.display()))?;
    let mut report = RepairReport {
        bytes_in: scan.file_len(),
        ..Default::default()
    };
    let profile = header_profile(input).unwrap_or_default();
    let mut out = McapFile::create(
        output,
        &McapFileOptions {
            chunk_size: 1 << 20,
            zstd_level: 3,
            profile,
        },
    )?;
    let mut defs = Definitions::default();
    // A finished file repeats its definitions in the summary: used when the chunk that first
    // defined a channel is damaged (written when a message needs them, so the metadata
    // records still come first in the copy).
    let spare = Definitions::spare(scan.summary_definitions()?);
    while let Some(item) = scan.next_item()? {
        use mcap::records::op;
        match item {
            Item::Record { opcode, data, .. } => match opcode {
                op::SCHEMA | op::CHANNEL => defs.define(&mut out, opcode, &data)?,
                op::METADATA if lengths_fit(opcode, &data).is_ok() => {
                    if let Ok(mcap::records::Record::Metadata(m)) =
                        mcap::parse_record(opcode, &data)
                    {
                        out.write_metadata(&m)?;
                        report.metadata_records += 1;
                    }
                }
                op::MESSAGE => {
                    let Ok(mcap::records::Record::Message { header, data }) =
                        mcap::parse_record(opcode, &data)
                    else {
                        continue;
                    };
                    if !defs.channels.contains_key(&header.channel_id) {
                        spare.lend(header.channel_id, &mut defs, &mut out)?;
                    }
                    match defs.channels.get(&header.channel_id) {
                        Some(topic) => {
                            out.write(&header, &data)?;
                            *report.messages.entry(topic.clone()).or_default() += 1;
                        }
                        None => report.orphan_messages += 1,
                    }
                }
                _ => {}
            },
            Item::Damaged { damage, .. } => report.damaged.push(damage),
            Item::Truncated { at, what, .. } => {
                if at < report.bytes_in {
                    report.cut_at = Some((at, what));
                } else {
                    report.unfinished = true;
                }
            }
            Item::Footer { summary } => report.unfinished = !summary,
        }
    }
    report.bytes_out = out.finish()?;
    Ok(report)
}

/// The schemas and channels copied so far.
#[derive(Default)]
struct Definitions {
    schemas: BTreeSet<u16>,
    channels: BTreeMap<u16, String>,
}

/// The summary's Schema and Channel records, by id.
struct Spare {
    schemas: BTreeMap<u16, Vec<u8>>,
    channels: BTreeMap<u16, (u16, Vec<u8>)>,
}

impl Definitions {
    fn spare(records: Vec<(u8, Vec<u8>)>) -> Spare {
        let mut s = Spare {
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
        };
        for (op, data) in records {
            if lengths_fit(op, &data).is_err() {
                continue;
            }
            match mcap::parse_record(op, &data) {
                Ok(mcap::records::Record::Schema { header, .. }) => {
                    s.schemas.insert(header.id, data.clone());
                }
                Ok(mcap::records::Record::Channel(c)) => {
                    s.channels.insert(c.id, (c.schema_id, data.clone()));
                }
                _ => {}
            }
        }
        s
    }

    /// Copy a Schema or Channel record (once per id; a channel only once its schema is known).
    fn define(&mut self, out: &mut McapFile, opcode: u8, data: &[u8]) -> Result<()> {
        if lengths_fit(opcode, data).is_err() {
            return Ok(());
        }
        match mcap::parse_record(opcode, data) {
            Ok(mcap::records::Record::Schema { header, data })
                if header.id != 0 && self.schemas.insert(header.id) =>
            {
                out.add_schema_with_id(header.id, &header.name, &header.encoding, &data)?;
            }
            Ok(mcap::records::Record::Channel(c)) => {
                let known = c.schema_id == 0 || self.schemas.contains(&c.schema_id);
                if known && !self.channels.contains_key(&c.id) {
                    out.add_channel_with_id(
                        c.id,
                        c.schema_id,
                        &c.topic,
                        &c.message_encoding,
                        &c.metadata,
                    )?;
                    self.channels.insert(c.id, c.topic);
                }
            }
            _ => {}
        }
        Ok(())
    }
}

impl Spare {
    /// Define channel `id` (and its schema) in `out` from the summary, when it has them.
    fn lend(&self, id: u16, defs: &mut Definitions, out: &mut McapFile) -> Result<()> {
        let Some((schema, channel)) = self.channels.get(&id) else {
            return Ok(());
        };
        if let Some(s) = self.schemas.get(schema) {
            defs.define(out, mcap::records::op::SCHEMA, s)?;
        }
        defs.define(out, mcap::records::op::CHANNEL, channel)
    }
}

/// The profile in the input's header record, when it is legible.
fn header_profile(input: &Path) -> Option<String> {
    use std::io::Read;
    let mut head = Vec::new();
    std::fs::File::open(input)
        .ok()?
        .take(4096)
        .read_to_end(&mut head)
        .ok()?;
    let rec = head.get(8..)?;
    if *rec.first()? != mcap::records::op::HEADER {
        return None;
    }
    let len = u64::from_le_bytes(rec.get(1..9)?.try_into().ok()?) as usize;
    match mcap::parse_record(mcap::records::op::HEADER, rec.get(9..9 + len)?) {
        Ok(mcap::records::Record::Header(h)) => Some(h.profile),
        _ => None,
    }
}
