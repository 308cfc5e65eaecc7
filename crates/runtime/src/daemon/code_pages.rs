//! Give back the code pages that only start-up needed. Loading the source, the model (tract
//! parses and optimises it) and opening the Zenoh session each run megabytes of code once;
//! the kernel maps code in 64 kB runs around every page touched (fault-around), so start-up
//! leaves most of a 33 MB `.text` resident although the steady loop runs a fraction of it.
//! [`end_of_phase`] drops the process' mappings of read-only file pages at the end of each
//! start-up phase and [`release_after`] once more a few seconds into the run: what runs next
//! faults straight back in from the page cache (a minor fault: the pages stay cached, no disk
//! I/O), so the resident set peaks at the largest phase instead of the sum of all of them.
//!
//! Only mappings that are read-only, backed by a file and hold no private copies (smaps
//! `Anonymous: 0 kB`) are touched: a RELRO segment whose relocated pages are private copies
//! is left alone, as are the heap, stacks and writable data. `madvise(MADV_DONTNEED)` on such a
//! mapping only unmaps it from this process, so it works on pages another process shares
//! (a `rigmon watch` on the same host) and it updates the kernel's high-water mark (VmHWM)
//! before dropping, which `MADV_PAGEOUT` did not.

use std::time::Duration;

/// One mapping of /proc/self/smaps that may be dropped: clean, file-backed, read-only.
#[derive(Debug, PartialEq)]
struct Mapping {
    start: usize,
    end: usize,
}

/// What one release did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Released {
    /// Mappings dropped and their size (bytes of address space).
    pub mappings: usize,
    pub bytes: usize,
    /// Resident set before and after, MB (VmRSS).
    pub rss_before_mb: f64,
    pub rss_after_mb: f64,
}

/// The end of a start-up phase (`phase` names it in the debug log): drop the code it ran.
pub fn end_of_phase(phase: &str) {
    match release_now() {
        Ok(r) => tracing::debug!(
            "{phase}: dropped {} read-only file mappings ({:.1} MB of address space), RSS {:.1} -> {:.1} MB",
            r.mappings,
            r.bytes as f64 / 1e6,
            r.rss_before_mb,
            r.rss_after_mb
        ),
        Err(e) => tracing::debug!("{phase}: could not drop start-up code pages: {e}"),
    }
}

/// Spawns a thread that waits `delay`, then drops the read-only file mappings once more (what
/// the first windows ran once) and exits.
pub fn release_after(delay: Duration) {
    let spawned = std::thread::Builder::new()
        .name("rigmon-code-pages".into())
        .spawn(move || {
            std::thread::sleep(delay);
            end_of_phase("first windows");
        });
    if let Err(e) = spawned {
        tracing::debug!("could not start the code-page thread: {e}");
    }
}

/// Drops every read-only, file-backed mapping without private copies now.
pub fn release_now() -> std::io::Result<Released> {
    let rss_before_mb = rss_mb();
    let smaps = std::fs::read_to_string("/proc/self/smaps")?;
    let (mut mappings, mut bytes) = (0, 0);
    for m in droppable(&smaps) {
        // SAFETY: the range is a whole read-only, file-backed mapping of this process as the
        // kernel listed it, with no private (anonymous) pages: MADV_DONTNEED only unmaps its
        // pages here, and the next access maps the same file contents back in.
        let rc = unsafe {
            libc::madvise(
                m.start as *mut libc::c_void,
                m.end - m.start,
                libc::MADV_DONTNEED,
            )
        };
        if rc != 0 {
            return Err(std::io::Error::last_os_error());
        }
        mappings += 1;
        bytes += m.end - m.start;
    }
    Ok(Released {
        mappings,
        bytes,
        rss_before_mb,
        rss_after_mb: rss_mb(),
    })
}

/// This process' resident set, MB (NaN when /proc cannot be read).
fn rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// The mappings of an smaps text that may be dropped: header `start-end perms offset dev
/// inode path` without `w`, readable, with a file path, and an `Anonymous:` line of 0 kB.
fn droppable(smaps: &str) -> Vec<Mapping> {
    let mut out = Vec::new();
    let mut current: Option<Mapping> = None;
    for line in smaps.lines() {
        if let Some(kb) = line.strip_prefix("Anonymous:") {
            let clean = kb.split_whitespace().next() == Some("0");
            if let Some(m) = current.take().filter(|_| clean) {
                out.push(m);
            }
        } else if line
            .split_whitespace()
            .next()
            .is_some_and(|f| f.contains('-'))
        {
            current = parse_header(line);
        }
    }
    out
}

/// An smaps header line that names a read-only file mapping.
fn parse_header(line: &str) -> Option<Mapping> {
    let mut fields = line.split_whitespace();
    let range = fields.next()?;
    let perms = fields.next()?;
    let path = fields.nth(3)?;
    if perms.contains('w') || !perms.starts_with('r') || !path.starts_with('/') {
        return None;
    }
    let (a, b) = range.split_once('-')?;
    let start = usize::from_str_radix(a, 16).ok()?;
    let end = usize::from_str_radix(b, 16).ok()?;
    (end > start).then_some(Mapping { start, end })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_only_read_only_file_mappings_without_private_copies() {
        let smaps = "\
55d0c0a00000-55d0c2a00000 r-xp 00200000 fd:01 1234 /usr/bin/rigmon
Size:              32768 kB
Rss:               15000 kB
Anonymous:             0 kB
55d0c2a00000-55d0c2b00000 r--p 02a00000 fd:01 1234 /usr/bin/rigmon
Rss:                1024 kB
Anonymous:          1024 kB
7f00-7f10 rw-p 00000000 00:00 0 [heap]
Anonymous:            64 kB
7f10-7f20 rw-p 00001000 fd:01 1234 /usr/bin/rigmon
Anonymous:             0 kB
7f20-7f30 r--p 00000000 00:00 0 [vvar]
Anonymous:             0 kB
7f30-7f40 ---p 00000000 fd:01 99 /lib/libc.so.6
Anonymous:             0 kB
7f40-7f50 r-xp 00000000 00:00 0
Anonymous:             0 kB
7f50-7f60 r--p 00000000 fd:01 99 /lib/libc.so.6
Anonymous:             0 kB
";
        // The code and libc's read-only data; not the relocated (private) RELRO segment,
        // the heap, writable data, [vvar], a guard or an anonymous mapping.
        assert_eq!(
            droppable(smaps),
            [
                Mapping {
                    start: 0x55d0c0a00000,
                    end: 0x55d0c2a00000
                },
                Mapping {
                    start: 0x7f50,
                    end: 0x7f60
                }
            ]
        );
    }

    #[test]
    fn dropping_keeps_the_process_working_and_its_data() {
        let table: Vec<u64> = (0..1000).map(|i| i * i).collect();
        let r = release_now().expect("madvise on this kernel");
        assert!(r.mappings > 0 && r.bytes > 0, "{r:?}");
        // Code runs on after its pages were dropped (they fault back from the page cache),
        // and data made before is intact.
        assert_eq!(table.iter().sum::<u64>(), 332_833_500);
        let again: Vec<u64> = (0..1000).map(|i| i * i).collect();
        assert_eq!(again, table);
    }
}
