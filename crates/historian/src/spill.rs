//! The spill: messages the memory buffer has no room for, appended to segment files
//! (`spill-0000000001.seg`, 16 MiB each) in the spill folder and read back in order once the
//! database keeps up again. A segment is deleted only after everything in it was committed,
//! so what is spilled survives a historian restart or crash.
//! Record: the marker `RSP2`, the body's length (`u32` LE) and CRC-32 (`u32` LE), then the
//! body: kind (1 byte; its high bit set for a recovered message), key length (`u16` LE),
//! key, payload. A damaged record (a torn tail, a
//! flipped length, bad bytes) is skipped up to the next marker that starts a record whose
//! CRC holds, so one bad length loses one message, not the rest of the segment; each damaged
//! stretch is counted with its bytes ([`Spill::damage`], the historian status). Segments of
//! the earlier format (no marker: length, kind, key length, key, payload) are still read; in
//! them damage ends the segment, counted the same way.

use super::incoming::{Incoming, Kind};
use anyhow::{bail, Context, Result};
use crc::{Crc, CRC_32_ISO_HDLC};
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

const SEGMENT_BYTES: u64 = 16 * 1024 * 1024;
/// Larger records are damage, not messages.
const MAX_RECORD: u32 = 64 * 1024 * 1024;
/// What starts a record.
const MARKER: [u8; 4] = *b"RSP2";
/// Marker, length, CRC.
const HEADER: u64 = 12;
/// Bytes of a segment read at once when reading it back.
const CHUNK: u64 = 4 * 1024 * 1024;
const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
/// The kind byte's flag of a message fetched from a daemon's recent history (not live): kept
/// through the spill so that the gap tracker and the live latency never take it for live.
const RECOVERED: u8 = 0x80;

/// Where reading stands: segment number and byte offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cursor {
    pub segment: u64,
    pub offset: u64,
}

/// The spill folder.
pub struct Spill {
    dir: PathBuf,
    /// Segments on disk, oldest first, with their sizes.
    segments: Vec<(u64, u64)>,
    writer: Option<File>,
    read: Cursor,
    /// Records written and not yet committed.
    records: u64,
    /// Damaged stretches seen: (segment, offset) -> bytes skipped.
    damaged: RefCell<BTreeMap<(u64, u64), u64>>,
}

fn segment_path(dir: &Path, n: u64) -> PathBuf {
    dir.join(format!("spill-{n:010}.seg"))
}

impl Spill {
    /// Open (and create) the folder; segments left by an earlier run are read back first.
    pub fn open(dir: &Path) -> Result<Spill> {
        std::fs::create_dir_all(dir).with_context(|| {
            format!(
                "cannot create the spill folder {} ([buffer] spill_dir)",
                dir.display()
            )
        })?;
        let probe = dir.join(".write-test");
        std::fs::write(&probe, b"")
            .with_context(|| format!("the spill folder {} is not writable", dir.display()))?;
        let _ = std::fs::remove_file(probe);
        let mut segments = Vec::new();
        for e in std::fs::read_dir(dir)? {
            let e = e?;
            let name = e.file_name().to_string_lossy().into_owned();
            if let Some(n) = name
                .strip_prefix("spill-")
                .and_then(|s| s.strip_suffix(".seg"))
                .and_then(|s| s.parse::<u64>().ok())
            {
                segments.push((n, e.metadata()?.len()));
            }
        }
        segments.sort();
        let read = Cursor {
            segment: segments.first().map_or(1, |s| s.0),
            offset: 0,
        };
        let mut spill = Spill {
            dir: dir.to_path_buf(),
            segments,
            writer: None,
            read,
            records: 0,
            damaged: RefCell::default(),
        };
        spill.records = spill.count_records()?;
        Ok(spill)
    }

    fn count_records(&self) -> Result<u64> {
        let mut n = 0;
        for &(seg, _) in &self.segments {
            let mut c = Cursor {
                segment: seg,
                offset: 0,
            };
            while let Some((_, next)) = self.read_one(c)? {
                n += 1;
                c = next;
            }
        }
        Ok(n)
    }

    /// Bytes on disk not yet committed.
    pub fn bytes(&self) -> u64 {
        let total: u64 = self.segments.iter().map(|s| s.1).sum();
        total.saturating_sub(self.read.offset)
    }

    /// Records not yet committed.
    pub fn records(&self) -> u64 {
        self.records
    }

    pub fn is_empty(&self) -> bool {
        self.records == 0
    }

    /// Damaged stretches skipped so far (each lost at least one message) and their bytes.
    pub fn damage(&self) -> (u64, u64) {
        let d = self.damaged.borrow();
        (d.len() as u64, d.values().sum())
    }

    /// Append one message.
    pub fn append(&mut self, m: &Incoming) -> Result<()> {
        let key = m.key.as_bytes();
        if key.len() > u16::MAX as usize {
            bail!("key too long to spill");
        }
        let len = 1 + 2 + key.len() + m.payload.len();
        if len > MAX_RECORD as usize {
            bail!("a message of {len} bytes is too large to spill");
        }
        let mut rec = Vec::with_capacity(HEADER as usize + len);
        rec.extend_from_slice(&MARKER);
        rec.extend_from_slice(&(len as u32).to_le_bytes());
        rec.extend_from_slice(&[0; 4]);
        rec.push(m.kind as u8 | if m.recovered { RECOVERED } else { 0 });
        rec.extend_from_slice(&(key.len() as u16).to_le_bytes());
        rec.extend_from_slice(key);
        rec.extend_from_slice(&m.payload);
        let crc = CRC32.checksum(&rec[HEADER as usize..]);
        rec[8..12].copy_from_slice(&crc.to_le_bytes());
        let need_new = match self.segments.last() {
            None => true,
            Some(&(_, size)) => size + rec.len() as u64 > SEGMENT_BYTES || self.writer.is_none(),
        };
        if need_new {
            let n = self.segments.last().map_or(self.read.segment, |s| s.0 + 1);
            let f = OpenOptions::new()
                .create(true)
                .append(true)
                .open(segment_path(&self.dir, n))
                .with_context(|| {
                    format!("cannot create a spill segment in {}", self.dir.display())
                })?;
            self.writer = Some(f);
            self.segments.push((n, 0));
        }
        let w = self.writer.as_mut().expect("segment open");
        w.write_all(&rec).context("writing to the spill")?;
        if let Some(last) = self.segments.last_mut() {
            last.1 += rec.len() as u64;
        }
        self.records += 1;
        Ok(())
    }

    /// Read one record at `c` or after it (damage skipped and noted); None at the end.
    fn read_one(&self, mut c: Cursor) -> Result<Option<(Incoming, Cursor)>> {
        loop {
            let Some(&(_, size)) = self.segments.iter().find(|s| s.0 == c.segment) else {
                return Ok(None);
            };
            let (found, skipped) = if c.offset < size {
                self.record_in(c, size)?
            } else {
                (None, 0)
            };
            if skipped > 0 {
                self.note_damage(c, skipped, found.is_some());
            }
            match found {
                Some((m, used)) => {
                    let next = Cursor {
                        segment: c.segment,
                        offset: c.offset + skipped + used,
                    };
                    return Ok(Some((m, next)));
                }
                None => match self.next_segment(c.segment) {
                    Some(n) => {
                        c = Cursor {
                            segment: n,
                            offset: 0,
                        }
                    }
                    None => return Ok(None),
                },
            }
        }
    }

    /// The first intact record of segment `c.segment` at or after `c.offset`, with the bytes
    /// it used, and the damaged bytes skipped before it.
    fn record_in(&self, c: Cursor, size: u64) -> Result<(Option<(Incoming, u64)>, u64)> {
        let mut f = File::open(segment_path(&self.dir, c.segment))?;
        let first = read_at(&mut f, 0, 4, size)?;
        if first.len() == 4 && first[..] != MARKER {
            // The earlier format: no marker to resync on.
            let len = read_at(&mut f, c.offset, 4, size)?;
            let n = len
                .get(..4)
                .map_or(0, |l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]));
            let rec = read_at(&mut f, c.offset, 4 + u64::from(n.min(MAX_RECORD)), size)?;
            return Ok(match legacy_record(&rec) {
                Some(r) => (Some(r), 0),
                None => (None, size - c.offset),
            });
        }
        let head = read_at(&mut f, c.offset, HEADER, size)?;
        if head.len() == HEADER as usize && head[..4] == MARKER {
            let len = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
            let rec = read_at(
                &mut f,
                c.offset,
                HEADER + u64::from(len.min(MAX_RECORD)),
                size,
            )?;
            if let Some(r) = record_at(&rec) {
                return Ok((Some(r), 0));
            }
        }
        let rest = read_at(&mut f, c.offset, size - c.offset, size)?;
        Ok(next_record(&rest))
    }

    fn note_damage(&self, c: Cursor, skipped: u64, resynced: bool) {
        let mut d = self.damaged.borrow_mut();
        if d.insert((c.segment, c.offset), skipped).is_none() {
            tracing::warn!(
                "spill segment {} is damaged at byte {}: {skipped} bytes skipped (at least one message lost){}",
                c.segment,
                c.offset,
                if resynced {
                    "; reading on from the next intact record"
                } else {
                    ""
                }
            );
        }
    }

    fn next_segment(&self, n: u64) -> Option<u64> {
        self.segments.iter().map(|s| s.0).find(|&s| s > n)
    }
}

/// Up to `n` bytes of a segment of `size` bytes from `offset`.
fn read_at(f: &mut File, offset: u64, n: u64, size: u64) -> Result<Vec<u8>> {
    let n = n.min(size.saturating_sub(offset));
    f.seek(SeekFrom::Start(offset))?;
    let mut b = Vec::with_capacity(n as usize);
    Read::take(&mut *f, n).read_to_end(&mut b)?;
    Ok(b)
}

/// A record body as a message.
fn message(body: &[u8]) -> Option<Incoming> {
    let kind_byte = *body.first()?;
    let kind = Kind::from_u8(kind_byte & !RECOVERED);
    let klen = u16::from_le_bytes([*body.get(1)?, *body.get(2)?]) as usize;
    let key = std::str::from_utf8(body.get(3..3 + klen)?)
        .ok()?
        .to_string();
    Some(Incoming {
        kind,
        key,
        payload: body[3 + klen..].to_vec(),
        recovered: kind_byte & RECOVERED != 0,
    })
}

/// The record at the start of `b`, if intact: the message and the bytes it used.
fn record_at(b: &[u8]) -> Option<(Incoming, u64)> {
    if b.len() < HEADER as usize || b[..4] != MARKER {
        return None;
    }
    let len = u32::from_le_bytes(b[4..8].try_into().ok()?);
    let crc = u32::from_le_bytes(b[8..12].try_into().ok()?);
    if !(3..=MAX_RECORD).contains(&len) {
        return None;
    }
    let body = b.get(HEADER as usize..HEADER as usize + len as usize)?;
    if CRC32.checksum(body) != crc {
        return None;
    }
    Some((message(body)?, HEADER + u64::from(len)))
}

/// The first intact record in `b` and the bytes skipped before it (damage); None and all
/// of `b` skipped when there is none.
fn next_record(b: &[u8]) -> (Option<(Incoming, u64)>, u64) {
    let mut at = 0;
    while at < b.len() {
        if let Some(r) = record_at(&b[at..]) {
            return (Some(r), at as u64);
        }
        match b[at + 1..].windows(4).position(|w| w == MARKER) {
            Some(i) => at += 1 + i,
            None => break,
        }
    }
    (None, b.len() as u64)
}

/// A record of the earlier format at the start of `b`, if whole.
fn legacy_record(b: &[u8]) -> Option<(Incoming, u64)> {
    let len = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
    if !(3..=MAX_RECORD).contains(&len) {
        return None;
    }
    let body = b.get(4..4 + len as usize)?;
    Some((message(body)?, 4 + u64::from(len)))
}

impl Spill {
    /// A read-only copy of where the spill stands now, to [`peek`](Self::peek) without the
    /// buffer's lock: it sees the records appended so far (the segments' sizes now), never
    /// one being appended; only its owner's [`commit`](Self::commit) moves the read position
    /// or deletes segments. Damage it finds is handed back with [`absorb`](Self::absorb).
    pub fn reader(&self) -> Spill {
        Spill {
            dir: self.dir.clone(),
            segments: self.segments.clone(),
            writer: None,
            read: self.read,
            records: self.records,
            damaged: RefCell::new(self.damaged.borrow().clone()),
        }
    }

    /// Keep what a [`reader`](Self::reader) found damaged.
    pub fn absorb(&self, reader: &Spill) {
        let found = reader.damaged.borrow();
        let mut d = self.damaged.borrow_mut();
        for (k, v) in found.iter() {
            d.entry(*k).or_insert(*v);
        }
    }

    /// Up to `max` records from the read position, and the cursor after them (not committed).
    /// The intact records of a segment are read a chunk at a time ([`Spill::read_chunk`]);
    /// a damaged or old-format stretch goes record by record ([`Spill::read_one`]).
    pub fn peek(&self, max: usize) -> Result<(Vec<Incoming>, Cursor)> {
        let mut out = Vec::new();
        let mut c = self.read;
        while out.len() < max {
            if let Some(next) = self.read_chunk(c, max - out.len(), &mut out)? {
                c = next;
                continue;
            }
            match self.read_one(c)? {
                Some((m, next)) => {
                    out.push(m);
                    c = next;
                }
                None => break,
            }
        }
        Ok((out, c))
    }

    /// Up to [`CHUNK`] bytes of `c`'s segment read at once (one open and two reads, instead
    /// of an open and three reads per record): up to `max` whole intact records from its
    /// start go to `out`. Returns the cursor after them, or None when the chunk starts with
    /// none (damage, an old-format segment, a record larger than the chunk, the segment's
    /// end): the careful path decides then.
    fn read_chunk(&self, c: Cursor, max: usize, out: &mut Vec<Incoming>) -> Result<Option<Cursor>> {
        let Some(&(_, size)) = self.segments.iter().find(|s| s.0 == c.segment) else {
            return Ok(None);
        };
        if c.offset >= size {
            return Ok(None);
        }
        let mut f = File::open(segment_path(&self.dir, c.segment))?;
        if read_at(&mut f, 0, 4, size)?[..] != MARKER {
            return Ok(None);
        }
        let chunk = read_at(&mut f, c.offset, CHUNK, size)?;
        let (mut at, mut n) = (0usize, 0usize);
        while n < max {
            let Some((m, used)) = chunk.get(at..).and_then(record_at) else {
                break;
            };
            out.push(m);
            at += used as usize;
            n += 1;
        }
        Ok((at > 0).then_some(Cursor {
            segment: c.segment,
            offset: c.offset + at as u64,
        }))
    }

    /// Everything before `c` is committed: delete the segments read to the end.
    pub fn commit(&mut self, c: Cursor, records: u64) -> Result<()> {
        self.read = c;
        self.records = self.records.saturating_sub(records);
        while let Some(&(first, size)) = self.segments.first() {
            let fully_read = first < self.read.segment
                || (first == self.read.segment && self.read.offset >= size);
            let is_writing = self.segments.len() == 1 && self.writer.is_some();
            if !fully_read {
                break;
            }
            if is_writing {
                self.writer = None;
            }
            std::fs::remove_file(segment_path(&self.dir, first))
                .with_context(|| format!("removing spill segment {first}"))?;
            self.segments.remove(0);
            self.read = Cursor {
                segment: self.segments.first().map_or(first + 1, |s| s.0),
                offset: 0,
            };
        }
        // Nothing readable left (a torn tail at most): every segment is done with.
        if !self.segments.is_empty() && self.read_one(self.read)?.is_none() {
            for &(n, _) in &self.segments {
                std::fs::remove_file(segment_path(&self.dir, n))
                    .with_context(|| format!("removing spill segment {n}"))?;
            }
            let next = self.segments.last().map_or(self.read.segment, |s| s.0 + 1);
            self.segments.clear();
            self.writer = None;
            self.read = Cursor {
                segment: next,
                offset: 0,
            };
        }
        if self.segments.is_empty() {
            self.records = 0;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(i: usize) -> Incoming {
        Incoming {
            kind: Kind::Health,
            key: format!("rigmon/r/a/p{i}/health"),
            payload: vec![i as u8; 100 + i],
            recovered: false,
        }
    }

    #[test]
    fn spilled_messages_come_back_in_order_and_survive_a_restart() {
        let d = tempfile::tempdir().unwrap();
        let mut s = Spill::open(d.path()).unwrap();
        for i in 0..10 {
            s.append(&msg(i)).unwrap();
        }
        let (first, c) = s.peek(4).unwrap();
        assert_eq!(
            first.iter().map(|m| m.payload.len()).collect::<Vec<_>>(),
            [100, 101, 102, 103]
        );
        s.commit(c, 4).unwrap();
        assert_eq!(s.records(), 6);
        drop(s);
        // A torn record at the end (killed mid-write) is skipped on reading.
        let seg = segment_path(d.path(), 1);
        let mut f = OpenOptions::new().append(true).open(&seg).unwrap();
        f.write_all(&[200, 0, 0, 0, 1, 2]).unwrap();
        let mut s = Spill::open(d.path()).unwrap();
        // The committed cursor was in memory only: a restart reads from the segment start
        // again (duplicates are dropped by the database's primary key).
        let (all, c) = s.peek(100).unwrap();
        assert_eq!(all.len(), 10);
        assert_eq!(all[9].key, "rigmon/r/a/p9/health");
        s.commit(c, all.len() as u64).unwrap();
        assert!(s.is_empty());
        assert!(
            std::fs::read_dir(d.path()).unwrap().next().is_none(),
            "segments deleted"
        );
    }

    #[test]
    fn a_recovered_message_comes_back_recovered() {
        let d = tempfile::tempdir().unwrap();
        let mut s = Spill::open(d.path()).unwrap();
        let mut live = msg(1);
        live.kind = Kind::Status;
        let mut recovered = msg(2);
        recovered.recovered = true;
        s.append(&live).unwrap();
        s.append(&recovered).unwrap();
        let (back, _) = s.peek(10).unwrap();
        let seen: Vec<(Kind, bool)> = back.iter().map(|m| (m.kind, m.recovered)).collect();
        assert_eq!(seen, [(Kind::Status, false), (Kind::Health, true)]);
    }

    /// Issue 38, F10: one damaged length field lost the rest of its segment (98 of 100
    /// messages), uncounted. Now the reader resyncs at the next intact record and counts the
    /// damaged stretch.
    #[test]
    fn a_damaged_length_loses_one_message_and_is_counted() {
        let d = tempfile::tempdir().unwrap();
        let mut s = Spill::open(d.path()).unwrap();
        let mut offsets = Vec::new();
        for i in 0..100 {
            offsets.push(s.segments.last().map_or(0, |x| x.1));
            s.append(&msg(i)).unwrap();
        }
        drop(s);
        // The length field of message 2 says 2^31 bytes.
        let seg = segment_path(d.path(), 1);
        let mut bytes = std::fs::read(&seg).unwrap();
        let at = offsets[2] as usize + 4;
        bytes[at..at + 4].copy_from_slice(&0x8000_0000u32.to_le_bytes());
        std::fs::write(&seg, &bytes).unwrap();
        let s = Spill::open(d.path()).unwrap();
        let (all, _) = s.peek(1000).unwrap();
        let got: Vec<usize> = all.iter().map(|m| m.payload.len() - 100).collect();
        let want: Vec<usize> = (0..100).filter(|&i| i != 2).collect();
        assert_eq!(got, want, "only message 2 is lost");
        let (stretches, skipped) = s.damage();
        assert_eq!(stretches, 1);
        assert_eq!(
            skipped,
            offsets[3] - offsets[2],
            "exactly message 2's bytes"
        );
        // A record of the earlier format (no marker) is still read.
        let d2 = tempfile::tempdir().unwrap();
        let mut old = Vec::new();
        for i in 0..3u8 {
            let key = b"rigmon/r/a/p/health";
            let body_len = 3 + key.len() + 10;
            old.extend_from_slice(&(body_len as u32).to_le_bytes());
            old.push(1);
            old.extend_from_slice(&(key.len() as u16).to_le_bytes());
            old.extend_from_slice(key);
            old.extend_from_slice(&[i; 10]);
        }
        std::fs::write(segment_path(d2.path(), 7), &old).unwrap();
        let s = Spill::open(d2.path()).unwrap();
        let (all, _) = s.peek(10).unwrap();
        assert_eq!(
            all.iter().map(|m| m.payload[0]).collect::<Vec<_>>(),
            [0, 1, 2]
        );
        assert_eq!(s.damage(), (0, 0));
    }
}
