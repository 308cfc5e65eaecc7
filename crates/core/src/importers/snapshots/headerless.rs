//! Headerless CSV captures, FEMTO PRONOSTIA's layout: no header line; each line holds the
//! capture clock (hour, minute, second, microsecond) and then one value per rig acceleration
//! channel in the rig file's order, or only the values (no clock). Cells are separated by `,`,
//! `;` or a tab, taken from each file's first line (FEMTO mixes them within one bearing's
//! folder); blank lines and lines starting with `#` are
//! skipped. Values are multiplied by the channel's sensitivity; a cell that is not a finite
//! number is an error naming the file, the line and the column.

use super::clock::time_of_day;
use anyhow::{bail, Context, Result};
use std::io::Read;
use std::path::Path;

/// Clock columns before the channels: hour, minute, second, microsecond.
pub const CLOCK_COLUMNS: usize = 4;

/// How a headerless capture file is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// The first four columns are the capture clock.
    pub clock: bool,
    /// Channels after the clock.
    pub channels: usize,
}

impl Layout {
    /// Cells per line.
    pub fn columns(&self) -> usize {
        self.channels + if self.clock { CLOCK_COLUMNS } else { 0 }
    }
}

fn delimiter_of(line: &str) -> char {
    [';', '\t']
        .into_iter()
        .find(|d| line.contains(*d))
        .unwrap_or(',')
}

fn cells(line: &str, d: char) -> impl Iterator<Item = &str> {
    line.split(d).map(str::trim)
}

fn skipped(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// The layout from a file's first line for a rig with `channels` acceleration channels:
/// `Ok(None)` when a cell is not a number (a header line: the file is an ordinary CSV).
pub fn sniff(path: &Path, line: &str, channels: usize) -> Result<Option<Layout>> {
    let d = delimiter_of(line);
    if cells(line, d).any(|c| c.parse::<f64>().is_err()) {
        return Ok(None);
    }
    let n = cells(line, d).count();
    let clock = match n {
        _ if n == channels + CLOCK_COLUMNS => true,
        _ if n == channels => false,
        _ => bail!(
            "{}: a headerless CSV with {n} columns, but the rig file has {channels} acceleration \
             channel(s): expected {} (hour, minute, second, microsecond, then the channels in the \
             rig file's order, as FEMTO PRONOSTIA writes them) or {channels} (the channels only); \
             list the file's channels under [[channels]] in that order",
            path.display(),
            channels + CLOCK_COLUMNS
        ),
    };
    Ok(Some(Layout { clock, channels }))
}

/// The first line of a file that is not blank or a comment (from its first 4 KiB).
pub fn first_line(path: &Path) -> Result<String> {
    let mut head = Vec::with_capacity(4096);
    std::fs::File::open(path)
        .and_then(|f| f.take(4096).read_to_end(&mut head))
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let text = String::from_utf8_lossy(&head);
    match text.lines().find(|l| !skipped(l)) {
        Some(l) => Ok(l.to_string()),
        None => bail!(
            "{}: no data line in its first 4 KiB (the capture is empty)",
            path.display()
        ),
    }
}

fn number(path: &Path, line_no: usize, col: usize, cell: &str) -> Result<f64> {
    match cell.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => bail!(
            "{}: line {line_no}, column {}: {cell:?} is not a finite number",
            path.display(),
            col + 1
        ),
    }
}

/// The capture clock of a file (its first line), time of day in s.
pub fn read_clock(path: &Path, layout: &Layout) -> Result<f64> {
    let line = first_line(path)?;
    let d = delimiter_of(&line);
    let n = cells(&line, d).count();
    if !layout.clock || n != layout.columns() {
        bail!(
            "{}: line 1 has {n} cells, but the series' first capture has {}",
            path.display(),
            layout.columns()
        );
    }
    let mut v = [0.0; CLOCK_COLUMNS];
    for (i, c) in cells(&line, d).take(CLOCK_COLUMNS).enumerate() {
        v[i] = number(path, 1, i, c)?;
    }
    Ok(time_of_day(v[0], v[1], v[2], v[3]))
}

/// A capture's samples: one vector per channel, each value times its sensitivity.
pub fn read_capture(path: &Path, layout: &Layout, sensitivity: &[f64]) -> Result<Vec<Vec<f32>>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let skip = if layout.clock { CLOCK_COLUMNS } else { 0 };
    let d = text.lines().find(|l| !skipped(l)).map_or(',', delimiter_of);
    let mut out: Vec<Vec<f32>> = (0..layout.channels)
        .map(|_| Vec::with_capacity(text.len() / 24))
        .collect();
    for (i, line) in text.lines().enumerate() {
        if skipped(line) {
            continue;
        }
        let mut n = 0;
        for (col, cell) in cells(line, d).enumerate() {
            n += 1;
            if col < skip || col >= layout.columns() {
                continue;
            }
            let x = number(path, i + 1, col, cell)? * sensitivity[col - skip];
            out[col - skip].push(x as f32);
        }
        if n != layout.columns() {
            bail!(
                "{}: line {}: {n} cells, but the capture's first line has {}",
                path.display(),
                i + 1,
                layout.columns()
            );
        }
    }
    if out[0].is_empty() {
        bail!("{}: the capture holds no samples", path.display());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn femto_lines_are_read_with_either_separator_and_bad_cells_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("acc_00001.csv");
        std::fs::write(&p, "9;39;39;65664;0.5;-0.25\n9;39;39;65703;1;2\n").unwrap();
        let line = first_line(&p).unwrap();
        let l = sniff(&p, &line, 2).unwrap().unwrap();
        assert_eq!((l.clock, l.columns()), (true, 6));
        assert!((read_clock(&p, &l).unwrap() - 34779.065664).abs() < 1e-9);
        let c = read_capture(&p, &l, &[1.0, 2.0]).unwrap();
        assert_eq!(c, vec![vec![0.5, 1.0], vec![-0.5, 4.0]]);
        // A header line makes it an ordinary CSV; a wrong column count is named.
        assert_eq!(sniff(&p, "h,m,s,us,x,y", 2).unwrap(), None);
        let e = sniff(&p, "1,2,3", 2).unwrap_err().to_string();
        assert!(e.contains("3 columns") && e.contains("expected 6"), "{e}");
        std::fs::write(&p, "9,39,39,65664,0.5,-0.25\n9,39,39,65703,nan,2\n").unwrap();
        let e = read_capture(&p, &l, &[1.0, 1.0]).unwrap_err();
        assert!(e.to_string().contains("line 2, column 5"), "{e}");
    }
}
