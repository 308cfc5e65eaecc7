//! The spill: messages the memory buffer has no room for, appended to segment files
//! (`spill-0000000001.seg`, 16 MiB each) in the spill folder and read back in order once the
//! database keeps up again. A segment is deleted only after everything in it was committed,
//! so what is spilled survives a historian restart or crash (a torn last record is skipped).
//! Record: `u32` length (LE), then kind (1 byte), key length (`u16` LE), key, payload.

use super::incoming::{Incoming, Kind};
use anyhow::{bail, Context, Result};
use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

const SEGMENT_BYTES: u64 = 16 * 1024 * 1024;
/// Larger records are damage, not messages.
const MAX_RECORD: u32 = 64 * 1024 * 1024;

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

    /// Append one message.
    pub fn append(&mut self, m: &Incoming) -> Result<()> {
        let key = m.key.as_bytes();
        if key.len() > u16::MAX as usize {
            bail!("key too long to spill");
        }
        let len = 1 + 2 + key.len() + m.payload.len();
        let mut rec = Vec::with_capacity(4 + len);
        rec.extend_from_slice(&(len as u32).to_le_bytes());
        rec.push(m.kind as u8);
        rec.extend_from_slice(&(key.len() as u16).to_le_bytes());
        rec.extend_from_slice(key);
        rec.extend_from_slice(&m.payload);
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

    /// Read one record at `c`; None at the end (or a torn tail).
    fn read_one(&self, c: Cursor) -> Result<Option<(Incoming, Cursor)>> {
        let Some(&(_, size)) = self.segments.iter().find(|s| s.0 == c.segment) else {
            return Ok(None);
        };
        if c.offset + 4 > size {
            return Ok(self.next_segment(c.segment).and_then(|n| {
                self.read_one(Cursor {
                    segment: n,
                    offset: 0,
                })
                .ok()
                .flatten()
            }));
        }
        let mut f = File::open(segment_path(&self.dir, c.segment))?;
        f.seek(SeekFrom::Start(c.offset))?;
        let mut len = [0u8; 4];
        f.read_exact(&mut len)?;
        let len = u32::from_le_bytes(len);
        if !(3..=MAX_RECORD).contains(&len) || c.offset + 4 + u64::from(len) > size {
            // A torn record (the historian died while writing it): skip the rest of the segment.
            tracing::warn!(
                "spill segment {} has a torn record at byte {}; skipping its rest",
                c.segment,
                c.offset
            );
            return Ok(self.next_segment(c.segment).and_then(|n| {
                self.read_one(Cursor {
                    segment: n,
                    offset: 0,
                })
                .ok()
                .flatten()
            }));
        }
        let mut rec = vec![0u8; len as usize];
        f.read_exact(&mut rec)?;
        let kind = Kind::from_u8(rec[0]);
        let klen = u16::from_le_bytes([rec[1], rec[2]]) as usize;
        let key = String::from_utf8_lossy(rec.get(3..3 + klen).unwrap_or_default()).into_owned();
        let payload = rec.get(3 + klen..).unwrap_or_default().to_vec();
        let next = Cursor {
            segment: c.segment,
            offset: c.offset + 4 + u64::from(len),
        };
        Ok(Some((
            Incoming {
                kind,
                key,
                payload,
                recovered: false,
            },
            next,
        )))
    }

    fn next_segment(&self, n: u64) -> Option<u64> {
        self.segments.iter().map(|s| s.0).find(|&s| s > n)
    }

    /// Up to `max` records from the read position, and the cursor after them (not committed).
    pub fn peek(&self, max: usize) -> Result<(Vec<Incoming>, Cursor)> {
        let mut out = Vec::new();
        let mut c = self.read;
        while out.len() < max {
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
}
