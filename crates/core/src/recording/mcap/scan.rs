//! Walking an MCAP file record by record ([`Scanner`]), tolerant of damage and with bounded
//! memory: one record (at most [`MAX_RECORD_BYTES`]) is in memory at a time. A chunk is
//! decompressed and its CRC checked before any of its records is handed out; a chunk that
//! fails is skipped and reading resumes after it. A record whose length field cannot be right
//! (past the end of the file, over the limit) starts a search for the next intact chunk
//! header (its fields must agree with each other and its CRC must check); if none follows, the
//! file is cut short there. What was skipped comes out as [`Item::Damaged`] and
//! [`Item::Truncated`], with byte offsets and, where a chunk header is legible, the time span
//! it covered.
//!
//! The `mcap` crate's own readers stop at the first problem; this one only uses its record
//! parsers and, per chunk, its sans-io reader (decompression, CRC).

use crate::recording::losses::Damage;
use anyhow::{bail, Context, Result};
use std::collections::VecDeque;
use std::io::{Read, Seek, SeekFrom};

/// Largest record (or decompressed chunk) accepted, bytes: a damaged length field gives an
/// error instead of a huge allocation. rigmon closes chunks at 512 KiB - 1 MiB.
pub const MAX_RECORD_BYTES: usize = 64 << 20;

/// Bytes of the search window when looking for the next intact chunk after damage.
const SEARCH_WINDOW: usize = 1 << 20;

/// What the walk found next.
#[derive(Debug)]
pub enum Item {
    /// A record outside chunks, or from inside a chunk whose CRC checked: Schema, Channel,
    /// Message or Metadata (other records are not handed out). `at`: the byte offset of the
    /// record (or of the chunk holding it).
    Record { opcode: u8, data: Vec<u8>, at: u64 },
    /// A stretch that could not be read; the walk resumed after it. `span_ns`: the log-time
    /// span a damaged chunk's (legible) header declares.
    Damaged {
        damage: Damage,
        span_ns: Option<(u64, u64)>,
    },
    /// The file ends before its footer; nothing from `at` on is readable.
    Truncated {
        at: u64,
        what: String,
        /// Log-time span (ns) the chunk cut at `at` declares, when its header is legible.
        span_ns: Option<(u64, u64)>,
    },
    /// The footer: the end of the file's data. `summary`: it points to a summary section
    /// (a finished file); a footer without one is the provisional end an unfinished
    /// [`McapFile`](super::durable_file::McapFile) keeps after its last chunk.
    Footer { summary: bool },
}

/// A chunk header read from raw bytes, checked for consistency.
#[derive(Debug, Clone, Copy)]
pub struct ChunkHeaderInfo {
    /// Record length (after opcode and length).
    pub len: u64,
    pub start_ns: u64,
    pub end_ns: u64,
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(
        b.get(at..at.checked_add(8)?)?.try_into().ok()?,
    ))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        b.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}

/// The chunk header at the start of `b` (opcode, length, header fields), if its fields agree:
/// a known compression, a length equal to the header plus the compressed size, sizes within
/// the limit, start time not after end time. `room` is how many bytes the record may span.
pub fn chunk_header(b: &[u8], room: u64) -> Option<ChunkHeaderInfo> {
    if *b.first()? != mcap::records::op::CHUNK {
        return None;
    }
    let len = u64_at(b, 1)?;
    let start_ns = u64_at(b, 9)?;
    let end_ns = u64_at(b, 17)?;
    let uncompressed = u64_at(b, 25)?;
    let c_len = u32_at(b, 37)? as usize;
    let name = b.get(41..41 + c_len.min(8))?;
    let compressed = u64_at(b, 41 + c_len)?;
    let known = matches!(name, b"" | b"zstd" | b"lz4") && c_len <= 4;
    let ok = known
        && start_ns <= end_ns
        && uncompressed <= MAX_RECORD_BYTES as u64
        && len <= MAX_RECORD_BYTES as u64
        && len.checked_add(9).is_some_and(|e| e <= room)
        && Some(len) == compressed.checked_add(8 + 8 + 8 + 4 + 4 + c_len as u64 + 8);
    ok.then_some(ChunkHeaderInfo {
        len,
        start_ns,
        end_ns,
    })
}

/// The `mcap` crate allocates a string's or map's declared length before reading it, so a
/// damaged length prefix could ask for gigabytes (found by fuzzing). Check every length prefix
/// of the records parsed here (Schema, Channel, Metadata) against the record's own size first.
pub fn lengths_fit(opcode: u8, d: &[u8]) -> std::result::Result<(), String> {
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

/// An uncompressed chunk whose inner records overrun it: `mcap` 0.26's reader panics on such
/// a chunk (an unchecked subtraction, found by fuzzing), so it is refused first. `record` is
/// the whole chunk record (opcode, length, body).
fn overruns(record: &[u8]) -> bool {
    let body = 9;
    let Some(c_len) = u32_at(record, body + 28) else {
        return false;
    };
    let Some(recs_len_at) = (body + 32).checked_add(c_len as usize) else {
        return true;
    };
    let Some(recs_len) = u64_at(record, recs_len_at).and_then(|l| usize::try_from(l).ok()) else {
        return false;
    };
    let recs = recs_len_at + 8;
    if c_len != 0 || recs.checked_add(recs_len).is_none_or(|e| e > record.len()) {
        return false;
    }
    let mut r = 0usize;
    while r < recs_len {
        let inner = u64_at(record, recs + r + 1).filter(|_| r + 9 <= recs_len);
        match inner.and_then(|l| usize::try_from(l).ok()) {
            Some(l) if l <= recs_len - r - 9 => r += 9 + l,
            _ => return true,
        }
    }
    false
}

/// Decompress a whole chunk record and check its CRC; its Schema, Channel, Message and
/// Metadata records, or why it is damaged.
fn unpack_chunk(record: &[u8]) -> std::result::Result<Vec<(u8, Vec<u8>)>, String> {
    if overruns(record) {
        return Err("a record inside overruns the chunk".into());
    }
    let mut reader = mcap::sans_io::LinearReader::new_with_options(
        mcap::sans_io::LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    let mut rest = record;
    let mut out = Vec::new();
    while let Some(event) = reader.next_event() {
        match event {
            Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                let n = need.min(rest.len());
                reader.insert(n).copy_from_slice(&rest[..n]);
                reader.notify_read(n);
                rest = &rest[n..];
            }
            Ok(mcap::sans_io::LinearReadEvent::Record { opcode, data }) => {
                if is_used(opcode) {
                    out.push((opcode, data.to_vec()));
                }
            }
            Err(e) => return Err(e.to_string()),
        }
    }
    Ok(out)
}

/// The records handed out (everything else is indexes and summary bookkeeping).
fn is_used(opcode: u8) -> bool {
    use mcap::records::op;
    matches!(
        opcode,
        op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA
    )
}

/// The damage-tolerant walk over an MCAP file.
pub struct Scanner<R> {
    src: R,
    len: u64,
    at: u64,
    /// Records of the chunk being handed out, and the chunk's offset.
    pending: VecDeque<(u8, Vec<u8>)>,
    pending_at: u64,
    done: bool,
    buf: Vec<u8>,
}

impl<R: Read + Seek> Scanner<R> {
    /// Start after the magic; errors when the source is not an MCAP file.
    pub fn new(mut src: R) -> Result<Self> {
        let len = src.seek(SeekFrom::End(0))?;
        if len == 0 {
            bail!("the file is empty (0 bytes)");
        }
        let mut magic = [0u8; 8];
        src.seek(SeekFrom::Start(0))?;
        let n = read_up_to(&mut src, &mut magic)?;
        if &magic[..n] != mcap::MAGIC {
            bail!("not an MCAP file (no MCAP magic at the start)");
        }
        Ok(Scanner {
            src,
            len,
            at: mcap::MAGIC.len() as u64,
            pending: VecDeque::new(),
            pending_at: 0,
            done: false,
            buf: Vec::new(),
        })
    }

    /// The file's size, bytes.
    pub fn file_len(&self) -> u64 {
        self.len
    }

    /// Start over from the first record.
    pub fn rewind(&mut self) {
        self.at = mcap::MAGIC.len() as u64;
        self.pending.clear();
        self.done = false;
    }

    fn read_at(&mut self, at: u64, n: usize) -> Result<&[u8]> {
        self.buf.resize(n, 0);
        self.src.seek(SeekFrom::Start(at))?;
        let got = read_up_to(&mut self.src, &mut self.buf)?;
        self.buf.truncate(got);
        Ok(&self.buf)
    }

    /// The next item, `None` after the footer or the end of the file.
    pub fn next_item(&mut self) -> Result<Option<Item>> {
        loop {
            if let Some((opcode, data)) = self.pending.pop_front() {
                let at = self.pending_at;
                return Ok(Some(Item::Record { opcode, data, at }));
            }
            if self.done {
                return Ok(None);
            }
            if self.at >= self.len {
                self.done = true;
                return Ok(Some(Item::Truncated {
                    at: self.at,
                    what: "the file ends without a footer (its writer did not close it)".into(),
                    span_ns: None,
                }));
            }
            let at = self.at;
            let head = self.read_at(at, 9)?.to_vec();
            let fits = head.len() == 9
                && u64_at(&head, 1)
                    .is_some_and(|l| l <= MAX_RECORD_BYTES as u64 && at + 9 + l <= self.len);
            if !fits {
                return self.after_bad_length(at, &head).map(Some);
            }
            let opcode = head[0];
            let len = u64_at(&head, 1).unwrap_or(0) as usize;
            let end = at + 9 + len as u64;
            use mcap::records::op;
            match opcode {
                op::CHUNK => {
                    let record = self.read_at(at, 9 + len)?;
                    match unpack_chunk(record) {
                        Ok(records) => {
                            self.pending.extend(records);
                            self.pending_at = at;
                            self.at = end;
                        }
                        Err(why) => {
                            let span_ns = chunk_header(&self.buf, self.len - at)
                                .map(|h| (h.start_ns, h.end_ns));
                            let next = self.resume_after(at, end)?;
                            self.at = next;
                            return Ok(Some(Item::Damaged {
                                damage: Damage {
                                    at_byte: at,
                                    bytes: next - at,
                                    what: format!("chunk {why}"),
                                },
                                span_ns,
                            }));
                        }
                    }
                }
                // A footer closes the file: one anywhere else is damage.
                op::FOOTER if end + 8 == self.len && len == 20 => {
                    self.done = true;
                    self.at = end;
                    let body = self.read_at(at + 9, len)?;
                    let summary = u64_at(body, 0).is_some_and(|s| s != 0);
                    return Ok(Some(Item::Footer { summary }));
                }
                _ if is_used(opcode) => {
                    let data = self.read_at(at + 9, len)?.to_vec();
                    self.at = end;
                    return Ok(Some(Item::Record { opcode, data, at }));
                }
                _ if opcode == 0 || opcode == op::FOOTER || (0x10..0x80).contains(&opcode) => {
                    // Not an MCAP opcode: the record boundary is lost.
                    let next = self.search_from(at + 1)?;
                    return Ok(Some(self.skip_or_cut(at, next, "an unknown record opcode")));
                }
                _ => self.at = end,
            }
        }
    }

    /// A record at `at` whose length cannot be right: skip to the next intact chunk, or the
    /// file is cut short here.
    fn after_bad_length(&mut self, at: u64, head: &[u8]) -> Result<Item> {
        let next = self.search_from(at + 1)?;
        if next < self.len {
            return Ok(self.skip_or_cut(at, next, "a record length that runs past the file"));
        }
        self.done = true;
        let (what, span_ns) = self.describe_cut(at, head)?;
        Ok(Item::Truncated { at, what, span_ns })
    }

    fn skip_or_cut(&mut self, at: u64, next: u64, why: &str) -> Item {
        if next >= self.len {
            self.done = true;
            return Item::Truncated {
                at,
                what: format!("{why}, and no intact chunk after it"),
                span_ns: None,
            };
        }
        self.at = next;
        Item::Damaged {
            damage: Damage {
                at_byte: at,
                bytes: next - at,
                what: why.into(),
            },
            span_ns: None,
        }
    }

    /// What the file holds where it is cut: a chunk the writer never closed, a chunk cut
    /// short (with the time span its header declares), or another record.
    fn describe_cut(&mut self, at: u64, head: &[u8]) -> Result<(String, Option<(u64, u64)>)> {
        if head.len() < 9 {
            return Ok(("the file ends inside a record header".into(), None));
        }
        if head[0] != mcap::records::op::CHUNK {
            return Ok((
                format!("a record (opcode 0x{:02x}) cut short or damaged", head[0]),
                None,
            ));
        }
        if u64_at(head, 1) == Some(u64::MAX) {
            return Ok((
                "an unfinished chunk (its writer was stopped before closing it)".into(),
                None,
            ));
        }
        let b = self.read_at(at, 9 + 41 + 8)?.to_vec();
        // The header's own consistency, with the length checked against the length field
        // only (the record runs past the file).
        let legible = chunk_header(&b, u64::MAX);
        Ok(match legible {
            Some(h) => ("a chunk cut short".into(), Some((h.start_ns, h.end_ns))),
            None => ("a damaged chunk header".into(), None),
        })
    }

    /// After a damaged chunk ending at `end` (by its length field): resume at `end` when a
    /// record plausibly starts there, else search for the next intact chunk from `at + 1`.
    fn resume_after(&mut self, at: u64, end: u64) -> Result<u64> {
        if end >= self.len {
            return Ok(end);
        }
        let head = self.read_at(end, 9 + 41 + 8)?.to_vec();
        let plausible = match head.first() {
            Some(&op) if op == mcap::records::op::CHUNK => {
                chunk_header(&head, self.len - end).is_some()
            }
            Some(&op)
                if (mcap::records::op::HEADER..=mcap::records::op::DATA_END).contains(&op) =>
            {
                u64_at(&head, 1).is_some_and(|l| end + 9 + l <= self.len)
            }
            _ => false,
        };
        if plausible {
            Ok(end)
        } else {
            self.search_from(at + 1)
        }
    }

    /// The offset of the next intact chunk (consistent header, CRC checks) at or after
    /// `from`, or of a footer closing the file; the file's length when there is none.
    fn search_from(&mut self, from: u64) -> Result<u64> {
        let mut window = Vec::new();
        let mut base = from;
        while base < self.len {
            let n = SEARCH_WINDOW.min((self.len - base) as usize);
            window.resize(n + 64, 0);
            self.src.seek(SeekFrom::Start(base))?;
            let got = read_up_to(&mut self.src, &mut window)?;
            window.truncate(got);
            let scan_len = n.min(got);
            let mut i = 0;
            while i < scan_len {
                let Some(k) = window[i..scan_len]
                    .iter()
                    .position(|&b| b == mcap::records::op::CHUNK || b == mcap::records::op::FOOTER)
                else {
                    break;
                };
                let off = base + (i + k) as u64;
                if self.candidate(off, &window[i + k..])? {
                    return Ok(off);
                }
                i += k + 1;
            }
            base += n as u64;
        }
        Ok(self.len)
    }

    /// An intact chunk (or the footer closing the file) starts at `off`; `seen` holds the
    /// bytes from there that are already in memory.
    fn candidate(&mut self, off: u64, seen: &[u8]) -> Result<bool> {
        let room = self.len - off;
        let head = if seen.len() >= 9 + 41 + 8 {
            seen[..9 + 41 + 8].to_vec()
        } else {
            self.read_at(off, 9 + 41 + 8)?.to_vec()
        };
        if head.first() == Some(&mcap::records::op::FOOTER) {
            return Ok(room == 9 + 20 + 8 && u64_at(&head, 1) == Some(20));
        }
        let Some(h) = chunk_header(&head, room) else {
            return Ok(false);
        };
        let record = self.read_at(off, 9 + h.len as usize)?;
        Ok(unpack_chunk(record).is_ok())
    }

    /// The Schema and Channel records of the summary section, when the file ends with an
    /// intact footer that points to one (a finished file repeats every definition there, so
    /// messages stay readable when the chunk that first defined their channel is damaged).
    pub fn summary_definitions(&mut self) -> Result<Vec<(u8, Vec<u8>)>> {
        let footer_at = match self.len.checked_sub(9 + 20 + 8) {
            Some(a) if a >= 8 => a,
            _ => return Ok(Vec::new()),
        };
        let tail = self.read_at(footer_at, 9 + 20 + 8)?.to_vec();
        if tail.len() != 37
            || tail[0] != mcap::records::op::FOOTER
            || u64_at(&tail, 1) != Some(20)
            || &tail[29..] != mcap::MAGIC
        {
            return Ok(Vec::new());
        }
        let start = u64_at(&tail, 9).unwrap_or(0);
        if start < 8 || start >= footer_at || footer_at - start > MAX_RECORD_BYTES as u64 {
            return Ok(Vec::new());
        }
        let section = self.read_at(start, (footer_at - start) as usize)?.to_vec();
        let mut out = Vec::new();
        let mut at = 0usize;
        while at + 9 <= section.len() {
            let op = section[at];
            let Some(l) = u64_at(&section, at + 1).and_then(|l| usize::try_from(l).ok()) else {
                break;
            };
            let Some(body) = section.get(at + 9..(at + 9).saturating_add(l)) else {
                break;
            };
            if matches!(op, mcap::records::op::SCHEMA | mcap::records::op::CHANNEL) {
                out.push((op, body.to_vec()));
            }
            at += 9 + l;
        }
        Ok(out)
    }

    /// The log-time span (ns) of the intact chunk headers, read without decompressing: the
    /// length of a recording known before its samples are read. `None` when no chunk header
    /// is legible.
    pub fn time_span(&mut self) -> Result<Option<(u64, u64)>> {
        let mut at = mcap::MAGIC.len() as u64;
        let mut span: Option<(u64, u64)> = None;
        while at + 9 <= self.len {
            let head = self.read_at(at, 9 + 41 + 8)?.to_vec();
            let Some(len) = u64_at(&head, 1).filter(|&l| at + 9 + l <= self.len) else {
                break;
            };
            if head[0] == mcap::records::op::CHUNK {
                if let Some(h) = chunk_header(&head, self.len - at) {
                    span = Some(match span {
                        None => (h.start_ns, h.end_ns),
                        Some((a, b)) => (a.min(h.start_ns), b.max(h.end_ns)),
                    });
                }
            } else if head[0] == mcap::records::op::DATA_END {
                break;
            }
            at += 9 + len;
        }
        Ok(span)
    }
}

/// Read until `buf` is full or the source ends; the bytes read.
fn read_up_to(src: &mut impl Read, buf: &mut [u8]) -> Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match src.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e).context("reading"),
        }
    }
    Ok(got)
}
