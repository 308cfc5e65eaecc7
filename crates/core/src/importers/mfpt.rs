//! MFPT-style bearing data (`.mat`): a struct `bearing` with fields `gs` (the signal, a
//! vector in g), `sr` (sample rate, Hz), `rate` (shaft rate, Hz) and `load`.
//!
//! The one signal becomes the rig's classifier channel (name, axis, unit and sensitivity from
//! the rig file). `gs` and `sr` are required and checked strictly; `rate` and `load` are side
//! data, read in whatever class they come in (the public variable-load files store `load` as
//! text, '25', '100', '300'); one that cannot be read is a warning in the provenance, never an
//! error.

use super::mat5::{MatClass, MatDirectory, MatFile, MatValue};
use super::{cwru::vector, resolve_sample_rate, ImportOptions, WARNING};
use crate::config::RigConfig;
use crate::recording::{Channel, Provenance, Recording};
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Does this MAT file look like an MFPT recording (a struct named `bearing`)?
pub fn is_mfpt(mat: &MatFile) -> bool {
    matches!(mat.get("bearing"), Some(MatValue::Struct { .. }))
}

/// Does this MAT file's variable directory look like an MFPT recording? (The same test as
/// [`is_mfpt`], before any data is decoded.)
pub fn is_mfpt_directory(dir: &MatDirectory) -> bool {
    dir.get("bearing")
        .is_some_and(|e| e.class == MatClass::Struct)
}

fn scalar(path: &Path, bearing: &MatValue, field: &str) -> Result<Option<f64>> {
    match bearing.field(field) {
        None => Ok(None),
        Some(v) => match v.as_scalar() {
            Some(x) => Ok(Some(x)),
            None => bail!(
                "{}: wrong shape: bearing.{field} is {}; expected a single number (1x1)",
                path.display(),
                v.describe()
            ),
        },
    }
}

/// The struct fields rigmon reads.
const KNOWN_FIELDS: [&str; 4] = ["gs", "sr", "rate", "load"];

/// A side-data field as a number in any MATLAB class; a field that is present but cannot be
/// read becomes a warning note (with its text) and `None`.
fn side_number(bearing: &MatValue, field: &str, notes: &mut Vec<String>) -> Option<f64> {
    let v = bearing.field(field)?;
    match v.as_number() {
        Some(x) => {
            if !matches!(v, MatValue::Numeric { .. }) {
                notes.push(format!(
                    "bearing.{field} read as {x} from {} {}",
                    v.describe(),
                    v.as_text()
                ));
            }
            Some(x)
        }
        None => {
            notes.push(format!(
                "{WARNING}bearing.{field} is {} holding {}, not one number; kept here as text, not used",
                v.describe(),
                v.as_text()
            ));
            None
        }
    }
}

/// Build a [`Recording`] from a parsed MFPT MAT file.
pub fn from_mat(
    path: &Path,
    mat: &MatFile,
    rig: &RigConfig,
    opts: &ImportOptions,
) -> Result<Recording> {
    let p = path.display();
    let bearing = mat.get("bearing").expect("is_mfpt checked");
    if let MatValue::Struct { dims, .. } = bearing {
        if dims.iter().any(|&d| d != 1) {
            bail!(
                "{p}: wrong shape: bearing is a {} struct array; expected a single (1x1) struct",
                bearing.describe()
            );
        }
    }
    let Some(gs) = bearing.field("gs") else {
        bail!("{p}: missing variable: the struct `bearing` has no field `gs` (the signal); its fields are {:?}", bearing.field_names());
    };
    let signal = vector(path, "bearing.gs", gs)?;
    let mut notes = Vec::new();
    let sr = scalar(path, bearing, "sr")?;
    if sr.is_none() {
        notes.push("no bearing.sr in the file".to_string());
    }
    let (sample_rate, note) = resolve_sample_rate(
        path,
        sr.map(|f| (f, "field bearing.sr".to_string())),
        &rig.acquisition,
        opts,
    )?;
    notes.push(note);
    let rate = side_number(bearing, "rate", &mut notes);
    let rpm = match (opts.rpm, rate) {
        (Some(r), _) => {
            notes.push(format!("rpm {r} from --rpm"));
            Some(r)
        }
        (None, Some(hz)) if hz.is_finite() && hz > 0.0 => Some(hz * 60.0),
        (None, Some(hz)) => {
            notes.push(format!(
                "{WARNING}bearing.rate = {hz} is not a valid shaft rate (Hz): speed unknown (pass --rpm R)"
            ));
            None
        }
        (None, None) => {
            if bearing.field("rate").is_none() {
                notes.push("no bearing.rate in the file: speed unknown (pass --rpm R)".to_string());
            }
            None
        }
    };
    let Some(cfg) = rig.classifier_channel() else {
        bail!("{p}: the rig file has no classifier channel to put the MFPT signal on");
    };
    notes.push(format!("bearing.gs mapped to rig channel {}", cfg.name));
    let mut metadata = BTreeMap::new();
    if let Some(load) = side_number(bearing, "load", &mut notes) {
        metadata.insert("load".to_string(), load.to_string());
    }
    let others: Vec<String> = bearing
        .field_names()
        .into_iter()
        .filter(|n| !KNOWN_FIELDS.contains(n))
        .map(|n| {
            format!(
                "{n} ({})",
                bearing
                    .field(n)
                    .map_or_else(String::new, MatValue::describe)
            )
        })
        .collect();
    if !others.is_empty() {
        notes.push(format!(
            "other fields of bearing not read: {}",
            others.join(", ")
        ));
    }
    let k = cfg.sensitivity;
    Ok(Recording {
        sample_rate,
        start_time_ns: 0,
        channels: vec![Channel {
            name: cfg.name.clone(),
            axis: cfg.axis.clone(),
            unit: cfg.unit.to_string(),
            samples: super::scaled_f32(path, &cfg.name, signal, k)?,
        }],
        tacho: None,
        rpm,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: path.display().to_string(),
            format: "mfpt-mat".into(),
            notes,
        },
        metadata,
    })
}
