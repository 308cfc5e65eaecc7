//! Case Western Reserve University bearing data (`.mat`): variables `X<nnn>_DE_time`,
//! `X<nnn>_FE_time`, `X<nnn>_BA_time` (vectors in g) and `X<nnn>RPM`.
//!
//! Channels DE/FE/BA are matched to the rig's channels by name (case-insensitive). The sample
//! rate is not stored: it comes from CWRU's own catalogue by record number ([`catalogue`]: the
//! normal baselines, drive end at 12 and 48 kHz, fan end at 12 kHz; the number is taken from the
//! variable names, so a renamed file still works), by the one rule of
//! [`resolve_sample_rate`](super::resolve_sample_rate). The speed `X<nnn>RPM` is side data:
//! read in any MATLAB class, a warning when it cannot be.

use super::mat5::{MatDirectory, MatFile, MatValue};
use super::{check_classifier_channel, resolve_sample_rate, ImportOptions, WARNING};
use crate::config::RigConfig;
use crate::recording::{Channel, Provenance, Recording};
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Sensor positions CWRU records.
pub const POSITIONS: [&str; 3] = ["DE", "FE", "BA"];

/// Motor loads of the CWRU tables (hp, the column index of [`Row::records`]) and the approximate
/// speed CWRU publishes for each.
pub const LOADS_HP_RPM: [(u8, f64); 4] = [(0, 1797.0), (1, 1772.0), (2, 1750.0), (3, 1730.0)];

/// What CWRU's catalogue says about one record number.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatalogueEntry {
    pub record: u32,
    pub sample_rate: f64,
    /// `healthy`, `inner_race`, `outer_race` or `ball` (of the faulty bearing).
    pub label: &'static str,
    /// Sensor position at the bearing that carries the seeded fault: `DE` (SKF 6205) or `FE`
    /// (SKF 6203); `None` for the normal baselines.
    pub faulty_bearing: Option<&'static str>,
    /// Fault diameter, inches (0 for the normal baselines).
    pub fault_size_in: f64,
    /// Outer-race fault position relative to the load zone (3, 6 or 12 o'clock).
    pub outer_race_clock: Option<u8>,
    /// Motor load, hp.
    pub load_hp: u8,
    /// CWRU's approximate motor speed for that load, rpm (files store their own `X<nnn>RPM`).
    pub nominal_rpm: f64,
}

/// One row of a CWRU table: a condition and its record numbers at 0, 1, 2 and 3 hp (0 = no
/// record at that load).
struct Row {
    rate: f64,
    end: Option<&'static str>,
    label: &'static str,
    mils: u16,
    clock: u8,
    records: [u32; 4],
}

const fn row(
    rate: f64,
    end: Option<&'static str>,
    label: &'static str,
    mils: u16,
    clock: u8,
    records: [u32; 4],
) -> Row {
    Row {
        rate,
        end,
        label,
        mils,
        clock,
        records,
    }
}

const K12: f64 = 12_000.0;
const K48: f64 = 48_000.0;
const DE: Option<&str> = Some("DE");
const FE: Option<&str> = Some("FE");
const IR: &str = Condition::InnerRace.as_str();
const B: &str = Condition::Ball.as_str();
const OR: &str = Condition::OuterRace.as_str();

/// The CWRU Bearing Data Center's tables (pages "Normal Baseline Data", "12k Drive End Bearing
/// Fault Data", "48k Drive End Bearing Fault Data", "12k Fan End Bearing Fault Data"), by record
/// number. Transcribed from two independent public copies of those tables, which agree on every
/// number, rate and condition: the `metadata.txt` of the Litchiware/cwru loader (record URL per
/// table, load and fault) and the `metainfo.csv` of yanncalec/dpmhm (rate, load, location,
/// fault, size per record); the record numbers of the 23 fan-end and 7 drive-end files in
/// ../shared/data were checked against their `X<nnn>` variable names. One correction: dpmhm lists
/// the normal baselines at 12 kHz, but record 97 is sampled at 48 kHz (its envelope shows the
/// shaft line at 1796/60 Hz only at 48 kHz; see ../shared/data/README.md), as CWRU's normal
/// page says.
const TABLE: &[Row] = &[
    // Normal baselines (both bearings healthy), 48 kHz.
    row(
        K48,
        None,
        Condition::Healthy.as_str(),
        0,
        0,
        [97, 98, 99, 100],
    ),
    // 12 kHz, fault on the drive-end bearing.
    row(K12, DE, IR, 7, 0, [105, 106, 107, 108]),
    row(K12, DE, IR, 14, 0, [169, 170, 171, 172]),
    row(K12, DE, IR, 21, 0, [209, 210, 211, 212]),
    row(K12, DE, IR, 28, 0, [3001, 3002, 3003, 3004]),
    row(K12, DE, B, 7, 0, [118, 119, 120, 121]),
    row(K12, DE, B, 14, 0, [185, 186, 187, 188]),
    row(K12, DE, B, 21, 0, [222, 223, 224, 225]),
    row(K12, DE, B, 28, 0, [3005, 3006, 3007, 3008]),
    row(K12, DE, OR, 7, 6, [130, 131, 132, 133]),
    row(K12, DE, OR, 14, 6, [197, 198, 199, 200]),
    row(K12, DE, OR, 21, 6, [234, 235, 236, 237]),
    row(K12, DE, OR, 7, 3, [144, 145, 146, 147]),
    row(K12, DE, OR, 21, 3, [246, 247, 248, 249]),
    row(K12, DE, OR, 7, 12, [156, 158, 159, 160]),
    row(K12, DE, OR, 21, 12, [258, 259, 260, 261]),
    // 48 kHz, fault on the drive-end bearing.
    row(K48, DE, IR, 7, 0, [109, 110, 111, 112]),
    row(K48, DE, IR, 14, 0, [174, 175, 176, 177]),
    row(K48, DE, IR, 21, 0, [213, 214, 215, 217]),
    row(K48, DE, B, 7, 0, [122, 123, 124, 125]),
    row(K48, DE, B, 14, 0, [189, 190, 191, 192]),
    row(K48, DE, B, 21, 0, [226, 227, 228, 229]),
    row(K48, DE, OR, 7, 6, [135, 136, 137, 138]),
    row(K48, DE, OR, 14, 6, [201, 202, 203, 204]),
    row(K48, DE, OR, 21, 6, [238, 239, 240, 241]),
    row(K48, DE, OR, 7, 3, [148, 149, 150, 151]),
    row(K48, DE, OR, 21, 3, [250, 251, 252, 253]),
    row(K48, DE, OR, 7, 12, [161, 162, 163, 164]),
    row(K48, DE, OR, 21, 12, [262, 263, 264, 265]),
    // 12 kHz, fault on the fan-end bearing.
    row(K12, FE, IR, 7, 0, [278, 279, 280, 281]),
    row(K12, FE, IR, 14, 0, [274, 275, 276, 277]),
    row(K12, FE, IR, 21, 0, [270, 271, 272, 273]),
    row(K12, FE, B, 7, 0, [282, 283, 284, 285]),
    row(K12, FE, B, 14, 0, [286, 287, 288, 289]),
    row(K12, FE, B, 21, 0, [290, 291, 292, 293]),
    row(K12, FE, OR, 7, 6, [294, 295, 296, 297]),
    row(K12, FE, OR, 14, 6, [313, 0, 0, 0]),
    row(K12, FE, OR, 21, 6, [315, 0, 0, 0]),
    row(K12, FE, OR, 7, 3, [298, 299, 300, 301]),
    row(K12, FE, OR, 14, 3, [310, 309, 311, 312]),
    row(K12, FE, OR, 21, 3, [0, 316, 317, 318]),
    row(K12, FE, OR, 7, 12, [302, 305, 306, 307]),
];

/// CWRU's catalogue entry for a record number (normal, drive-end 12k/48k, fan-end 12k).
pub fn catalogue(number: u32) -> Option<CatalogueEntry> {
    TABLE.iter().find_map(|r| {
        let k = r.records.iter().position(|&n| n == number && n != 0)?;
        let (load_hp, nominal_rpm) = LOADS_HP_RPM[k];
        Some(CatalogueEntry {
            record: number,
            sample_rate: r.rate,
            label: r.label,
            faulty_bearing: r.end,
            fault_size_in: r.mils as f64 / 1000.0,
            outer_race_clock: (r.clock != 0).then_some(r.clock),
            load_hp,
            nominal_rpm,
        })
    })
}

/// Every record number in the catalogue, ascending.
pub fn catalogue_records() -> Vec<u32> {
    let mut v: Vec<u32> = TABLE
        .iter()
        .flat_map(|r| r.records)
        .filter(|&n| n != 0)
        .collect();
    v.sort_unstable();
    v
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
    mat.vars.iter().any(|v| is_signal_name(&v.name))
}

/// Does this MAT file's variable directory look like a CWRU recording? (The same test as
/// [`is_cwru`], before any data is decoded.)
pub fn is_cwru_directory(dir: &MatDirectory) -> bool {
    dir.entries.iter().any(|e| is_signal_name(&e.name))
}

/// `X<nnn>_DE_time`, `X<nnn>_FE_time` or `X<nnn>_BA_time`.
fn is_signal_name(name: &str) -> bool {
    matches!(parse_var_name(name), Some((_, Some(_))))
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
            unit: cfg.unit.to_string(),
            samples: super::scaled_f32(path, &cfg.name, samples, k)?,
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

    // Speed (side data: never fatal).
    let rpm_var = format!("X{number:03}RPM");
    let rpm = match (opts.rpm, mat.get(&rpm_var)) {
        (Some(r), _) => {
            notes.push(format!("rpm {r} from --rpm"));
            Some(r)
        }
        (None, Some(v)) => match v.as_number() {
            Some(r) if r.is_finite() && r > 0.0 => {
                if !matches!(v, MatValue::Numeric { .. }) {
                    notes.push(format!(
                        "{rpm_var} read as {r} from {} {}",
                        v.describe(),
                        v.as_text()
                    ));
                }
                Some(r)
            }
            Some(r) => {
                notes.push(format!(
                    "{WARNING}{rpm_var} = {r} is not a valid speed: speed unknown (pass --rpm R)"
                ));
                None
            }
            None => {
                notes.push(format!(
                    "{WARNING}{rpm_var} is {} holding {}, not one number; kept here as text, speed unknown (pass --rpm R)",
                    v.describe(),
                    v.as_text()
                ));
                None
            }
        },
        (None, None) => {
            notes.push(format!(
                "no {rpm_var} in the file: speed unknown (pass --rpm R to set it)"
            ));
            None
        }
    };
    let ignored: Vec<String> = mat
        .vars
        .iter()
        .filter(|v| !matches!(parse_var_name(&v.name), Some((n, _)) if n == number))
        .map(|v| format!("{} ({})", v.name, v.value.describe()))
        .collect();
    if !ignored.is_empty() {
        notes.push(format!("other variables not read: {}", ignored.join(", ")));
    }

    // Sample rate.
    let entry = catalogue(number);
    let file_rate = entry.map(|e| (e.sample_rate, format!("CWRU catalogue (record {number})")));
    let (sample_rate, note) = resolve_sample_rate(path, file_rate, &rig.acquisition, opts).map_err(|e| {
        if entry.is_none()
            && opts.sample_rate.is_none()
            && opts.declared_sample_rate.is_none()
            && rig.acquisition.sample_rate_hz.is_none()
        {
            anyhow::anyhow!(
                "{p}: the sample rate is unknown: CWRU files do not store it and record {number} is not in \
                 CWRU's published tables (normal 97-100, drive end 105-265 and 3001-3008, fan end 270-318); \
                 pass --sample-rate HZ (12000 or 48000 for CWRU)"
            )
        } else {
            e
        }
    })?;
    notes.push(note);

    let mut metadata = BTreeMap::new();
    metadata.insert("cwru_record".to_string(), number.to_string());
    if let Some(e) = entry {
        metadata.insert("cwru_load_hp".into(), e.load_hp.to_string());
        let monitored = rig.classifier_channel().and_then(|c| {
            POSITIONS
                .iter()
                .copied()
                .find(|p| p.eq_ignore_ascii_case(&c.name))
        });
        let label = match (e.faulty_bearing, monitored) {
            (Some(end), Some(m)) if end != m => {
                notes.push(format!(
                    "record {number}: the {} fault is on the {end} bearing; this rig's classifier \
                     watches {m}, whose bearing is healthy: labelled healthy",
                    e.label
                ));
                Condition::Healthy.as_str()
            }
            _ => e.label,
        };
        metadata.insert("label".to_string(), label.to_string());
        if let Some(end) = e.faulty_bearing {
            metadata.insert("cwru_fault".into(), e.label.to_string());
            metadata.insert("cwru_fault_bearing".into(), end.to_string());
            metadata.insert(
                "cwru_fault_size_in".into(),
                format!("{:.3}", e.fault_size_in),
            );
        }
        if let Some(c) = e.outer_race_clock {
            metadata.insert("cwru_outer_race_clock".into(), c.to_string());
        }
    }
    let rec = Recording {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho: None,
        rpm,
        nominal_rpm: None,
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
        assert_eq!(catalogue(217).unwrap().load_hp, 3);
        assert_eq!(catalogue(216), None);
        assert_eq!(catalogue(157), None);
        let fe = catalogue(310).unwrap();
        assert_eq!(
            (fe.sample_rate, fe.label, fe.faulty_bearing, fe.load_hp),
            (12_000.0, "outer_race", Some("FE"), 0)
        );
        assert_eq!((fe.fault_size_in, fe.outer_race_clock), (0.014, Some(3)));
        assert_eq!(catalogue(309).unwrap().load_hp, 1);
        assert_eq!(catalogue(316).unwrap().nominal_rpm, 1772.0);
        assert_eq!(catalogue(279).unwrap().label, "inner_race");
        assert_eq!(catalogue(0), None);
        // Every number once; the published set of record numbers (161 records).
        let all = catalogue_records();
        let mut dedup = all.clone();
        dedup.dedup();
        assert_eq!(all, dedup, "a record number appears twice");
        let mut expected: Vec<u32> = (97..=100).collect();
        for (a, b) in [
            (105, 112),
            (118, 125),
            (130, 133),
            (135, 138),
            (144, 151),
            (161, 164),
            (169, 172),
            (174, 177),
            (185, 192),
            (197, 204),
            (209, 215),
            (222, 229),
            (234, 241),
            (246, 253),
            (258, 265),
            (270, 302),
            (305, 307),
            (309, 313),
            (315, 318),
            (3001, 3008),
        ] {
            expected.extend(a..=b);
        }
        expected.extend([156, 158, 159, 160, 217]);
        expected.sort_unstable();
        assert_eq!(all, expected);
    }
}
