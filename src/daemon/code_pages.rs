//! Give back the code pages that only start-up needed. Loading zenoh, tract and the config
//! touches tens of MB of the executable's code once; those pages are clean and file-backed, so
//! the kernel keeps them resident (RSS) until memory runs short. A few seconds after the
//! daemon is up, `release_after` asks the kernel (`madvise(MADV_PAGEOUT)`) to drop the
//! read-only, file-backed mappings of the process; the pages the steady loop uses fault back
//! in from the page cache at once (minor faults, no disk I/O while the file is cached). Private
//! data (heap, stacks, writable mappings) is never touched. Linux >= 5.4; on older kernels
//! `madvise` fails with EINVAL, which is logged and ignored.

use std::time::Duration;

/// One mapping line of /proc/self/maps that may be paged out: clean, file-backed, read-only.
#[derive(Debug, PartialEq)]
struct Mapping {
    start: usize,
    end: usize,
}

/// Spawns a thread that waits `delay`, then pages out the process' read-only file-backed
/// mappings once and exits.
pub fn release_after(delay: Duration) {
    let spawned = std::thread::Builder::new()
        .name("rigmon-code-pages".into())
        .spawn(move || {
            std::thread::sleep(delay);
            match release_now() {
                Ok((n, bytes)) => tracing::debug!(
                    "paged out {n} read-only file mappings ({:.1} MB of address space)",
                    bytes as f64 / 1e6
                ),
                Err(e) => tracing::debug!("could not page out start-up code: {e}"),
            }
        });
    if let Err(e) = spawned {
        tracing::debug!("could not start the code-page thread: {e}");
    }
}

/// Pages out every read-only, file-backed mapping now; returns how many and their size.
pub fn release_now() -> std::io::Result<(usize, usize)> {
    let maps = std::fs::read_to_string("/proc/self/maps")?;
    let (mut n, mut bytes) = (0, 0);
    for m in maps.lines().filter_map(parse_line) {
        // SAFETY: the range is a whole mapping of this process as the kernel listed it;
        // MADV_PAGEOUT only reclaims clean pages of it and never changes their contents.
        let rc = unsafe {
            libc::madvise(
                m.start as *mut libc::c_void,
                m.end - m.start,
                libc::MADV_PAGEOUT,
            )
        };
        if rc != 0 {
            return Err(std::io::Error::last_os_error());
        }
        n += 1;
        bytes += m.end - m.start;
    }
    Ok((n, bytes))
}

/// `start-end perms offset dev inode path`: keeps mappings without `w` whose path is a file.
fn parse_line(line: &str) -> Option<Mapping> {
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
    fn keeps_only_read_only_file_mappings() {
        let code = "55d0c0a00000-55d0c2a00000 r-xp 00200000 fd:01 1234 /usr/bin/rigmon";
        assert_eq!(
            parse_line(code),
            Some(Mapping {
                start: 0x55d0c0a00000,
                end: 0x55d0c2a00000
            })
        );
        assert!(parse_line("7f00-7f10 rw-p 00000000 00:00 0 [heap]").is_none());
        assert!(parse_line("7f00-7f10 rw-p 00001000 fd:01 1234 /usr/bin/rigmon").is_none());
        assert!(parse_line("7f00-7f10 r--p 00000000 00:00 0 [vvar]").is_none());
        assert!(parse_line("7f00-7f10 ---p 00000000 fd:01 99 /lib/libc.so.6").is_none());
        assert!(parse_line("7f00-7f10 r-xp 00000000 00:00 0").is_none());
    }

    #[test]
    fn paging_out_keeps_the_process_working() {
        let (n, bytes) = release_now().expect("madvise on this kernel");
        assert!(n > 0 && bytes > 0);
        // Code runs on after its pages were dropped (they fault back from the page cache).
        let v: Vec<u64> = (0..1000).map(|i| i * i).collect();
        assert_eq!(v.iter().sum::<u64>(), 332_833_500);
    }
}
