//! CSV recordings: a header line naming the columns, then one line per sample.
//!
//! Columns are matched to the rig's channels by name (acceleration and tacho); an optional time
//! column (`time`, `t`, `time_s`, `t_s`, `seconds`; in seconds) gives the sample rate, which must
//! be uniform. Without one the rig's (or `--sample-rate`'s) rate is used. The delimiter is `,`,
//! `;` or tab (taken from the header, outside quotes). Fields are split by the `csv` crate:
//! quoted fields may hold the delimiter and doubled quotes; LF and CRLF line ends and a UTF-8
//! byte-order mark are accepted. Lines starting with `#` and blank lines are skipped. Values are
//! multiplied by the channel's `sensitivity`. Columns that name no rig channel are side data:
//! skipped with a warning in the provenance (their values are not read).

use super::{check_classifier_channel, resolve_sample_rate, ImportOptions, WARNING};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Bytes at the start of a CSV file checked for being text before it is read.
const TEXT_CHECK_BYTES: usize = 64 * 1024;

/// Refuse a file named `.csv` that is not text, from its first 64 KiB: a NUL byte or bytes
/// that are not UTF-8 (so a binary file is refused at once, not after reading it all).
pub fn check_text(path: &Path, size: u64) -> Result<()> {
    use std::io::Read;
    let mut head = Vec::with_capacity(TEXT_CHECK_BYTES);
    std::fs::File::open(path)
        .and_then(|f| f.take(TEXT_CHECK_BYTES as u64).read_to_end(&mut head))
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let line_of = |at: usize| 1 + head[..at].iter().filter(|&&b| b == b'\n').count();
    if let Some(at) = head.iter().position(|&b| b == 0) {
        bail!(
            "{}: not a text file: byte {at} (line {}) is a NUL byte; CSV recordings are text \
             (the file is {}; is it a binary file with a .csv name?)",
            path.display(),
            line_of(at),
            super::memory::size_text(size)
        );
    }
    if let Err(e) = std::str::from_utf8(&head) {
        // A character cut by the 64 KiB boundary is fine.
        if e.error_len().is_some() || (head.len() as u64) == size {
            let at = e.valid_up_to();
            bail!(
                "{}: not UTF-8 text: byte {at} (line {}) is not valid UTF-8; save the CSV as \
                 UTF-8 (or ASCII)",
                path.display(),
                line_of(at)
            );
        }
    }
    Ok(())
}

/// A cell written with a decimal comma (`1,5`, `-0,25`): digits, one comma, digits.
fn decimal_comma(cell: &str) -> bool {
    let t = cell.strip_prefix(['-', '+']).unwrap_or(cell);
    match t.split_once(',') {
        Some((a, b)) => {
            !a.is_empty()
                && !b.is_empty()
                && a.bytes().all(|c| c.is_ascii_digit())
                && b.bytes().all(|c| c.is_ascii_digit())
        }
        None => false,
    }
}

/// What to say about numbers written with decimal commas.
const DECIMAL_COMMA_HINT: &str = "rigmon reads numbers with a decimal point (1.5, not 1,5): \
     export the CSV with `.` as the decimal separator (in a spreadsheet, set the language to \
     English for the export), or replace the decimal commas (with `;` or tab between columns: \
     `sed 's/,/./g'`)";

/// Header names accepted for the time column.
pub const TIME_COLUMNS: [&str; 5] = ["time", "t", "time_s", "t_s", "seconds"];

/// A line the reader skips: blank, or a comment (`#` after optional whitespace).
fn skipped_line(line: &str) -> bool {
    let t = line.trim_start();
    t.is_empty() || t.starts_with('#')
}

/// The delimiter the header line uses: the first of `,`, `;`, tab found outside quotes
/// (`,` when there is none: a one-column file).
fn sniff_delimiter(header: &str) -> u8 {
    let (mut quoted, mut seen) = (false, [false; 3]);
    for c in header.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => seen[0] = true,
            ';' if !quoted => seen[1] = true,
            '\t' if !quoted => seen[2] = true,
            _ => {}
        }
    }
    match seen {
        [true, _, _] => b',',
        [_, true, _] => b';',
        [_, _, true] => b'\t',
        _ => b',',
    }
}

/// The 1-based line each record starts on. The `csv` reader reports byte offsets that lie
/// before the blank and comment lines it skipped; this walks from there to the record's first
/// byte and counts the line ends on the way (monotonically, so the whole file costs one pass).
struct Lines<'a> {
    text: &'a [u8],
    at: usize,
    line: u64,
}

impl Lines<'_> {
    fn start_of(&mut self, from: u64) -> u64 {
        let mut i = (from as usize).max(self.at).min(self.text.len());
        self.line += self.text[self.at..i]
            .iter()
            .filter(|&&b| b == b'\n')
            .count() as u64;
        // Skip what csv-core skips before a record: line ends and `#` comment lines.
        while i < self.text.len() {
            match self.text[i] {
                b'\n' => self.line += 1,
                b'\r' => {}
                b'#' => {
                    while i < self.text.len() && self.text[i] != b'\n' {
                        i += 1;
                    }
                    continue;
                }
                _ => break,
            }
            i += 1;
        }
        self.at = i;
        self.line
    }
}

/// A cell's text: trimmed, and unquoted when whitespace before the opening quote kept the
/// `csv` reader from taking it as a quoted field (`1, "2"`).
fn cell(field: &str) -> &str {
    let f = field.trim();
    match f.len() >= 2 && f.starts_with('"') && f.ends_with('"') {
        true => f[1..f.len() - 1].trim(),
        false => f,
    }
}

/// What a column is read into.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Col {
    Time,
    /// Rig channel `k`.
    Channel(usize),
    /// Side data: not read.
    Skip,
}

/// What reading the rows needs to know.
struct RowContext<'a> {
    path: &'a Path,
    names: &'a [String],
    kinds: &'a [Col],
    delim: u8,
    rig: &'a RigConfig,
}

/// The rows read: the time column, each rig channel's samples (`None`: no column), the count.
type Rows = (Vec<f64>, Vec<Option<Vec<f32>>>, usize);

/// The next record and its line, or `None` at the end.
type NextRecord<'a> = dyn FnMut(&mut ::csv::StringRecord) -> Result<Option<u64>> + 'a;

impl RowContext<'_> {
    /// Every row: the time column (empty without one), each rig channel's samples (by rig
    /// channel index; `None` for channels with no column) and the number of rows. Each cell is
    /// looked at once (a wide header costs linear time); a time must be finite and a sample,
    /// times its sensitivity, must fit an f32: both refused naming the line.
    fn read_rows(
        &self,
        next: &mut NextRecord,
        record: &mut ::csv::StringRecord,
        rows_hint: usize,
    ) -> Result<Rows> {
        let (p, names) = (self.path.display(), self.names);
        let mut time = Vec::new();
        if self.kinds.contains(&Col::Time) {
            time.reserve_exact(rows_hint);
        }
        let mut chans: Vec<Option<Vec<f32>>> = vec![None; self.rig.channels.len()];
        for kind in self.kinds {
            if let Col::Channel(k) = kind {
                chans[*k] = Some(Vec::with_capacity(rows_hint));
            }
        }
        let mut rows = 0;
        while let Some(line) = next(record)? {
            if record.len() > names.len() {
                return Err(self.width_error(record, line));
            }
            for (c, field) in record.iter().enumerate() {
                let kind = self.kinds[c];
                if kind == Col::Skip {
                    continue;
                }
                let v = self.number(cell(field), line, c)?;
                match kind {
                    Col::Time if v.is_finite() => time.push(v),
                    Col::Time => bail!(
                        "{p}: line {line}, column {} ({:?}): the time is {v}; times must be finite numbers (seconds)",
                        c + 1,
                        names[c]
                    ),
                    Col::Channel(k) => {
                        let cfg = &self.rig.channels[k];
                        let x = v * cfg.sensitivity;
                        if x.is_finite() && x.abs() > f64::from(f32::MAX) {
                            bail!(
                                "{p}: line {line}, column {} ({:?}): {v:e} is beyond the range of the 32-bit floats \
                                 recordings hold (+-3.4e38, after the channel's sensitivity); check the file's scaling",
                                c + 1,
                                names[c]
                            );
                        }
                        chans[k].as_mut().expect("mapped").push(x as f32);
                    }
                    Col::Skip => {}
                }
            }
            if record.len() < names.len() {
                return Err(self.width_error(record, line));
            }
            rows += 1;
        }
        Ok((time, chans, rows))
    }

    /// A cell as a number, or an error naming the line and column (and a decimal comma).
    fn number(&self, f: &str, line: u64, c: usize) -> Result<f64> {
        f.parse().map_err(|_| {
            let what = if f.contains('\n') {
                "a quoted cell runs over several lines (a `\"` not closed?)".into()
            } else if decimal_comma(f) {
                format!("{f:?} is not a number: it looks written with a decimal comma; {DECIMAL_COMMA_HINT}")
            } else {
                format!("{f:?} is not a number")
            };
            anyhow::anyhow!(
                "{}: line {line}, column {} ({:?}): {what}",
                self.path.display(),
                c + 1,
                self.names[c]
            )
        })
    }

    /// The error for a row of another width than the header.
    fn width_error(&self, record: &::csv::StringRecord, line: u64) -> anyhow::Error {
        let (p, n, delim) = (self.path.display(), self.names.len(), self.delim);
        if record.len() < n {
            return anyhow::anyhow!(
                "{p}: line {line}: {} values but the header names {n} columns (truncated file?)",
                record.len()
            );
        }
        // `0,5,1,25` under a header `time,x`: decimal commas split every number in two.
        let commas = delim == b','
            && record.len() == 2 * n
            && record.iter().all(|f| {
                !f.trim().is_empty() && f.trim().bytes().all(|b| b.is_ascii_digit() || b == b'-')
            });
        if commas {
            return anyhow::anyhow!(
                "{p}: line {line}: {} values but the header names {n} columns: the numbers \
                 look written with decimal commas; {DECIMAL_COMMA_HINT}",
                record.len()
            );
        }
        anyhow::anyhow!(
            "{p}: line {line}: {} values but the header names {n} columns; quote cells \
             that contain the delimiter {:?}",
            record.len(),
            delim as char
        )
    }
}

/// Read a CSV file into a [`Recording`].
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let p = path.display();
    let text =
        std::fs::read_to_string(path).with_context(|| format!("{p}: cannot read as UTF-8 text"))?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let Some(header_line) = text.lines().find(|l| !skipped_line(l)) else {
        bail!("{p}: the file is empty (no header line)");
    };
    let delim = sniff_delimiter(header_line);
    let mut reader = ::csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .delimiter(delim)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut lines = Lines {
        text: text.as_bytes(),
        at: 0,
        line: 1,
    };
    let mut record = ::csv::StringRecord::new();
    // The next record that is not a blank or indented-comment line, and its line number.
    let mut next = |record: &mut ::csv::StringRecord| -> Result<Option<u64>> {
        loop {
            let from = reader.position().byte();
            if !reader
                .read_record(record)
                .with_context(|| format!("{p}: cannot read as CSV"))?
            {
                return Ok(None);
            }
            let line = lines.start_of(from);
            let blank = record.len() == 1 && record[0].trim().is_empty();
            if !(blank
                || record
                    .get(0)
                    .is_some_and(|f| f.trim_start().starts_with('#')))
            {
                return Ok(Some(line));
            }
        }
    };
    let Some(header_no) = next(&mut record)? else {
        bail!("{p}: the file is empty (no header line)");
    };
    let names: Vec<String> = record.iter().map(|s| cell(s).to_string()).collect();
    if let Some(c) = names.iter().position(|n| n.contains('\n')) {
        bail!(
            "{p}: line {header_no}, column {}: the header's quoted name runs over several lines \
             (a `\"` not closed?); close the quote on the header line",
            c + 1
        );
    }
    // Map columns.
    let mut time_col = None;
    let mut map: Vec<Option<usize>> = Vec::with_capacity(names.len()); // column -> rig channel index
    let mut skipped: Vec<usize> = Vec::new(); // columns naming no rig channel
    for (c, name) in names.iter().enumerate() {
        if TIME_COLUMNS.iter().any(|t| t.eq_ignore_ascii_case(name)) {
            if let Some(tc) = time_col {
                bail!(
                    "{p}: line {}: two time columns ({:?} and {name:?})",
                    header_no,
                    names[tc]
                );
            }
            time_col = Some(c);
            map.push(None);
            continue;
        }
        match rig
            .channels
            .iter()
            .position(|ch| ch.name.eq_ignore_ascii_case(name))
        {
            Some(k) => {
                if map.contains(&Some(k)) {
                    bail!("{p}: line {}: column {name:?} appears twice", header_no);
                }
                map.push(Some(k));
            }
            None => {
                skipped.push(c);
                map.push(None);
            }
        }
    }
    if map.iter().all(Option::is_none) {
        bail!(
            "{p}: line {}: the header names no channel (expected some of {:?})",
            header_no,
            rig.channel_names()
        );
    }
    let mut notes = Vec::new();
    if !skipped.is_empty() {
        let list: Vec<String> = skipped
            .iter()
            .map(|&c| format!("{} {:?}", c + 1, names[c]))
            .collect();
        notes.push(format!(
            "{WARNING}line {}: column(s) {} name no rig channel (the rig's channels are {:?}, plus an optional \
             time column {:?}); skipped",
            header_no,
            super::mat5::bounded(&list.join(", "), 1000),
            rig.channel_names(),
            TIME_COLUMNS
        ));
    }
    // Parse rows: the time column as f64, mapped channels as scaled f32, other columns not
    // kept; room for every line that can be a row, reserved once (see `memory::estimate`).
    let rows_hint = text.lines().filter(|l| !skipped_line(l)).count();
    let kinds: Vec<Col> = (0..names.len())
        .map(|c| match map[c] {
            Some(k) => Col::Channel(k),
            None if time_col == Some(c) => Col::Time,
            None => Col::Skip,
        })
        .collect();
    let ctx = RowContext {
        path,
        names: &names,
        kinds: &kinds,
        delim,
        rig,
    };
    let (time, mut chans, rows) = ctx.read_rows(&mut next, &mut record, rows_hint)?;
    if rows == 0 {
        bail!("{p}: the file has a header but no samples");
    }
    // Sample rate from the time column.
    let file_rate = match time_col {
        Some(tc) => {
            let t = &time;
            if rows < 2 {
                bail!("{p}: the time column needs at least two rows to give a sample rate");
            }
            let dt = (t[rows - 1] - t[0]) / (rows - 1) as f64;
            if !(dt.is_finite() && dt > 0.0) {
                bail!(
                    "{p}: column {:?}: time does not increase (first {}, last {})",
                    names[tc],
                    t[0],
                    t[rows - 1]
                );
            }
            for k in 1..rows {
                let step = t[k] - t[k - 1];
                if (step - dt).abs() > 0.01 * dt + 1e-12 {
                    bail!(
                        "{p}: column {:?}: uneven time step {step} s before data row {k} (the mean step is {dt} s); \
                         rigmon needs uniformly sampled data",
                        names[tc]
                    );
                }
            }
            Some((1.0 / dt, format!("time column {:?}", names[tc])))
        }
        None => None,
    };
    let (sample_rate, note) = resolve_sample_rate(path, file_rate, &rig.acquisition, opts)?;
    // Build channels in rig order.
    let mut channels = Vec::new();
    let mut tacho = None;
    notes.push(note);
    for (k, cfg) in rig.channels.iter().enumerate() {
        let Some(samples) = chans[k].take() else {
            notes.push(format!("no column for rig channel {}", cfg.name));
            continue;
        };
        match cfg.kind {
            ChannelKind::Acceleration => channels.push(Channel {
                name: cfg.name.clone(),
                axis: cfg.axis.clone(),
                unit: cfg.unit.to_string(),
                samples,
            }),
            ChannelKind::Tacho => {
                tacho = Some(Tacho::Analog {
                    samples,
                    unit: cfg.unit.to_string(),
                })
            }
        }
    }
    if channels.is_empty() {
        bail!(
            "{p}: no acceleration column; the rig's acceleration channels are {:?}",
            rig.acceleration_channels()
                .map(|c| &c.name)
                .collect::<Vec<_>>()
        );
    }
    let rec = Recording {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: opts.rpm,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: p.to_string(),
            format: "csv".into(),
            notes,
        },
        metadata: BTreeMap::new(),
    };
    check_classifier_channel(path, rig, &rec, "column")?;
    Ok(rec)
}
