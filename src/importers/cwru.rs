//! Case Western Reserve University bearing data (`.mat`): variables `X<nnn>_DE_time`,
//! `X<nnn>_FE_time`, `X<nnn>_BA_time` (vectors in g) and `X<nnn>RPM`.
//!
//! Channels DE/FE/BA are matched to the rig's channels by name (case-insensitive). The sample
//! rate is not stored: it comes from `--sample-rate`, else the rig file, else CWRU's own
//! catalogue by file number ([`catalogue`]; the number is taken from the variable names, so a
//! renamed file still works).

use super::mat5::{MatFile, MatValue};
use super::{check_classifier_channel, resolve_sample_rate, ImportOptions};
use crate::config::RigConfig;
use crate::recording::{Channel, Provenance, Recording};
use anyhow::{bail, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Sensor positions CWRU records.
pub const POSITIONS: [&str; 3] = ["DE", "FE", "BA"];

/// What CWRU's catalogue says about a drive-end file number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatalogueEntry {
    pub sample_rate: f64,
    /// `healthy`, `inner_race`, `outer_race` or `ball`.
    pub label: &'static str,
}

// (first, last, rate, label) ranges from CWRU's catalogue (see ../shared/data/README.md).
const CATALOGUE: &[(u32, u32, f64, &str)] = &[
    // Normal baselines, 48 kHz.
    (97, 100, 48_000.0, "healthy"),
    // 12 kHz drive-end faults.
    (105, 108, 12_000.0, "inner_race"),
    (169, 172, 12_000.0, "inner_race"),
    (209, 212, 12_000.0, "inner_race"),
    (3001, 3004, 12_000.0, "inner_race"),
    (118, 121, 12_000.0, "ball"),
    (185, 188, 12_000.0, "ball"),
    (222, 225, 12_000.0, "ball"),
    (3005, 3008, 12_000.0, "ball"),
    (130, 133, 12_000.0, "outer_race"),
    (197, 200, 12_000.0, "outer_race"),
    (234, 237, 12_000.0, "outer_race"),
    (144, 147, 12_000.0, "outer_race"),
    (246, 249, 12_000.0, "outer_race"),
    (156, 156, 12_000.0, "outer_race"),
    (158, 160, 12_000.0, "outer_race"),
    (258, 261, 12_000.0, "outer_race"),
    // 48 kHz drive-end faults.
    (109, 112, 48_000.0, "inner_race"),
    (174, 177, 48_000.0, "inner_race"),
    (213, 215, 48_000.0, "inner_race"),
    (217, 217, 48_000.0, "inner_race"),
    (122, 125, 48_000.0, "ball"),
    (189, 192, 48_000.0, "ball"),
    (226, 229, 48_000.0, "ball"),
    (135, 138, 48_000.0, "outer_race"),
    (201, 204, 48_000.0, "outer_race"),
    (238, 241, 48_000.0, "outer_race"),
    (148, 151, 48_000.0, "outer_race"),
    (250, 253, 48_000.0, "outer_race"),
    (161, 164, 48_000.0, "outer_race"),
    (262, 265, 48_000.0, "outer_race"),
];

/// CWRU's catalogue entry for a file number (drive-end and normal sets only).
pub fn catalogue(number: u32) -> Option<CatalogueEntry> {
    CATALOGUE
        .iter()
        .find(|(a, b, _, _)| (*a..=*b).contains(&number))
        .map(|&(_, _, sample_rate, label)| CatalogueEntry { sample_rate, label })
}

/// A CWRU variable name split up: `X105_DE_time` -> (105, Some("DE")), `X105RPM` -> (105, None).
pub fn parse_var_name(name: &str) -> Option<(u32, Option<&str>)> {
    let rest = name.strip_prefix('X')?;
    let digits = rest.chars().take_while(char::is_ascii_digit).count();
    if digits == 0 {
        return None;
    }
    let number: u32 = rest[..digits].parse().ok()?;
    let tail = &rest[digits..];
    if tail == "RPM" {
        return Some((number, None));
    }
    let pos = tail.strip_prefix('_')?.strip_suffix("_time")?;
    POSITIONS
        .iter()
        .find(|&&p| p == pos)
        .map(|&p| (number, Some(p)))
}

/// Does this MAT file look like a CWRU recording?
pub fn is_cwru(mat: &MatFile) -> bool {
    mat.vars
        .iter()
        .any(|v| matches!(parse_var_name(&v.name), Some((_, Some(_)))))
}

/// Build a [`Recording`] from a parsed CWRU MAT file.
pub fn from_mat(
    path: &Path,
    mat: &MatFile,
    rig: &RigConfig,
    opts: &ImportOptions,
) -> Result<Recording> {
    let p = path.display();
    let mut notes = Vec::new();
    // Which record number? Usually exactly one; some public files carry a second record's
    // variables too (then prefer the number in the file name, else the first one).
    let numbers: BTreeSet<u32> = mat
        .vars
        .iter()
        .filter_map(|v| parse_var_name(&v.name))
        .filter(|(_, pos)| pos.is_some())
        .map(|(n, _)| n)
        .collect();
    let number = if numbers.len() == 1 {
        *numbers.iter().next().unwrap()
    } else {
        let stem_number: Option<u32> = path
            .file_stem()
            .and_then(|s| s.to_str())
            .map(|s| {
                s.chars()
                    .take_while(char::is_ascii_digit)
                    .collect::<String>()
            })
            .and_then(|d| d.parse().ok());
        let first = mat
            .vars
            .iter()
            .find_map(|v| {
                parse_var_name(&v.name)
                    .filter(|(_, pos)| pos.is_some())
                    .map(|(n, _)| n)
            })
            .unwrap();
        let chosen = stem_number.filter(|n| numbers.contains(n)).unwrap_or(first);
        notes.push(format!("file holds records {numbers:?}; used {chosen}"));
        chosen
    };

    // Channels: rig acceleration channels named DE/FE/BA, in rig order.
    let rig_positions: Vec<_> = rig
        .acceleration_channels()
        .filter_map(|c| {
            POSITIONS
                .iter()
                .find(|p| p.eq_ignore_ascii_case(&c.name))
                .map(|p| (c, *p))
        })
        .collect();
    if rig_positions.is_empty() {
        bail!(
            "{p}: this is a CWRU file (record {number}) but none of the rig's acceleration channels {:?} is named DE, FE or BA; \
             use a rig file whose channels are named after the CWRU sensors (e.g. config/cwru-de.toml)",
            rig.acceleration_channels().map(|c| c.name.as_str()).collect::<Vec<_>>()
        );
    }
    let mut channels = Vec::new();
    let mut first_len: Option<(String, usize)> = None;
    for (cfg, pos) in rig_positions {
        let var = format!("X{number:03}_{pos}_time");
        let Some(value) = mat.get(&var) else {
            notes.push(format!(
                "no {var} in the file: rig channel {} left out",
                cfg.name
            ));
            continue;
        };
        let samples = vector(path, &var, value)?;
        if let Some((other, n)) = &first_len {
            if *n != samples.len() {
                bail!("{p}: {var} has {} samples but {other} has {n}; CWRU channels must have the same length", samples.len());
            }
        } else {
            first_len = Some((var.clone(), samples.len()));
        }
        let k = cfg.sensitivity;
        channels.push(Channel {
            name: cfg.name.clone(),
            axis: cfg.axis.clone(),
            unit: cfg.unit.clone(),
            samples: samples.iter().map(|&x| (x * k) as f32).collect(),
        });
    }
    if let Some(c) = rig.classifier_channel() {
        if let Some(pos) = POSITIONS.iter().find(|q| q.eq_ignore_ascii_case(&c.name)) {
            let var = format!("X{number:03}_{pos}_time");
            if mat.get(&var).is_none() {
                bail!(
                    "{p}: missing variable {var}: rig channel {} feeds the classifier (features.classifier_axis = {:?}); \
                     the file holds: {}",
                    c.name,
                    rig.features.classifier_axis,
                    mat.summary()
                );
            }
        }
    }
    if channels.is_empty() {
        bail!(
            "{p}: missing variable: none of {} found for the rig's channels; the file holds: {}",
            POSITIONS
                .map(|pos| format!("X{number:03}_{pos}_time"))
                .join(", "),
            mat.summary()
        );
    }

    // Speed.
    let rpm_var = format!("X{number:03}RPM");
    let rpm = match (opts.rpm, mat.get(&rpm_var)) {
        (Some(r), _) => {
            notes.push(format!("rpm {r} from --rpm"));
            Some(r)
        }
        (None, Some(v)) => match v.as_scalar() {
            Some(r) if r.is_finite() && r > 0.0 => Some(r),
            Some(r) => bail!("{p}: {rpm_var} = {r} is not a valid speed; pass --rpm R"),
            None => bail!(
                "{p}: wrong shape: {rpm_var} is {}, expected a single number (1x1)",
                v.describe()
            ),
        },
        (None, None) => {
            notes.push(format!(
                "no {rpm_var} in the file: speed unknown (pass --rpm R to set it)"
            ));
            None
        }
    };

    // Sample rate.
    let entry = catalogue(number);
    let file_rate = entry.map(|e| (e.sample_rate, format!("CWRU catalogue (file {number})")));
    let (sample_rate, note) = resolve_sample_rate(path, file_rate, rig, opts).map_err(|e| {
        if entry.is_none() && opts.sample_rate.is_none() && rig.acquisition.sample_rate_hz.is_none() {
            anyhow::anyhow!(
                "{p}: the sample rate is unknown: CWRU files do not store it and record {number} is not in rigmon's \
                 copy of the CWRU catalogue; pass --sample-rate HZ (12000 or 48000 for CWRU)"
            )
        } else {
            e
        }
    })?;
    notes.push(note);

    let mut metadata = BTreeMap::new();
    metadata.insert("cwru_record".to_string(), number.to_string());
    if let Some(e) = entry {
        metadata.insert("label".to_string(), e.label.to_string());
    }
    let rec = Recording {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho: None,
        rpm,
        provenance: Provenance {
            source_path: path.display().to_string(),
            format: "cwru-mat".into(),
            notes,
        },
        metadata,
    };
    check_classifier_channel(
        path,
        rig,
        &rec,
        &format!("variable X{number:03}_<pos>_time"),
    )?;
    Ok(rec)
}

/// A signal variable as a vector; errors name the variable and say what shape it has.
pub(crate) fn vector<'a>(path: &Path, var: &str, value: &'a MatValue) -> Result<&'a [f64]> {
    match value {
        MatValue::Numeric { imag: Some(_), .. } => {
            bail!("{}: {var} is complex ({}); expected real samples", path.display(), value.describe())
        }
        MatValue::Numeric { .. } => match value.as_vector() {
            Some([]) => bail!("{}: {var} is empty ({})", path.display(), value.describe()),
            Some(v) => Ok(v),
            None => bail!(
                "{}: wrong shape: {var} is a {} matrix; expected a column vector (n x 1) of samples",
                path.display(),
                value.describe()
            ),
        },
        other => bail!("{}: wrong shape: {var} is {}; expected a numeric column vector (n x 1)", path.display(), other.describe()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_catalogue() {
        assert_eq!(parse_var_name("X097_DE_time"), Some((97, Some("DE"))));
        assert_eq!(parse_var_name("X3001_BA_time"), Some((3001, Some("BA"))));
        assert_eq!(parse_var_name("X105RPM"), Some((105, None)));
        assert_eq!(parse_var_name("X105_XX_time"), None);
        assert_eq!(parse_var_name("ans"), None);
        assert_eq!(catalogue(97).unwrap().sample_rate, 48_000.0);
        assert_eq!(catalogue(105).unwrap().sample_rate, 12_000.0);
        assert_eq!(catalogue(130).unwrap().label, "outer_race");
        assert_eq!(catalogue(217).unwrap().sample_rate, 48_000.0);
        assert_eq!(catalogue(216), None);
        // Ranges never overlap.
        for (i, a) in CATALOGUE.iter().enumerate() {
            for b in &CATALOGUE[i + 1..] {
                assert!(a.1 < b.0 || b.1 < a.0, "{a:?} overlaps {b:?}");
            }
        }
    }
}
