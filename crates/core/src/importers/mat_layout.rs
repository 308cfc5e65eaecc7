//! Any MAT layout: which variables of a MAT v5 file are the rig's channels, and which one
//! holds the sample rate.
//!
//! The variable directory ([`mat5::read_directory`]) is read first and the whole mapping is
//! settled on it, before any sample is decoded:
//! 1. a rig file that names variables (`[[channels]] mat_variable`, `mat_column`,
//!    `[acquisition] mat_rate_variable`) is followed exactly;
//! 2. otherwise the CWRU and MFPT layouts are recognised by their names, as before
//!    ([`cwru`], [`mfpt`]);
//! 3. otherwise a file holding one numeric vector (row or column, any class) and a rig with one
//!    acceleration channel: that vector is the channel, whatever its name;
//! 4. otherwise an error listing the variables found (name, dims, class) and the key to set.
//!
//! Then only what is needed is decoded: the rate variable first (a scalar), then the signals.

use super::mat5::{self, MatDirectory, MatEntry, MatValue};
use super::{check_classifier_channel, cwru, memory, mfpt, resolve_sample_rate, ImportOptions};
use crate::config::{ChannelConfig, ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// What the error for an unmappable file says about the two recognised layouts.
const KNOWN_LAYOUTS: &str = "it is not a CWRU file (variables X<nnn>_DE_time, X<nnn>_FE_time, \
     X<nnn>_BA_time, X<nnn>RPM) nor an MFPT file (a struct `bearing` with fields gs, sr, rate, load)";

/// Read a MAT file by the rules in the module doc.
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let dir = mat5::read_directory(path)?;
    if !rig_names_variables(rig) && (mfpt::is_mfpt_directory(&dir) || cwru::is_cwru_directory(&dir))
    {
        // These layouts are decoded whole.
        let all: Vec<&str> = dir.entries.iter().map(|e| e.name.as_str()).collect();
        let need = memory::mat_need(path, &dir, &all)?;
        memory::check_need(path, need, "its variables", &memory::available())?;
    }
    if !rig_names_variables(rig) {
        if mfpt::is_mfpt_directory(&dir) {
            return mfpt::from_mat(path, &mat5::read(path)?, rig, opts);
        }
        if cwru::is_cwru_directory(&dir) {
            return cwru::from_mat(path, &mat5::read(path)?, rig, opts);
        }
    }
    from_directory(path, &dir, rig, opts)
}

/// Does the rig file say which MAT variable is what?
pub fn rig_names_variables(rig: &RigConfig) -> bool {
    rig.acquisition.mat_rate_variable.is_some()
        || rig.channels.iter().any(|c| c.mat_variable.is_some())
}

/// A variable path from the rig file: a top-level name and struct fields below it.
#[derive(Debug, Clone, PartialEq)]
struct VarPath {
    text: String,
    top: String,
    fields: Vec<String>,
}

impl VarPath {
    fn parse(text: &str) -> VarPath {
        let mut parts = text.split('.').map(str::to_string);
        let top = parts.next().unwrap_or_default();
        VarPath {
            text: text.to_string(),
            top,
            fields: parts.collect(),
        }
    }
}

/// Where one rig channel's samples are.
struct Source<'r> {
    channel: &'r ChannelConfig,
    var: VarPath,
    /// Column (from 1) of a samples x channels matrix.
    column: Option<usize>,
    /// Why this variable: "mat_variable" or "the file's only numeric vector".
    why: &'static str,
}

impl Source<'_> {
    /// "rig channel \"vertical\" (mat_variable = \"Data\", mat_column = 2)", for messages.
    fn key(&self) -> String {
        let col = self
            .column
            .map_or_else(String::new, |k| format!(", mat_column = {k}"));
        format!(
            "rig channel {:?} (mat_variable = {:?}{col})",
            self.channel.name, self.var.text
        )
    }
}

/// Build a recording from a MAT file of any layout (rules 1, 3 and 4 of the module doc).
pub fn from_directory(
    path: &Path,
    dir: &MatDirectory,
    rig: &RigConfig,
    opts: &ImportOptions,
) -> Result<Recording> {
    let mut notes = Vec::new();
    let sources = if rig.channels.iter().any(|c| c.mat_variable.is_some()) {
        named_sources(path, dir, rig, &mut notes)?
    } else {
        vec![single_vector(path, dir, rig)?]
    };
    check_in_directory(path, dir, &sources)?;
    let mut tops: Vec<&str> = sources.iter().map(|s| s.var.top.as_str()).collect();
    tops.sort_unstable();
    tops.dedup();
    let rate = rig
        .acquisition
        .mat_rate_variable
        .as_deref()
        .map(VarPath::parse);
    let mut decoded = tops.clone();
    decoded.extend(rate.as_ref().map(|v| v.top.as_str()));
    let need = memory::mat_need(path, dir, &decoded)?;
    memory::check_need(
        path,
        need,
        &format!("variables {}", mat5::bounded(&decoded.join(", "), 200)),
        &memory::available(),
    )?;
    let (sample_rate, rate_note) = sample_rate(path, dir, rig, opts)?;
    let mat = mat5::read_selected(path, dir, &tops)?;
    let (channels, tacho) = read_channels(path, &mat, &sources, &mut notes)?;
    notes.push(rate_note);
    notes.extend(unread_note(dir, &sources, rig));
    if let Some(r) = opts.rpm {
        notes.push(format!("rpm {r} from --rpm"));
    }
    let rec = Recording {
        sample_rate,
        start_time_ns: 0,
        channels,
        tacho,
        rpm: opts.rpm,
        nominal_rpm: None,
        provenance: Provenance {
            source_path: path.display().to_string(),
            format: "mat".into(),
            notes,
        },
        metadata: BTreeMap::new(),
    };
    check_classifier_channel(path, rig, &rec, "mat_variable")?;
    Ok(rec)
}

/// The mapped channels' samples (sensitivity applied) and the analog tacho, if mapped;
/// channels must agree in length.
fn read_channels(
    path: &Path,
    mat: &mat5::MatFile,
    sources: &[Source],
    notes: &mut Vec<String>,
) -> Result<(Vec<Channel>, Option<Tacho>)> {
    let mut channels = Vec::new();
    let mut tacho = None;
    let mut first_len: Option<(String, usize)> = None;
    for src in sources {
        let value = resolve(path, mat.get(&src.var.top), &src.var)?;
        let samples = column_samples(path, src, value)?;
        match &first_len {
            Some((other, n)) if *n != samples.len() => bail!(
                "{}: {} has {} samples but {other} has {n}; a recording's channels must have the same length",
                path.display(),
                src.key(),
                samples.len()
            ),
            Some(_) => {}
            None => first_len = Some((src.key(), samples.len())),
        }
        notes.push(mapping_note(src, value));
        let cfg = src.channel;
        let k = cfg.sensitivity;
        let samples = super::scaled_f32(path, &cfg.name, samples, k)?;
        match cfg.kind {
            ChannelKind::Acceleration => channels.push(Channel {
                name: cfg.name.clone(),
                axis: cfg.axis.clone(),
                unit: cfg.unit.to_string(),
                samples,
            }),
            ChannelKind::Tacho if tacho.is_none() => {
                tacho = Some(Tacho::Analog {
                    samples,
                    unit: cfg.unit.to_string(),
                })
            }
            ChannelKind::Tacho => bail!(
                "{}: the rig file maps more than one tacho channel; rigmon uses one",
                path.display()
            ),
        }
    }
    Ok((channels, tacho))
}

/// Rule 1: the channels that name a `mat_variable`; the others are left out (noted).
fn named_sources<'r>(
    path: &Path,
    dir: &MatDirectory,
    rig: &'r RigConfig,
    notes: &mut Vec<String>,
) -> Result<Vec<Source<'r>>> {
    let mut out = Vec::new();
    for c in &rig.channels {
        let Some(v) = &c.mat_variable else {
            notes.push(format!(
                "rig channel {:?} names no mat_variable: left out",
                c.name
            ));
            continue;
        };
        let var = VarPath::parse(v);
        if dir.get(&var.top).is_none() {
            bail!(
                "{}: missing variable {:?}: rig channel {:?} reads mat_variable = {v:?} but the file holds: {}; \
                 set that channel's mat_variable in the rig file to one of these",
                path.display(),
                var.top,
                c.name,
                dir.summary()
            );
        }
        out.push(Source {
            channel: c,
            var,
            column: c.mat_column,
            why: "mat_variable",
        });
    }
    Ok(out)
}

/// Rule 3: one acceleration channel and one numeric vector in the file.
fn single_vector<'r>(path: &Path, dir: &MatDirectory, rig: &'r RigConfig) -> Result<Source<'r>> {
    let accel: Vec<&ChannelConfig> = rig.acceleration_channels().collect();
    let arrays: Vec<&MatEntry> = dir
        .entries
        .iter()
        .filter(|e| e.is_real_numeric() && e.count() >= 2)
        .collect();
    let example = arrays.first().map(|e| e.name.as_str());
    if accel.len() != 1 {
        let names: Vec<&str> = accel.iter().map(|c| c.name.as_str()).collect();
        return Err(unmappable(
            path,
            dir,
            &format!(
                "the rig has {} acceleration channels ({}) and none names its variable",
                accel.len(),
                names.join(", ")
            ),
            accel[0],
            example,
        ));
    }
    let reason = match arrays.as_slice() {
        [one] if one.is_vector() => {
            return Ok(Source {
                channel: accel[0],
                var: VarPath::parse(&one.name),
                column: None,
                why: "the file's only numeric vector",
            })
        }
        [one] => format!(
            "its only numeric array, {}, is a {} matrix, not a vector (pick a column with mat_column = <k>)",
            mat5::shown(&one.name),
            one.describe()
        ),
        [] => "it holds no real numeric vector of samples".to_string(),
        many => format!(
            "it holds {} numeric arrays ({})",
            many.len(),
            mat5::bounded(
                &many
                    .iter()
                    .map(|e| mat5::shown(&e.name))
                    .collect::<Vec<_>>()
                    .join(", "),
                1000
            )
        ),
    };
    Err(unmappable(path, dir, &reason, accel[0], example))
}

/// The error for a file no rule maps: what was found and the keys to set.
fn unmappable(
    path: &Path,
    dir: &MatDirectory,
    reason: &str,
    channel: &ChannelConfig,
    example: Option<&str>,
) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: cannot tell which MAT variable holds which channel: {reason}, and {KNOWN_LAYOUTS}. \
         The file holds: {}. Name the variables in the rig file: under [[channels]] name = {:?} set \
         mat_variable = {:?} (a struct field as \"<struct>.<field>\", a matrix column with \
         mat_column = <k>), one per channel; and a sample rate the file stores with \
         [acquisition] mat_rate_variable = \"<scalar>\"",
        path.display(),
        dir.summary(),
        channel.name,
        example.unwrap_or("<variable>")
    )
}

/// Shape checks that the directory can answer before any data is decoded: each top-level
/// variable is numeric and real with a usable shape, structs are 1x1 where fields are named,
/// and the channels agree in length.
fn check_in_directory(path: &Path, dir: &MatDirectory, sources: &[Source]) -> Result<()> {
    let mut first: Option<(String, usize)> = None;
    for src in sources {
        let e = dir
            .get(&src.var.top)
            .expect("sources name listed variables");
        if !src.var.fields.is_empty() {
            if e.class != mat5::MatClass::Struct || e.dims.iter().any(|&d| d != 1) {
                bail!(
                    "{}: wrong shape: {}: {} is {}, not a 1x1 struct with a field {:?}",
                    path.display(),
                    src.key(),
                    mat5::shown(&e.name),
                    e.describe(),
                    src.var.fields[0]
                );
            }
            continue;
        }
        let n = samples_shape(path, src, &e.class_name(), &e.dims, e.is_real_numeric())?;
        match &first {
            Some((other, m)) if *m != n => bail!(
                "{}: {} holds {n} samples but {other} holds {m}; a recording's channels must have the same length",
                path.display(),
                src.key()
            ),
            Some(_) => {}
            None => first = Some((src.key(), n)),
        }
    }
    Ok(())
}

/// The number of samples a variable of this class and shape gives a channel, or an error
/// saying what is wrong: not real numbers, empty, more than two dimensions, a matrix without
/// a column (or a column out of range, or samples along the rows).
fn samples_shape(
    path: &Path,
    src: &Source,
    class: &str,
    dims: &[usize],
    real_numeric: bool,
) -> Result<usize> {
    let p = path.display();
    let what = format!("{} is {} {class}", src.key(), join_dims(dims));
    if !real_numeric {
        return Err(not_samples(path, src, class, dims));
    }
    let count: usize = dims.iter().product();
    if count == 0 {
        bail!("{p}: {what}: it is empty");
    }
    let big: Vec<usize> = dims.iter().copied().filter(|&d| d != 1).collect();
    match (big.as_slice(), src.column) {
        ([] | [_], None | Some(1)) => Ok(count),
        ([] | [_], Some(k)) => bail!(
            "{p}: {what}: a vector holds one channel; mat_column = {k} has nothing to pick (remove it)"
        ),
        ([rows, cols], _) if dims.len() == 2 && rows < cols => bail!(
            "{p}: {what}: its columns hold only {rows} samples each; rigmon reads a matrix's columns \
             as channels and its rows as samples: save the transpose ({}.')",
            src.var.text
        ),
        ([_, cols], None) if dims.len() == 2 => bail!(
            "{p}: {what}: a matrix; set mat_column = 1 to {cols} on this channel (columns are channels, rows are samples)"
        ),
        ([_, cols], Some(k)) if dims.len() == 2 && k > *cols => bail!(
            "{p}: {what}: mat_column = {k} but it has {cols} columns"
        ),
        ([rows, _], Some(_)) if dims.len() == 2 => Ok(*rows),
        _ => bail!(
            "{p}: wrong shape: {what}: arrays of more than two dimensions are not supported; \
             save the channels as vectors or as the columns of a matrix"
        ),
    }
}

/// The error for a variable that holds no real numbers (text, a struct, complex values...).
fn not_samples(path: &Path, src: &Source, class: &str, dims: &[usize]) -> anyhow::Error {
    let hint = if class == "struct" {
        format!(
            "; name one of its fields, mat_variable = \"{}.<field>\"",
            src.var.text
        )
    } else {
        String::new()
    };
    anyhow::anyhow!(
        "{}: wrong shape: {} is {} {class}; expected real numbers (a vector of samples){hint}",
        path.display(),
        src.key(),
        join_dims(dims)
    )
}

fn join_dims(dims: &[usize]) -> String {
    dims.iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join("x")
}

/// Follow a variable path's struct fields down from its top-level value.
fn resolve<'a>(path: &Path, top: Option<&'a MatValue>, var: &VarPath) -> Result<&'a MatValue> {
    let p = path.display();
    let Some(mut value) = top else {
        bail!(
            "{p}: missing variable {:?} (mat_variable = {:?})",
            var.top,
            var.text
        );
    };
    let mut at = var.top.clone();
    for f in &var.fields {
        let one = matches!(value, MatValue::Struct { dims, .. } if dims.iter().all(|&d| d == 1));
        let next = value.field(f);
        value = match (one, next) {
            (true, Some(v)) => v,
            (true, None) => bail!(
                "{p}: missing field: {at} has no field {f:?} (mat_variable = {:?}); its fields are {:?}",
                var.text,
                value.field_names()
            ),
            (false, _) => bail!(
                "{p}: wrong shape: {at} is {}, not a 1x1 struct with a field {f:?} (mat_variable = {:?})",
                value.describe(),
                var.text
            ),
        };
        at = format!("{at}.{f}");
    }
    Ok(value)
}

/// A channel's samples from its (resolved) variable: the vector, or the chosen column.
fn column_samples<'a>(path: &Path, src: &Source, value: &'a MatValue) -> Result<&'a [f64]> {
    let (dims, real) = match value {
        MatValue::Numeric {
            dims,
            real,
            imag: None,
            logical: false,
            ..
        } => (dims, real),
        other => return Err(not_samples(path, src, &other.class_name(), other.dims())),
    };
    let n = samples_shape(path, src, &value.class_name(), dims, true)?;
    let k = src.column.unwrap_or(1) - 1;
    Ok(&real[k * n..(k + 1) * n])
}

fn mapping_note(src: &Source, value: &MatValue) -> String {
    let col = src
        .column
        .map_or_else(String::new, |k| format!("column {k} of "));
    format!(
        "{col}variable {} ({}) -> rig channel {:?} ({})",
        src.var.text,
        value.describe(),
        src.channel.name,
        src.why
    )
}

/// "other variables not read: ..." for what neither a channel nor the rate uses.
fn unread_note(dir: &MatDirectory, sources: &[Source], rig: &RigConfig) -> Option<String> {
    let rate_top = rig
        .acquisition
        .mat_rate_variable
        .as_deref()
        .map(|v| VarPath::parse(v).top);
    let other: Vec<String> = dir
        .entries
        .iter()
        .filter(|e| !sources.iter().any(|s| s.var.top == e.name))
        .filter(|e| rate_top.as_deref() != Some(e.name.as_str()))
        .map(|e| format!("{} ({})", mat5::shown(&e.name), e.describe()))
        .collect();
    (!other.is_empty()).then(|| {
        format!(
            "other variables not read: {}",
            mat5::bounded(&other.join(", "), 1000)
        )
    })
}

/// The sample rate by the importers' one rule, with the rate variable (if the rig names one)
/// as the rate the file fixes. Decodes only that variable; refuses an unknown rate before
/// any signal is decoded, listing the file's scalars as candidates.
fn sample_rate(
    path: &Path,
    dir: &MatDirectory,
    rig: &RigConfig,
    opts: &ImportOptions,
) -> Result<(f64, String)> {
    let file_rate = match &rig.acquisition.mat_rate_variable {
        Some(v) => Some((
            rate_variable(path, dir, &VarPath::parse(v))?,
            format!("variable {v}"),
        )),
        None => None,
    };
    let unknown = file_rate.is_none()
        && opts.sample_rate.is_none()
        && opts.declared_sample_rate.is_none()
        && rig.acquisition.sample_rate_hz.is_none();
    if unknown {
        bail!(
            "{}: the sample rate is unknown: the file's layout does not fix it, the rig file names no \
             [acquisition] mat_rate_variable and has no sample_rate_hz{}; set mat_rate_variable = \"<scalar>\" \
             (a variable holding the rate in Hz) or sample_rate_hz = HZ in the rig file, or pass --sample-rate HZ",
            path.display(),
            scalars_hint(path, dir)
        );
    }
    resolve_sample_rate(path, file_rate, &rig.acquisition, opts)
}

/// The value of the rig's `mat_rate_variable`: one number, in any class.
fn rate_variable(path: &Path, dir: &MatDirectory, var: &VarPath) -> Result<f64> {
    let p = path.display();
    let key = format!("acquisition.mat_rate_variable = {:?}", var.text);
    let Some(e) = dir.get(&var.top) else {
        bail!(
            "{p}: missing variable {:?}: the rig file's {key} names no variable in the file; the file holds: {}",
            var.top,
            dir.summary()
        );
    };
    // A number needs a handful of characters; a long char array is refused before it is read.
    let too_long = e.class == mat5::MatClass::Char && e.count() > 64;
    if var.fields.is_empty() && ((e.class.is_numeric() && e.count() != 1) || too_long) {
        bail!(
            "{p}: wrong shape: {key}: {} is {}; expected one number (the sample rate in Hz)",
            mat5::shown(&e.name),
            e.describe()
        );
    }
    let mat = mat5::read_selected(path, dir, &[var.top.as_str()])?;
    let value = resolve(path, mat.get(&var.top), var)?;
    value.as_number().ok_or_else(|| {
        anyhow::anyhow!(
            "{p}: wrong shape: {key}: {} is {} holding {}, not one number (the sample rate in Hz)",
            var.text,
            value.describe(),
            value.as_text()
        )
    })
}

/// " (the file's scalars: fs = 51200, gain = 2)": candidates for the rate variable.
fn scalars_hint(path: &Path, dir: &MatDirectory) -> String {
    let names: Vec<&str> = dir
        .entries
        .iter()
        .filter(|e| e.is_real_numeric() && e.count() == 1)
        .map(|e| e.name.as_str())
        .take(8)
        .collect();
    if names.is_empty() {
        return " (the file holds no scalar variable)".into();
    }
    let values = mat5::read_selected(path, dir, &names).ok();
    let shown: Vec<String> = names
        .iter()
        .map(|n| match values.as_ref().and_then(|m| m.get(n)) {
            Some(v) => format!(
                "{} = {}",
                mat5::shown(n),
                v.as_text().trim_matches(['[', ']'])
            ),
            None => mat5::shown(n),
        })
        .collect();
    format!(" (the file's scalars: {})", shown.join(", "))
}
