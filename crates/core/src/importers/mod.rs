//! Importers: read recordings from `.mat` (CWRU, MFPT or any layout the rig file maps, see
//! [`mat_layout`]), WAV, CSV and rigmon MCAP into a [`Recording`](crate::recording::Recording).
//!
//! [`load`] picks the format by content (magic bytes) and then by extension; a folder is a
//! series of periodic captures ([`snapshots`]), and so is a rigmon MCAP file written from one.
//! Every importer
//! maps the file's channels onto the rig file's channels, applies sensitivities, settles the
//! sample rate by one rule ([`resolve_sample_rate`]) and refuses non-finite samples, naming the
//! file, the channel and the sample index. Required data (the samples, whatever fixes the
//! sample rate) is checked strictly; side data (speed, load, extra columns...) that cannot be
//! read becomes a provenance note starting with [`WARNING`], never an error.

pub mod csv;
pub mod cwru;
pub mod mat5;
pub(crate) mod mat_layout;
pub mod memory;
pub mod mfpt;
pub mod snapshots;
pub mod wav;
pub mod wav_header;

use crate::config::{Acquisition, RigConfig};
use crate::recording::mcap::file_writer::default_block_len;
use crate::recording::mcap::{read_recording_with_losses, RecordingReader};
use crate::recording::stream::{BlockStream, McapStream, MemoryStream};
use crate::recording::{captures, Losses, NominalSpeed, Recording, Tacho};
use anyhow::{bail, Context, Result};
use std::path::Path;

/// Options a user may give on the command line to override what a file or rig says.
#[derive(Debug, Clone, Default)]
pub struct ImportOptions {
    /// Sample rate override, Hz (`--sample-rate`): wins over everything.
    pub sample_rate: Option<f64>,
    /// Speed override, rpm.
    pub rpm: Option<f64>,
    /// A sample rate declared beside the file (a manifest's `sample_rate_hz` column) and where
    /// it was declared ("labels.csv line 4"): wins over the rig file's default, but a file that
    /// carries a different rate is a mismatch error naming both.
    pub declared_sample_rate: Option<(f64, String)>,
    /// A nominal speed declared beside the file (a manifest's `rpm` column), rpm, and where it
    /// was declared: a hint carried to [`Recording::nominal_rpm`] for the speed stage to check
    /// against the vibration, unlike `rpm`, which overrides.
    pub nominal_rpm: Option<(f64, String)>,
}

/// Prefix of provenance notes that warn: side data an importer could not read (kept as text),
/// or a stored speed the vibration contradicts.
pub const WARNING: &str = "warning: ";

/// Metadata key holding the rig id a recording was imported with.
pub const META_RIG_ID: &str = "rig_id";
/// Metadata key holding the rig file (TOML text) a recording was imported with.
pub const META_RIG_CONFIG: &str = "rig_config";
/// Metadata key holding the speed a file stored, when the vibration showed it off and another
/// was used (`Recording::rpm`).
pub const META_STORED_RPM: &str = "stored_rpm";

/// The formats [`load`] understands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Mat,
    Wav,
    Csv,
    Mcap,
}

/// Decide the format from the first bytes, then from the extension.
pub fn detect_format(path: &Path, head: &[u8]) -> Result<Format> {
    if head.starts_with(b"MATLAB") {
        return Ok(Format::Mat);
    }
    if head.starts_with(b"\x89MCAP") {
        return Ok(Format::Mcap);
    }
    if head.starts_with(b"RIFF") || head.starts_with(b"RIFX") || head.starts_with(b"RF64") {
        return Ok(Format::Wav);
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "mat" => Ok(Format::Mat),
        "wav" => Ok(Format::Wav),
        "mcap" => Ok(Format::Mcap),
        "csv" | "txt" | "tsv" => Ok(Format::Csv),
        _ => bail!(
            "{}: unknown recording format (not MAT v5, WAV or MCAP by content, extension {:?}); \
             supported: .mat (MAT v5/v7), .wav, .csv, .mcap",
            path.display(),
            ext
        ),
    }
}

/// The format of a file, from its first bytes and its name, with its magic checked before
/// anything else is read (a 2 GiB file of something else is refused at once), and its size.
pub fn sniff(path: &Path) -> Result<(Format, u64)> {
    let p = path.display();
    let meta = std::fs::metadata(path).with_context(|| format!("{p}: cannot open"))?;
    if meta.is_dir() {
        bail!("{p}: is a folder, not a recording");
    }
    if meta.len() == 0 {
        bail!("{p}: the file is empty (0 bytes)");
    }
    let mut head = Vec::with_capacity(128);
    {
        use std::io::Read;
        std::fs::File::open(path)
            .with_context(|| format!("{p}: cannot open"))?
            .take(128)
            .read_to_end(&mut head)
            .with_context(|| format!("{p}: cannot read"))?;
    }
    let format = detect_format(path, &head)?;
    let named = |e: &str| format!("{p}: {e} (the file is {})", memory::size_text(meta.len()));
    match format {
        // A MAT v5 header: 116 bytes of text, version and endian indicator.
        Format::Mat => {
            if let Err(e) = mat5::parse(&head) {
                bail!(named(&e.to_string()));
            }
        }
        Format::Mcap if !head.starts_with(mcap::MAGIC) => bail!(named(
            "not an MCAP file (no MCAP magic at the start; rigmon MCAP files begin with \\x89MCAP0)"
        )),
        Format::Wav
            if !(head.starts_with(b"RIFF")
                || head.starts_with(b"RIFX")
                || head.starts_with(b"RF64")) =>
        {
            bail!(named("not a WAV file (no RIFF header at the start)"))
        }
        Format::Csv => csv::check_text(path, meta.len())?,
        _ => {}
    }
    Ok((format, meta.len()))
}

/// Open any supported recording as a stream of blocks. rigmon MCAP and WAV files stream from
/// disk (memory does not grow with the file); CWRU/MFPT `.mat` and CSV are read whole first
/// ([`load`]). Non-MCAP streams carry `rig_id` and `rig_config` like [`load`]'s recordings.
pub fn open(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Box<dyn BlockStream>> {
    check_options(opts)?;
    if path.is_dir() {
        let s = snapshots::open(path, rig, opts)?;
        warn_notes(path, &s.info().provenance.notes);
        return Ok(Box::new(s));
    }
    let (format, _) = sniff(path)?;
    match format {
        Format::Mcap => {
            let mut s = McapStream::new(RecordingReader::open(path)?)?;
            let info = s.info_mut();
            let mut notes = Vec::new();
            apply_overrides(&mut info.sample_rate, &mut info.rpm, opts, &mut notes);
            info.provenance.notes.extend(notes);
            if captures::is_capture_series(&s.info().metadata) {
                return Ok(Box::new(snapshots::stream::RecordedSeries(Box::new(s))));
            }
            Ok(Box::new(s))
        }
        Format::Wav => {
            let mut s = wav::open(path, rig, opts)?;
            for note in s.info_mut().provenance.notes.iter() {
                if let Some(w) = note.strip_prefix(WARNING) {
                    tracing::warn!("{}: {w}", path.display());
                }
            }
            stamp_rig(&mut s.info_mut().metadata, rig);
            Ok(Box::new(s))
        }
        Format::Mat | Format::Csv => {
            let rec = load(path, rig, opts)?;
            let block = default_block_len(rec.sample_rate);
            Ok(Box::new(MemoryStream::new(rec, block)))
        }
    }
}

/// `--sample-rate` and `--rpm` over what an MCAP file stores, noted.
fn apply_overrides(
    sample_rate: &mut f64,
    rpm: &mut Option<f64>,
    opts: &ImportOptions,
    notes: &mut Vec<String>,
) {
    if let Some(fs) = opts.sample_rate {
        if (fs - *sample_rate).abs() > 1e-3 * *sample_rate {
            notes.push(format!(
                "sample rate {fs} Hz from --sample-rate overrides the file's {} Hz",
                sample_rate
            ));
            *sample_rate = fs;
        }
    }
    if let Some(r) = opts.rpm {
        *rpm = Some(r);
        notes.push(format!("rpm {r} from --rpm"));
    }
}

/// Read any supported recording, chosen by content and extension.
///
/// Non-MCAP inputs get `rig_id` and `rig_config` (the rig TOML) in their metadata, so an MCAP
/// written from them records which rig they were read with; MCAP inputs keep what they carry.
/// A damaged or cut MCAP file reads up to what is intact around the damage; what was lost is
/// logged (a warning on stderr) and noted (see [`load_with_losses`]).
pub fn load(path: &Path, rig: &RigConfig, opts: &ImportOptions) -> Result<Recording> {
    load_with_losses(path, rig, opts).map(|(rec, _)| rec)
}

/// [`load`], and what could not be read (empty for every format but a damaged MCAP file).
pub fn load_with_losses(
    path: &Path,
    rig: &RigConfig,
    opts: &ImportOptions,
) -> Result<(Recording, Losses)> {
    check_options(opts)?;
    if path.is_dir() {
        let mut rec = snapshots::load(path, rig, opts)?;
        carry_nominal_rpm(&mut rec, opts);
        warn_notes(path, &rec.provenance.notes);
        return Ok((rec, Losses::default()));
    }
    let (format, size) = sniff(path)?;
    memory::check_whole_read(path, format, size, &memory::available())?;
    if format == Format::Mcap {
        if let Some(series) = snapshots::stream::recorded_series(path, opts)? {
            return Ok(series);
        }
    }
    let mut rec = match format {
        Format::Mat => mat_layout::load(path, rig, opts)?,
        Format::Wav => wav::load(path, rig, opts)?,
        Format::Csv => csv::load(path, rig, opts)?,
        Format::Mcap => {
            let (mut rec, losses) = read_recording_with_losses(path)?;
            let mut notes = Vec::new();
            apply_overrides(&mut rec.sample_rate, &mut rec.rpm, opts, &mut notes);
            rec.provenance.notes.extend(notes);
            // rigmon's own recordings keep what a live source delivered, NaN/Inf bursts
            // included (losing nothing); the daemon's pipeline flags and zeroes them per window.
            check_finite_tacho_edges(path, &rec)?;
            carry_nominal_rpm(&mut rec, opts);
            let filled = losses.gap_samples() as usize
                * (rec.channels.len()
                    + usize::from(matches!(rec.tacho, Some(Tacho::Analog { .. }))));
            let bad = count_non_finite(&rec).saturating_sub(filled);
            if bad > 0 {
                rec.provenance.notes.push(format!(
                    "{bad} NaN/Inf samples kept as recorded (the daemon flags them per window; \
                     `rigmon features` refuses such windows)"
                ));
            }
            if !losses.is_empty() {
                tracing::warn!("{}: {}", path.display(), losses.line(rec.sample_rate));
            }
            return Ok((rec, losses));
        }
    };
    if rec.is_empty() {
        bail!("{}: the recording holds no samples", path.display());
    }
    check_finite(path, &rec)?;
    carry_nominal_rpm(&mut rec, opts);
    if opts.rpm.is_none() {
        check_stored_speed(&mut rec, rig);
    }
    warn_notes(path, &rec.provenance.notes);
    stamp_rig(&mut rec.metadata, rig);
    Ok((rec, Losses::default()))
}

/// Log the provenance notes that warn.
fn warn_notes(path: &Path, notes: &[String]) {
    for note in notes {
        if let Some(w) = note.strip_prefix(WARNING) {
            tracing::warn!("{}: {w}", path.display());
        }
    }
}

/// Put a declared nominal speed on the recording as a hint (not as its speed) and say so.
fn carry_nominal_rpm(rec: &mut Recording, opts: &ImportOptions) {
    if let Some((rpm, place)) = &opts.nominal_rpm {
        rec.provenance.notes.push(format!(
            "nominal speed {rpm} rpm from {place} (a hint, to be checked against the vibration)"
        ));
        rec.nominal_rpm = Some(NominalSpeed {
            rpm: *rpm,
            declared_at: place.clone(),
        });
    }
}

/// Where the rig reads speed from the recording (`[speed] source = "recording"`), check the
/// file's stored speed against its own 1x line ([`crate::dsp::stored_speed`]) and use the
/// vibration's where the stored one is clearly off; the stored value stays in the metadata
/// (`stored_rpm`) and the provenance says what was done. A speed given on the command line
/// (`--rpm`) is never checked; rigmon's own MCAP recordings keep what they carry.
fn check_stored_speed(rec: &mut Recording, rig: &RigConfig) {
    let (Some(within), Some(stored)) = (rig.speed.stored_speed_check(), rec.rpm) else {
        return;
    };
    let Some(ch) = rig
        .classifier_channel()
        .and_then(|c| rec.channel(&c.name))
        .or_else(|| rec.channels.first())
    else {
        return;
    };
    let checked = crate::dsp::stored_speed::check(&ch.samples, rec.sample_rate, stored, within);
    let name = ch.name.clone();
    match checked {
        Ok(c) if c.replaced() => {
            rec.metadata.insert(META_STORED_RPM.into(), stored.to_string());
            rec.rpm = Some(c.rpm);
            rec.provenance.notes.push(format!(
                "{WARNING}the file stores {stored} rpm but channel {:?} turns at {:.1} rpm ({:+.2} %, its 1x line searched within +-{:.0} %): \
                 using {:.1} rpm (set [speed] check_within_percent = 0 in the rig file, or pass --rpm, to keep the stored value)",
                name,
                c.rpm,
                100.0 * c.off,
                100.0 * within,
                c.rpm
            ));
        }
        Ok(c) => rec.provenance.notes.push(format!(
            "stored speed {stored} rpm checked against channel {:?}: 1x line at {:.1} rpm ({:+.2} %), kept",
            name,
            c.estimate.rpm,
            100.0 * c.off
        )),
        Err(e) => rec.provenance.notes.push(format!(
            "stored speed {stored} rpm not checked against the vibration: {e}"
        )),
    }
}

/// Record which rig a recording belongs to: `rig_id` and `rig_config` (the rig as TOML) in its
/// metadata (the simulator and the recording sink can use this too).
pub fn stamp_rig(metadata: &mut std::collections::BTreeMap<String, String>, rig: &RigConfig) {
    metadata.insert(META_RIG_ID.into(), rig.machine.id.clone());
    if let Ok(text) = toml::to_string(rig) {
        metadata.insert(META_RIG_CONFIG.into(), text);
    }
}

fn check_options(opts: &ImportOptions) -> Result<()> {
    if let Some(fs) = opts.sample_rate {
        if !(fs.is_finite() && fs > 0.0) {
            bail!("--sample-rate {fs}: must be a positive number of Hz");
        }
    }
    if let Some((fs, place)) = &opts.declared_sample_rate {
        if !(fs.is_finite() && *fs > 0.0) {
            bail!("{place}: sample rate {fs}: must be a positive number of Hz");
        }
    }
    if let Some(rpm) = opts.rpm {
        if !(rpm.is_finite() && rpm > 0.0) {
            bail!("--rpm {rpm}: must be a positive number");
        }
    }
    if let Some((rpm, place)) = &opts.nominal_rpm {
        if !(rpm.is_finite() && *rpm > 0.0) {
            bail!("{place}: nominal speed {rpm} rpm: must be a positive number");
        }
    }
    Ok(())
}

/// Two rates differ when they are more than 0.1 % apart.
fn rates_differ(a: f64, b: f64) -> bool {
    (a - b).abs() > 1e-3 * a.abs().max(b.abs())
}

/// Settle the sample rate by one rule for every importer, strongest first:
/// 1. `--sample-rate` wins (noting what it overrides);
/// 2. a rate declared beside the file (`opts.declared_sample_rate`, a manifest column) must agree
///    (0.1 %) with the rate the file fixes, if any: a conflict is a `sample-rate mismatch` error
///    naming both numbers;
/// 3. the rate the file fixes (`file_rate`, with `what` saying where it comes from: "WAV
///    header", "time column", "CWRU catalogue (record 97)"...);
/// 4. the rig's `acquisition.sample_rate_hz`, the default for files that carry no rate (a file
///    that fixes another rate uses its own and says so at debug level and in the note);
/// 5. else an error saying to pass `--sample-rate`.
///
/// Returns the rate and a provenance note.
pub fn resolve_sample_rate(
    path: &Path,
    file_rate: Option<(f64, String)>,
    acquisition: &Acquisition,
    opts: &ImportOptions,
) -> Result<(f64, String)> {
    if let Some(fs) = opts.sample_rate {
        let note = match &file_rate {
            Some((f, what)) if rates_differ(*f, fs) => {
                format!("sample rate {fs} Hz from --sample-rate (overrides {f} Hz from the {what})")
            }
            _ => format!("sample rate {fs} Hz from --sample-rate"),
        };
        return Ok((fs, note));
    }
    if let Some((f, what)) = &file_rate {
        if !(f.is_finite() && *f > 0.0) {
            bail!(
                "{}: the {what} gives an invalid sample rate ({f} Hz); pass --sample-rate HZ",
                path.display()
            );
        }
    }
    if let Some((d, place)) = &opts.declared_sample_rate {
        return match &file_rate {
            Some((f, what)) if rates_differ(*f, *d) => bail!(
                "{}: sample-rate mismatch: the {what} says {f} Hz but {place} says {d} Hz; \
                 correct (or empty) that sample_rate_hz entry, or pass --sample-rate HZ to say which is right",
                path.display()
            ),
            Some((_, what)) => Ok((
                *d,
                format!("sample rate {d} Hz from {place} (agrees with the {what})"),
            )),
            None => Ok((*d, format!("sample rate {d} Hz from {place}"))),
        };
    }
    let rig_rate = acquisition.sample_rate_hz;
    match (file_rate, rig_rate) {
        (Some((f, what)), Some(g)) => {
            if rates_differ(f, g) {
                let note = format!(
                    "sample rate {f} Hz from the {what} (the rig file's acquisition.sample_rate_hz = {g} Hz \
                     is the default for files that carry no rate)"
                );
                tracing::debug!("{}: {note}", path.display());
                Ok((f, note))
            } else {
                Ok((
                    f,
                    format!("sample rate {f} Hz from the {what} (agrees with the rig file)"),
                ))
            }
        }
        (Some((f, what)), None) => Ok((f, format!("sample rate {f} Hz from the {what}"))),
        (None, Some(g)) => Ok((g, format!("sample rate {g} Hz from the rig file"))),
        (None, None) => bail!(
            "{}: the sample rate is unknown: the file does not store it and the rig file has no \
             acquisition.sample_rate_hz; pass --sample-rate HZ",
            path.display()
        ),
    }
}

/// A channel's samples as f32 after its sensitivity `k`, refusing a finite value beyond the
/// range of f32 (it would become inf and be reported as inf, not as the number the file holds).
pub(crate) fn scaled_f32(path: &Path, channel: &str, values: &[f64], k: f64) -> Result<Vec<f32>> {
    let too_big = |x: f64| x.is_finite() && (x * k).abs() > f64::from(f32::MAX);
    if let Some(i) = values.iter().position(|&x| too_big(x)) {
        bail!(
            "{}: channel {channel:?}: sample {i} is {:e}{}, beyond the range of the 32-bit floats \
             recordings hold (+-3.4e38); check the file's scaling or the channel's sensitivity",
            path.display(),
            values[i],
            if k == 1.0 {
                String::new()
            } else {
                format!(" (times sensitivity {k})")
            }
        );
    }
    Ok(values.iter().map(|&x| (x * k) as f32).collect())
}

/// NaN/Inf samples in the acceleration channels and the analog tacho.
pub fn count_non_finite(rec: &Recording) -> usize {
    let tacho = match &rec.tacho {
        Some(Tacho::Analog { samples, .. }) => samples.iter().filter(|x| !x.is_finite()).count(),
        _ => 0,
    };
    rec.channels
        .iter()
        .map(|c| c.samples.iter().filter(|x| !x.is_finite()).count())
        .sum::<usize>()
        + tacho
}

/// Tacho edge times must be finite (a NaN edge has no place on the sample clock).
fn check_finite_tacho_edges(path: &Path, rec: &Recording) -> Result<()> {
    if let Some(Tacho::Edges { times_s }) = &rec.tacho {
        if let Some(i) = times_s.iter().position(|x| !x.is_finite()) {
            bail!(
                "{}: tacho edge {i} is {}; edge times must be finite",
                path.display(),
                times_s[i]
            );
        }
    }
    Ok(())
}

/// Refuse NaN/Inf samples, naming the channel and the sample index.
pub fn check_finite(path: &Path, rec: &Recording) -> Result<()> {
    for ch in &rec.channels {
        if let Some(i) = ch.samples.iter().position(|x| !x.is_finite()) {
            bail!(
                "{}: channel {:?}: sample {i} (t = {:.6} s) is {}; recordings must hold finite numbers only",
                path.display(),
                ch.name,
                i as f64 / rec.sample_rate,
                ch.samples[i]
            );
        }
    }
    match &rec.tacho {
        Some(Tacho::Analog { samples, .. }) => {
            if let Some(i) = samples.iter().position(|x| !x.is_finite()) {
                bail!(
                    "{}: tacho channel: sample {i} (t = {:.6} s) is {}; recordings must hold finite numbers only",
                    path.display(),
                    i as f64 / rec.sample_rate,
                    samples[i]
                );
            }
        }
        Some(Tacho::Edges { .. }) => check_finite_tacho_edges(path, rec)?,
        None => {}
    }
    Ok(())
}

/// The rig's classifier channel must be among the imported channels.
pub(crate) fn check_classifier_channel(
    path: &Path,
    rig: &RigConfig,
    rec: &Recording,
    what_missing: &str,
) -> Result<()> {
    if let Some(c) = rig.classifier_channel() {
        if rec.channel(&c.name).is_none() {
            let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
            return check_classifier_names(path, rig, &names, what_missing);
        }
    }
    Ok(())
}

/// [`check_classifier_channel`] on the names of the channels a file provides.
pub(crate) fn check_classifier_names(
    path: &Path,
    rig: &RigConfig,
    names: &[&str],
    what_missing: &str,
) -> Result<()> {
    if let Some(c) = rig.classifier_channel() {
        if !names.iter().any(|n| *n == c.name) {
            bail!(
                "{}: missing {what_missing} for rig channel {:?}, which feeds the classifier (features.classifier_axis = {:?}); \
                 the file provides {:?}",
                path.display(),
                c.name,
                rig.features.classifier_axis,
                names
            );
        }
    }
    Ok(())
}
