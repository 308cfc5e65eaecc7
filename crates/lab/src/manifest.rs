//! The `labels.csv` manifest that names labelled recordings for training, evaluation,
//! calibration and adaptation: `path,label` columns, relative paths relative to the CSV, an
//! optional `sample_rate_hz` column for files that do not carry their rate, optional
//! `start_s`/`end_s` columns to use part of a recording, an optional `rpm` column with a
//! recording's nominal speed (a hint the speed stage checks against the vibration).

use crate::importers::ImportOptions;
use crate::vocabulary::Condition;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// One row of a manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct ManifestEntry {
    /// Resolved path (relative paths joined to the CSV's folder).
    pub path: PathBuf,
    /// As written in the CSV.
    pub path_text: String,
    pub label: String,
    /// 1-based line in the CSV.
    pub line: usize,
    /// The row's `sample_rate_hz` (when the column exists and the cell is not empty) and where
    /// it was written ("labels.csv line 4, column sample_rate_hz").
    pub sample_rate: Option<(f64, String)>,
    /// The row's `start_s`/`end_s` (either may be empty): only feature windows wholly inside
    /// this stretch of the recording are used, so one file can be cut into parts (adapt on
    /// one half of a healthy record, score the other).
    pub span: Option<(f64, f64)>,
    /// The row's `rpm` (when the column exists and the cell is not empty): the nominal shaft
    /// speed, and where it was written ("labels.csv line 4, column rpm"). A hint, not an
    /// override: the vibration decides.
    pub nominal_rpm: Option<(f64, String)>,
}

impl ManifestEntry {
    /// How reports name this row: the path as written, with its span when it has one.
    pub fn display_name(&self) -> String {
        match self.span {
            None => self.path_text.clone(),
            Some((a, b)) if b.is_finite() => format!("{} [{a}-{b} s]", self.path_text),
            Some((a, _)) => format!("{} [{a} s-]", self.path_text),
        }
    }

    /// Whether a feature window `[t_start, t_end]` (s) lies within the row's span.
    pub fn keeps_window(&self, t_start: f64, t_end: f64) -> bool {
        self.span
            .is_none_or(|(a, b)| t_start >= a - 1e-9 && t_end <= b + 1e-9)
    }

    /// How to import this row's file: its declared sample rate, if any (the importers' one rule
    /// then settles it against the file and the rig file), and its nominal speed as a hint.
    pub fn import_options(&self) -> ImportOptions {
        ImportOptions {
            declared_sample_rate: self.sample_rate.clone(),
            nominal_rpm: self.nominal_rpm.clone(),
            ..Default::default()
        }
    }
}

/// `--data` may name a dataset folder (holding `labels.csv`) or the CSV itself.
pub fn manifest_path(data: &Path) -> PathBuf {
    if data.is_dir() {
        data.join("labels.csv")
    } else {
        data.to_path_buf()
    }
}

/// Read a manifest. The header must have `path` and `label` columns; an optional
/// `sample_rate_hz` column gives a row's rate, `rpm` its nominal speed (empty cell: none);
/// other columns are ignored.
pub fn read_manifest(csv: &Path) -> Result<Vec<ManifestEntry>> {
    let text = std::fs::read_to_string(csv).with_context(|| {
        format!("cannot read manifest {} (expected a CSV with header `path,label`, or a dataset folder holding labels.csv)", csv.display())
    })?;
    parse_manifest(&text, csv)
}

/// Parse manifest text; `csv` is used to resolve relative paths and to name errors.
pub fn parse_manifest(text: &str, csv: &Path) -> Result<Vec<ManifestEntry>> {
    let base = csv.parent().unwrap_or(Path::new("."));
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (hline, header) = lines.next().with_context(|| {
        format!(
            "{}: empty manifest; expected a header `path,label`",
            csv.display()
        )
    })?;
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| {
        cols.iter()
            .position(|c| c.eq_ignore_ascii_case(name))
            .with_context(|| {
                format!(
                    "{}:{}: header {:?} has no `{name}` column; the header must be `path,label`",
                    csv.display(),
                    hline + 1,
                    header
                )
            })
    };
    let (ip, il) = (find("path")?, find("label")?);
    let ir = cols
        .iter()
        .position(|c| c.eq_ignore_ascii_case("sample_rate_hz"));
    let (i_start, i_end) = (
        cols.iter().position(|c| c.eq_ignore_ascii_case("start_s")),
        cols.iter().position(|c| c.eq_ignore_ascii_case("end_s")),
    );
    let i_rpm = cols.iter().position(|c| c.eq_ignore_ascii_case("rpm"));
    let csv_name = csv
        .file_name()
        .map_or_else(|| csv.display().to_string(), |n| n.to_string_lossy().into());
    let mut out = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != cols.len() {
            bail!(
                "{}:{}: {} fields but the header has {} ({:?})",
                csv.display(),
                i + 1,
                fields.len(),
                cols.len(),
                line
            );
        }
        let (p, label) = (fields[ip].trim_matches('"'), fields[il].trim_matches('"'));
        if !Condition::NAMES.contains(&label) {
            bail!(
                "{}:{}: label {:?} is not one of {}",
                csv.display(),
                i + 1,
                label,
                Condition::NAMES.join(", ")
            );
        }
        let sample_rate = match ir.map(|k| fields[k].trim_matches('"')) {
            None | Some("") => None,
            Some(text) => match text.parse::<f64>() {
                Ok(fs) if fs.is_finite() && fs > 0.0 => Some((
                    fs,
                    format!("{csv_name} line {}, column sample_rate_hz", i + 1),
                )),
                _ => bail!(
                    "{}:{}: sample_rate_hz {:?} is not a positive number of Hz (leave the cell empty \
                     when the file carries its rate or the rig file's acquisition.sample_rate_hz applies)",
                    csv.display(),
                    i + 1,
                    text
                ),
            },
        };
        let seconds = |col: Option<usize>, name: &str| -> Result<Option<f64>> {
            match col.map(|k| fields[k].trim_matches('"')) {
                None | Some("") => Ok(None),
                Some(text) => match text.parse::<f64>() {
                    Ok(t) if t.is_finite() && t >= 0.0 => Ok(Some(t)),
                    _ => bail!(
                        "{}:{}: {name} {:?} is not a time in seconds >= 0 (leave it empty for the whole recording)",
                        csv.display(),
                        i + 1,
                        text
                    ),
                },
            }
        };
        let nominal_rpm = match i_rpm.map(|k| fields[k].trim_matches('"')) {
            None | Some("") => None,
            Some(text) => match text.parse::<f64>() {
                Ok(rpm) if rpm.is_finite() && rpm > 0.0 => {
                    Some((rpm, format!("{csv_name} line {}, column rpm", i + 1)))
                }
                _ => bail!(
                    "{}:{}: rpm {:?} is not a positive shaft speed in rpm (leave the cell empty when the \
                     nominal speed is unknown)",
                    csv.display(),
                    i + 1,
                    text
                ),
            },
        };
        let span = match (seconds(i_start, "start_s")?, seconds(i_end, "end_s")?) {
            (None, None) => None,
            (a, b) => {
                let (a, b) = (a.unwrap_or(0.0), b.unwrap_or(f64::INFINITY));
                if b <= a {
                    bail!(
                        "{}:{}: end_s {b} is not after start_s {a}",
                        csv.display(),
                        i + 1
                    );
                }
                Some((a, b))
            }
        };
        let pb = Path::new(p);
        let path = if pb.is_absolute() {
            pb.to_path_buf()
        } else {
            base.join(pb)
        };
        out.push(ManifestEntry {
            path,
            path_text: p.to_string(),
            label: label.to_string(),
            line: i + 1,
            sample_rate,
            span,
            nominal_rpm,
        });
    }
    if out.is_empty() {
        bail!("{}: the manifest lists no recordings", csv.display());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manifest_resolves_relative_paths_and_names_bad_lines() {
        let csv = Path::new("/data/set/labels.csv");
        let m = parse_manifest("path,label\na.mcap,healthy\n/abs/b.mat,inner_race\n", csv).unwrap();
        assert_eq!(m[0].path, Path::new("/data/set/a.mcap"));
        assert_eq!(m[1].path, Path::new("/abs/b.mat"));
        assert_eq!(m[1].line, 3);
        let e = parse_manifest("path,label\na.mcap,broken\n", csv)
            .unwrap_err()
            .to_string();
        assert!(e.contains("labels.csv:2") && e.contains("broken"), "{e}");
        let e = parse_manifest("file,label\n", csv).unwrap_err().to_string();
        assert!(e.contains("no `path` column"), "{e}");
    }

    #[test]
    fn manifest_sample_rate_column_is_optional_per_row() {
        let csv = Path::new("/data/set/labels.csv");
        let m = parse_manifest(
            "path,label,sample_rate_hz\na.csv,healthy,12000\nb.mat,ball,\n",
            csv,
        )
        .unwrap();
        assert_eq!(
            m[0].sample_rate,
            Some((
                12000.0,
                "labels.csv line 2, column sample_rate_hz".to_string()
            ))
        );
        assert_eq!(
            m[0].import_options().declared_sample_rate.map(|d| d.0),
            Some(12000.0)
        );
        assert_eq!(m[1].sample_rate, None);
        let e = parse_manifest("path,label,sample_rate_hz\na.csv,healthy,12k\n", csv)
            .unwrap_err()
            .to_string();
        assert!(e.contains("labels.csv:2") && e.contains("\"12k\""), "{e}");
        let e = parse_manifest("path,label,sample_rate_hz\na.csv,healthy,-5\n", csv)
            .unwrap_err()
            .to_string();
        assert!(e.contains("positive"), "{e}");
    }

    #[test]
    fn manifest_rpm_column_is_an_optional_hint_per_row() {
        let csv = Path::new("/data/hit/labels.csv");
        let m = parse_manifest(
            "path,label,rpm\nNormal_600.mat,healthy,600\nIR2_900.mat,inner_race,\n",
            csv,
        )
        .unwrap();
        let hint = Some((600.0, "labels.csv line 2, column rpm".to_string()));
        assert_eq!(m[0].nominal_rpm, hint);
        let opts = m[0].import_options();
        assert_eq!(opts.nominal_rpm, hint);
        assert_eq!(
            opts.rpm, None,
            "a nominal speed is a hint, not the --rpm override"
        );
        assert_eq!(m[1].nominal_rpm, None);
        assert_eq!(m[1].import_options().nominal_rpm, None);
        let m = parse_manifest("path,label\na.mat,healthy\n", csv).unwrap();
        assert_eq!(
            m[0].nominal_rpm, None,
            "manifests without the column still work"
        );
        for bad in ["fast", "-600", "0", "nan"] {
            let e = parse_manifest(&format!("path,label,rpm\na.mat,healthy,{bad}\n"), csv)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("labels.csv:2") && e.contains(&format!("rpm \"{bad}\"")),
                "{e}"
            );
        }
    }

    #[test]
    fn manifest_spans_cut_a_recording_and_bad_spans_name_their_line() {
        let csv = Path::new("/data/labels.csv");
        let m = parse_manifest(
            "path,label,start_s,end_s\na.mat,healthy,0,2.5\na.mat,healthy,2.5,\nb.mat,ball,,\n",
            csv,
        )
        .unwrap();
        assert_eq!(m[0].span, Some((0.0, 2.5)));
        assert_eq!(m[1].span, Some((2.5, f64::INFINITY)));
        assert_eq!(m[2].span, None);
        let e = parse_manifest("path,label,start_s,end_s\na.mat,healthy,3,1\n", csv).unwrap_err();
        assert!(
            e.to_string().contains(":2: end_s 1 is not after start_s 3"),
            "{e}"
        );
        let e = parse_manifest("path,label,start_s\na.mat,healthy,soon\n", csv).unwrap_err();
        assert!(e.to_string().contains("start_s \"soon\""), "{e}");
    }
}
