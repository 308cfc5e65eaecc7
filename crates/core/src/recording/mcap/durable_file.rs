//! An MCAP file that is complete on disk after every chunk ([`McapFile`]): the writer closes
//! its own chunks (at `chunk_size` uncompressed bytes or on [`McapFile::flush`]), each written
//! in one piece (no placeholder chunk header), and after each one a provisional end follows the
//! data: a `DataEnd` and a `Footer` without a summary (`summary_start = 0`), then the magic.
//! The next chunk overwrites it; [`McapFile::finish`] replaces it with the real summary and
//! footer. So a file whose writer was killed (kill -9, power cut after the page cache reached
//! the disk) is a valid MCAP up to its last chunk, and every standard reader reads it, the
//! Python `mcap` package's `make_reader(...).iter_messages()` and the Rust crate's
//! `MessageStream` included (they read a footer without a summary linearly).
//!
//! It also keeps an upper bound of the finished file's size ([`McapFile::size_bound`]) so a
//! rotating recorder can close a segment before it passes its size limit, and a failed writer
//! can be cut back to its last complete chunk ([`McapFile::abandon`]).

use anyhow::{Context, Result};
use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The provisional end written after every chunk: `DataEnd` (crc 0: not computed), `Footer`
/// (no summary, no summary offsets, crc 0) and the closing magic.
const PROVISIONAL_END: [u8; 50] = {
    let mut b = [0u8; 50];
    b[0] = 0x0f; // DataEnd
    b[1] = 4; // record length 4 (u64 LE), data_section_crc u32 = 0
    b[13] = 0x02; // Footer
    b[14] = 20; // record length 20: summary_start, summary_offset_start (u64), summary_crc (u32)
    let magic = *b"\x89MCAP0\r\n";
    let mut i = 0;
    while i < 8 {
        b[42 + i] = magic[i];
        i += 1;
    }
    b
};

/// Bytes a finished file adds after the data for itself (`DataEnd`, footer, magic, summary
/// offsets, statistics header) besides what grows with channels and chunks.
const SUMMARY_FIXED: u64 = 13 + 29 + 8 + 6 * 26 + 64;
/// Summary bytes per chunk (chunk index without its per-channel offsets) ...
const SUMMARY_PER_CHUNK: u64 = 96;
/// ... and per channel, per chunk (message-index offset) and once (message count).
const SUMMARY_PER_CHANNEL: u64 = 10;

/// How far a [`DurableFile`] got, readable while the MCAP writer owns the file.
#[derive(Debug, Default)]
struct Progress {
    /// End of the MCAP data written so far (the provisional end lies beyond it).
    len: AtomicU64,
    /// End of the data the last provisional end closed (a readable prefix of the file).
    committed: AtomicU64,
}

/// A file written through the MCAP writer (unbuffered: the writer hands it whole chunks):
/// tracks the data's length and writes the provisional end on every flush.
pub struct DurableFile {
    file: File,
    /// Where the next write goes.
    pos: u64,
    len: u64,
    progress: Arc<Progress>,
}

impl DurableFile {
    fn create(path: &Path) -> std::io::Result<Self> {
        Ok(DurableFile {
            file: File::create(path)?,
            pos: 0,
            len: 0,
            progress: Arc::default(),
        })
    }

    /// Write the provisional end at the end of the data and return to it.
    fn close_data(&mut self) -> std::io::Result<()> {
        self.file.seek(SeekFrom::Start(self.len))?;
        self.file.write_all(&PROVISIONAL_END)?;
        self.file.seek(SeekFrom::Start(self.pos))?;
        self.progress.committed.store(self.len, Ordering::Relaxed);
        Ok(())
    }
}

impl Write for DurableFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.pos += n as u64;
        self.len = self.len.max(self.pos);
        self.progress.len.store(self.len, Ordering::Relaxed);
        Ok(n)
    }

    /// Called when the MCAP writer has closed a chunk (and its buffer reached the file): the
    /// data ends at a record boundary, so the provisional end can follow it.
    fn flush(&mut self) -> std::io::Result<()> {
        if self.pos == self.len && self.len > 0 {
            self.close_data()?;
        }
        self.file.flush()
    }
}

impl Seek for DurableFile {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let target = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.len.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        }
        .ok_or_else(|| std::io::Error::other("seek before the start of the file"))?;
        if target != self.pos {
            self.file.seek(SeekFrom::Start(target))?;
            self.pos = target;
        }
        Ok(self.pos)
    }
}

/// The settings of an [`McapFile`].
#[derive(Debug, Clone)]
pub struct McapFileOptions {
    /// Close a chunk at this many uncompressed bytes.
    pub chunk_size: u64,
    /// zstd level (1..19).
    pub zstd_level: u32,
    /// MCAP header profile.
    pub profile: String,
}

/// An MCAP file complete on disk after every chunk (see the module documentation).
pub struct McapFile {
    mcap: mcap::Writer<DurableFile>,
    progress: Arc<Progress>,
    path: PathBuf,
    chunk_size: u64,
    /// Uncompressed bytes and messages in the open chunk.
    open_bytes: u64,
    open_messages: u64,
    /// Chunks closed so far, and whether any of them held a message.
    chunks: u64,
    has_messages: bool,
    /// Something was written since the last provisional end.
    dirty: bool,
    /// Channels added (each costs summary bytes), and bytes of the records before the data
    /// (header, metadata, schemas, channels: repeated or indexed in the summary).
    channels: u64,
    definitions: u64,
}

impl McapFile {
    /// Create `path` (truncating it) and write the MCAP header.
    pub fn create(path: &Path, opts: &McapFileOptions) -> Result<Self> {
        let file = DurableFile::create(path)
            .with_context(|| format!("{}: cannot create", path.display()))?;
        let progress = file.progress.clone();
        let mcap = mcap::WriteOptions::new()
            .profile(opts.profile.clone())
            .library(concat!("rigmon ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(opts.zstd_level)
            // Chunks are closed here (`write`), each written whole from memory.
            .chunk_size(None)
            .disable_seeking(true)
            .create(file)
            .with_context(|| format!("{}: cannot write MCAP", path.display()))?;
        Ok(McapFile {
            mcap,
            progress,
            path: path.to_path_buf(),
            chunk_size: opts.chunk_size.max(1),
            open_bytes: 0,
            open_messages: 0,
            chunks: 0,
            has_messages: false,
            dirty: true,
            channels: 0,
            definitions: 0,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Add a schema (its record is written into the open chunk).
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> Result<u16> {
        let id = self.mcap.add_schema(name, encoding, data)?;
        self.dirty = true;
        let size = 9 + 2 + 12 + (name.len() + encoding.len() + data.len()) as u64;
        self.open_bytes += size;
        self.definitions += size;
        Ok(id)
    }

    /// Add a channel (its record is written into the open chunk).
    pub fn add_channel(
        &mut self,
        schema: u16,
        topic: &str,
        encoding: &str,
        metadata: &std::collections::BTreeMap<String, String>,
    ) -> Result<u16> {
        let id = self.mcap.add_channel(schema, topic, encoding, metadata)?;
        self.dirty = true;
        let meta: usize = metadata.iter().map(|(k, v)| 8 + k.len() + v.len()).sum();
        let size = 9 + 4 + 12 + (topic.len() + encoding.len() + meta) as u64;
        self.open_bytes += size;
        self.definitions += size;
        self.channels += 1;
        Ok(id)
    }

    /// Add a schema under a given id (copying another file's records).
    pub fn add_schema_with_id(
        &mut self,
        id: u16,
        name: &str,
        encoding: &str,
        data: &[u8],
    ) -> Result<()> {
        self.mcap.add_schema_with_id(id, name, encoding, data)?;
        self.dirty = true;
        let size = 9 + 2 + 12 + (name.len() + encoding.len() + data.len()) as u64;
        self.open_bytes += size;
        self.definitions += size;
        Ok(())
    }

    /// Add a channel under a given id (copying another file's records).
    pub fn add_channel_with_id(
        &mut self,
        id: u16,
        schema: u16,
        topic: &str,
        encoding: &str,
        metadata: &std::collections::BTreeMap<String, String>,
    ) -> Result<()> {
        self.mcap
            .add_channel_with_id(id, schema, topic, encoding, metadata)?;
        self.dirty = true;
        let meta: usize = metadata.iter().map(|(k, v)| 8 + k.len() + v.len()).sum();
        let size = 9 + 4 + 12 + (topic.len() + encoding.len() + meta) as u64;
        self.open_bytes += size;
        self.definitions += size;
        self.channels += 1;
        Ok(())
    }

    /// Write a metadata record (outside chunks: the open chunk is closed first).
    pub fn write_metadata(&mut self, m: &mcap::records::Metadata) -> Result<()> {
        if self.open_bytes > 0 {
            self.flush()?;
        }
        self.mcap.write_metadata(m)?;
        self.dirty = true;
        let size: usize = m.metadata.iter().map(|(k, v)| 8 + k.len() + v.len()).sum();
        // The record, and its index in the summary.
        self.definitions += 2 * (9 + 8 + m.name.len() as u64) + size as u64;
        Ok(())
    }

    /// Bytes one message of `data_len` bytes can add to the finished file: the record in the
    /// chunk (compression never expands by more than the bound allowed here) and its index.
    pub fn message_cost(data_len: usize) -> u64 {
        let record = 9 + 22 + data_len as u64;
        record + record / 128 + 16
    }

    /// Write a message; the chunk is closed once it holds `chunk_size` uncompressed bytes.
    pub fn write(&mut self, header: &mcap::records::MessageHeader, data: &[u8]) -> Result<()> {
        self.mcap.write_to_known_channel(header, data)?;
        self.dirty = true;
        self.open_bytes += 9 + 22 + data.len() as u64;
        self.open_messages += 1;
        if self.open_bytes >= self.chunk_size {
            self.flush()?;
        }
        Ok(())
    }

    /// Close the open chunk, write it and the provisional end: everything written so far
    /// survives the writer being killed.
    pub fn flush(&mut self) -> Result<()> {
        if !self.dirty {
            return Ok(());
        }
        self.mcap.flush()?;
        self.dirty = false;
        if self.open_bytes > 0 {
            self.chunks += 1;
        }
        self.has_messages |= self.open_messages > 0;
        self.open_bytes = 0;
        self.open_messages = 0;
        Ok(())
    }

    /// A complete chunk holding messages is on disk.
    pub fn has_data(&self) -> bool {
        self.has_messages
    }

    /// An upper bound of the file's size if it were finished now: the data on disk, the open
    /// chunk as if it did not compress, its message indexes, and the summary.
    pub fn size_bound(&self) -> u64 {
        let written = self.progress.len.load(Ordering::Relaxed);
        let open = self.open_bytes + self.open_bytes / 128 + 1024 + 16 * self.open_messages;
        let chunks = self.chunks + 1;
        let summary = SUMMARY_FIXED
            + self.definitions
            + chunks * (SUMMARY_PER_CHUNK + SUMMARY_PER_CHANNEL * self.channels)
            + SUMMARY_PER_CHANNEL * self.channels;
        written + open + summary
    }

    /// Write the summary and footer and close the file; its size.
    pub fn finish(mut self) -> Result<u64> {
        self.mcap
            .finish()
            .with_context(|| format!("{}: finishing MCAP", self.path.display()))?;
        let path = self.path.clone();
        let file = self.mcap.into_inner();
        // Nothing may follow the real footer (a provisional end from an earlier flush is
        // always overwritten, but be exact).
        file.file
            .set_len(file.len)
            .with_context(|| format!("{}: finishing MCAP", path.display()))?;
        Ok(file.len)
    }

    /// After a failed write: cut the file back to its last complete chunk and close it there
    /// with the provisional end. Returns the bytes that remain a readable MCAP, or 0 when no
    /// complete chunk with messages was ever written (the caller may then remove the file).
    pub fn abandon(self) -> Result<u64> {
        let has_data = self.has_messages;
        let path = self.path.clone();
        let mut file = self.mcap.into_inner();
        let committed = file.progress.committed.load(Ordering::Relaxed);
        if !has_data || committed == 0 {
            return Ok(0);
        }
        file.len = committed;
        file.pos = committed;
        let end = committed + PROVISIONAL_END.len() as u64;
        file.close_data()
            .and_then(|_| file.file.set_len(end))
            .with_context(|| {
                format!(
                    "{}: cutting back to the last complete chunk",
                    path.display()
                )
            })?;
        Ok(end)
    }
}
