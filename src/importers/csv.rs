//! CSV recordings: a header line naming the columns, then one line per sample.
//!
//! Columns are matched to the rig's channels by name (acceleration and tacho); an optional time
//! column (`time`, `t`, `time_s`, `t_s`, `seconds`; in seconds) gives the sample rate, which must
//! be uniform. Without one the rig's (or `--sample-rate`'s) rate is used. The delimiter is `,`,
//! `;` or tab (taken from the header). Lines starting with `#` and blank lines are skipped.
//! Values are multiplied by the channel's `sensitivity`. Columns that name no rig channel are
//! side data: skipped with a warning in the provenance (their values are not read).

use super::{check_classifier_channel, resolve_sample_rate, ImportOptions, WARNING};
use crate::config::{ChannelKind, RigConfig};
use crate::recording::{Channel, Provenance, Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// Header names accepted for the time column.
pub const TIME_COLUMNS: [&str; 5] = ["time", "t", "time_s", "t_s", "seconds"];

/// Read a CSV file into a [`Recording`].
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    let p = path.display();
    let text =
        std::fs::read_to_string(path).with_context(|| format!("{p}: cannot read as UTF-8 text"))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((header_idx, header)) = lines.next() else {
        bail!("{p}: the file is empty (no header line)");
    };
    let delim = if header.contains(',') {
        ','
    } else if header.contains(';') {
        ';'
    } else if header.contains('\t') {
        '\t'
    } else {
        ','
    };
    let names: Vec<String> = header
        .split(delim)
        .map(|s| s.trim().trim_matches('"').to_string())
        .collect();
    // Map columns.
    let mut time_col = None;
    let mut map: Vec<Option<usize>> = Vec::with_capacity(names.len()); // column -> rig channel index
    let mut skipped: Vec<usize> = Vec::new(); // columns naming no rig channel
    for (c, name) in names.iter().enumerate() {
        if TIME_COLUMNS.iter().any(|t| t.eq_ignore_ascii_case(name)) {
            if let Some(tc) = time_col {
                bail!(
                    "{p}: line {}: two time columns ({:?} and {name:?})",
                    header_idx + 1,
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
                    bail!(
                        "{p}: line {}: column {name:?} appears twice",
                        header_idx + 1
                    );
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
            header_idx + 1,
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
            header_idx + 1,
            list.join(", "),
            rig.channel_names(),
            TIME_COLUMNS
        ));
    }
    // Parse rows.
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for (idx, line) in lines {
        let mut n = 0;
        for (c, field) in line.split(delim).enumerate() {
            if c >= names.len() {
                bail!(
                    "{p}: line {}: more than the {} columns the header names",
                    idx + 1,
                    names.len()
                );
            }
            n += 1;
            if skipped.contains(&c) {
                cols[c].push(0.0); // side data: not read
                continue;
            }
            let f = field.trim().trim_matches('"');
            let v: f64 = f.parse().map_err(|_| {
                anyhow::anyhow!(
                    "{p}: line {}, column {} ({:?}): {f:?} is not a number",
                    idx + 1,
                    c + 1,
                    names[c]
                )
            })?;
            cols[c].push(v);
        }
        if n < names.len() {
            bail!(
                "{p}: line {}: {n} values but the header names {} columns (truncated file?)",
                idx + 1,
                names.len()
            );
        }
    }
    let rows = cols[0].len();
    if rows == 0 {
        bail!("{p}: the file has a header but no samples");
    }
    // Sample rate from the time column.
    let file_rate = match time_col {
        Some(tc) => {
            let t = &cols[tc];
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
    let (sample_rate, note) = resolve_sample_rate(path, file_rate, rig, opts)?;
    // Build channels in rig order.
    let mut channels = Vec::new();
    let mut tacho = None;
    notes.push(note);
    for (k, cfg) in rig.channels.iter().enumerate() {
        let Some(c) = map.iter().position(|m| *m == Some(k)) else {
            notes.push(format!("no column for rig channel {}", cfg.name));
            continue;
        };
        let s = cfg.sensitivity;
        let samples: Vec<f32> = cols[c].iter().map(|&x| (x * s) as f32).collect();
        match cfg.kind {
            ChannelKind::Acceleration => channels.push(Channel {
                name: cfg.name.clone(),
                axis: cfg.axis.clone(),
                unit: cfg.unit.clone(),
                samples,
            }),
            ChannelKind::Tacho => {
                tacho = Some(Tacho::Analog {
                    samples,
                    unit: cfg.unit.clone(),
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
