//! Memory for reading a recording whole ([`check_whole_read`]): commands that need all of a
//! recording at once (`features`, `inspect`, `evaluate`, ...) estimate what reading it will
//! take from its size and format, and refuse at once, naming both figures, when that is more
//! than the memory available to the process ([`available`]: the kernel's `MemAvailable`, a
//! cgroup's `memory.max`, `ulimit -v`), instead of being killed minutes later. `replay` and
//! `import` stream rigmon MCAP and WAV files and need no such check.

use super::mat5::{self, MatDirectory};
use super::Format;
use anyhow::{bail, Result};
use std::path::Path;

/// Memory the process may still use, bytes, and what limits it.
#[derive(Debug, Clone, PartialEq)]
pub struct Available {
    pub bytes: u64,
    pub limited_by: &'static str,
}

/// Bytes of memory reading a file of `size` bytes whole takes, at most: samples as f32 plus
/// what the reader holds while it converts.
/// - WAV: 16-bit samples become 4-byte floats (2x the data), 8-bit 4x; plus the file's
///   bytes never held at once: 4x covers every sample width.
/// - CSV: the text (1x), and, reserved once for every line that can be a row, the time
///   column as f64 and the channels as f32 (columns naming no channel are not kept); a value
///   takes at least 2 characters (digit and separator), so at most 12 bytes per 4 characters of
///   `0,0` rows: 3x. 4x in all.
/// - rigmon MCAP: zstd-compressed float blocks (decompressed at most ~2x), held as blocks and
///   then as channels: 4x.
/// - MAT: estimated from the variable directory instead ([`mat_need`]): the size of a file
///   says nothing of what its compressed elements expand to.
pub fn estimate(format: Format, size: u64) -> Option<u64> {
    match format {
        Format::Wav | Format::Csv | Format::Mcap => Some(size.saturating_mul(4)),
        Format::Mat => None,
    }
}

/// Refuse a whole read that cannot fit in `available` memory, naming the file's size, the
/// estimate and the limit, and what to do instead.
pub fn check_whole_read(
    path: &Path,
    format: Format,
    size: u64,
    available: &Option<Available>,
) -> Result<()> {
    let (Some(need), Some(avail)) = (estimate(format, size), available) else {
        return Ok(());
    };
    if need > avail.bytes {
        bail!(
            "{}: this command reads the whole recording into memory: the {} file needs about {} \
             but {} is available ({}); `rigmon replay` and `rigmon import` stream rigmon MCAP and \
             WAV files with bounded memory (convert it with `rigmon import`), or split the file",
            path.display(),
            size_text(size),
            size_text(need),
            size_text(avail.bytes),
            avail.limited_by
        );
    }
    Ok(())
}

/// Bytes of memory decoding the MAT variables `names` of `dir` takes, at most. Each variable's
/// data is held as read (its stored bytes), decompressed (inflated into nothing first to learn
/// its size: [`mat5::inflated_len`]), then decoded:
/// - a numeric array: `count` f64 values, then f32 channel samples: 12 bytes per element
///   (an int8 element inflates 13-fold);
/// - a struct or cell: per decompressed byte, at most one int8 value as f64 and f32 (12 bytes)
///   or one nested matrix header: 13x its decompressed size.
///
/// Element counts come from the header and are checked against the data when decoding; here
/// they only size the estimate, nothing is allocated from them.
pub fn mat_need(path: &Path, dir: &MatDirectory, names: &[&str]) -> Result<u64> {
    let mut f = std::io::BufReader::new(
        std::fs::File::open(path)
            .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?,
    );
    let mut need = 0u64;
    for e in dir
        .entries
        .iter()
        .filter(|e| names.contains(&e.name.as_str()))
    {
        let raw = mat5::inflated_len(&mut f, e)
            .map_err(|err| anyhow::anyhow!("{}: cannot read: {err}", path.display()))?;
        let decoded = if e.class.is_numeric() {
            let count = e.count() as u64 * if e.complex { 2 } else { 1 };
            count
                .saturating_mul(12)
                .max(raw.saturating_mul(12) / mat5::class_bytes(e.class))
        } else {
            raw.saturating_mul(12)
        };
        need = need
            .saturating_add(e.len)
            .saturating_add(raw)
            .saturating_add(decoded);
    }
    Ok(need)
}

/// Refuse decoding that needs `need` bytes (a [`mat_need`]) when less is `available`.
pub fn check_need(path: &Path, need: u64, what: &str, available: &Option<Available>) -> Result<()> {
    let Some(avail) = available else {
        return Ok(());
    };
    if need > avail.bytes {
        bail!(
            "{}: decoding {what} needs about {} of memory but {} is available ({}); nothing was \
             decoded. Re-save the signals as single or double vectors in smaller files, or \
             raise the limit",
            path.display(),
            size_text(need),
            size_text(avail.bytes),
            avail.limited_by
        );
    }
    Ok(())
}

/// "2.0 GiB", "512 MiB", "37 KiB", "12 B".
pub fn size_text(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else if b >= (1u64 << 20) as f64 {
        format!("{:.0} MiB", b / (1u64 << 20) as f64)
    } else if b >= 1024.0 {
        format!("{:.0} KiB", b / 1024.0)
    } else {
        format!("{bytes} B")
    }
}

/// The least of: `MemAvailable` (/proc/meminfo), the cgroup v2 limit minus its usage, and
/// `ulimit -v` minus the address space in use. `None` when none can be read (not Linux).
pub fn available() -> Option<Available> {
    let mut best: Option<Available> = None;
    let mut offer = |bytes: u64, limited_by: &'static str| {
        if best.as_ref().is_none_or(|b| bytes < b.bytes) {
            best = Some(Available { bytes, limited_by });
        }
    };
    let read = |p: &str| std::fs::read_to_string(p).ok();
    if let Some(kb) = read("/proc/meminfo").and_then(|t| field_kb(&t, "MemAvailable:")) {
        offer(kb * 1024, "MemAvailable in /proc/meminfo");
    }
    let cg =
        |f: &str| read(&format!("/sys/fs/cgroup/{f}")).and_then(|t| t.trim().parse::<u64>().ok());
    if let (Some(max), Some(cur)) = (cg("memory.max"), cg("memory.current")) {
        offer(max.saturating_sub(cur), "the cgroup's memory.max");
    }
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct we pass.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut lim) } == 0
        && lim.rlim_cur != libc::RLIM_INFINITY
    {
        let used = read("/proc/self/status")
            .and_then(|t| field_kb(&t, "VmSize:"))
            .unwrap_or(0)
            * 1024;
        offer(lim.rlim_cur.saturating_sub(used), "ulimit -v (RLIMIT_AS)");
    }
    best
}

/// A `Key:   123 kB` field of /proc/meminfo or /proc/self/status, in kB.
fn field_kb(text: &str, key: &str) -> Option<u64> {
    text.lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_read_that_cannot_fit_is_refused_naming_the_sizes() {
        let small = Some(Available {
            bytes: 1_500_000_000,
            limited_by: "ulimit -v (RLIMIT_AS)",
        });
        let p = Path::new("big.wav");
        let e = check_whole_read(p, Format::Wav, 2 << 30, &small)
            .unwrap_err()
            .to_string();
        for want in [
            "big.wav",
            "2.0 GiB",
            "8.0 GiB",
            "1.4 GiB",
            "RLIMIT_AS",
            "rigmon replay",
        ] {
            assert!(e.contains(want), "{want:?} not in {e}");
        }
        assert!(check_whole_read(p, Format::Wav, 100 << 20, &small).is_ok());
        assert!(check_whole_read(p, Format::Mat, 2 << 30, &small).is_ok());
        assert!(check_whole_read(p, Format::Csv, 2 << 30, &None).is_ok());
        assert!(available().is_some_and(|a| a.bytes > 0));
        assert_eq!(
            field_kb("MemTotal: 10 kB\nMemAvailable:  7 kB\n", "MemAvailable:"),
            Some(7)
        );
    }
}
