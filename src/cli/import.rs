//! `rigmon import <file> --rig <toml> -o <out.mcap>`: read a `.mat` (any layout), WAV, CSV (or
//! rigmon MCAP) recording and write it in the rigmon MCAP layout; prints a one-line summary
//! (`--json`: one JSON object). rigmon MCAP and WAV inputs are streamed block by block, so
//! memory does not grow with the file. A damaged or cut MCAP input is converted up to what is
//! intact around the damage: its gaps stay gaps in the output (never silence), and what was
//! lost is printed on stderr and reported in the summary (`losses` in the JSON).

use crate::config::RigConfig;
use crate::importers;
use crate::recording::mcap::{RecordingWriter, TachoInfo};
use crate::recording::stream::BlockStream;
use crate::recording::LossReport;
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Arguments of `rigmon import`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording to import: CWRU or MFPT .mat, .wav, .csv (or a rigmon .mcap).
    pub file: PathBuf,
    /// Rig file (TOML): channel map, units, sensitivities, sample rate.
    #[arg(long)]
    pub rig: PathBuf,
    /// Output MCAP file.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
    /// Print the summary as one JSON object instead of a line.
    #[arg(long)]
    pub json: bool,
}

/// What `rigmon import` wrote.
#[derive(Debug, Clone, Serialize)]
pub struct ImportSummary {
    pub output: String,
    pub channels: Vec<String>,
    /// Samples per channel on the sample clock (gaps included) and those the file holds.
    pub samples: u64,
    pub samples_present: u64,
    pub sample_rate_hz: f64,
    pub seconds: f64,
    pub rpm: Option<f64>,
    /// `none`, `analog (<unit>)` or `<n> edges`.
    pub tacho: String,
    pub label: Option<String>,
    /// What the input could not deliver (a damaged or cut MCAP file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub losses: Option<LossReport>,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(
        &[("-o", &args.output)],
        &[("", &args.file), ("--rig", &args.rig)],
    )?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let opts = args.read.import_options();
    let mut stream = importers::open(&args.file, &rig, &opts)?;
    let summary = match write_stream(stream.as_mut(), &args.output) {
        Ok(s) => s,
        Err(e) => {
            // No half-written output left behind to be taken for the import.
            let _ = std::fs::remove_file(&args.output);
            return Err(e.context(format!("writing {}", args.output.display())));
        }
    };
    if let Some(l) = &summary.losses {
        eprintln!("warning: {}: {}", args.file.display(), l.summary);
    }
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        println!("{}", summary_line(&summary));
    }
    Ok(())
}

/// Copy a stream block by block into a rigmon MCAP file.
pub fn write_stream(stream: &mut dyn BlockStream, out: &Path) -> Result<ImportSummary> {
    let mut info = stream.info().clone();
    info.provenance.notes.extend(stream.notes());
    let mut w = RecordingWriter::create(out, &info)?;
    let (mut samples, mut present, mut edges) = (0u64, 0u64, 0usize);
    while let Some(b) = stream.next_block()? {
        let chans: Vec<&[f32]> = b.channels.iter().map(Vec::as_slice).collect();
        w.write_block(
            b.first_sample,
            &chans,
            b.tacho_analog.as_deref(),
            &b.tacho_edges,
        )?;
        present += b.len() as u64;
        samples = b.first_sample + b.len() as u64;
        edges += b.tacho_edges.len();
    }
    w.finish()?;
    if present == 0 {
        bail!("the recording holds no samples");
    }
    let fs = info.sample_rate;
    let losses = stream.losses();
    Ok(ImportSummary {
        output: out.display().to_string(),
        channels: info.channels.iter().map(|c| c.name.clone()).collect(),
        samples,
        samples_present: present,
        sample_rate_hz: fs,
        seconds: samples as f64 / fs,
        rpm: info.rpm,
        tacho: match &info.tacho {
            TachoInfo::None => "none".to_string(),
            TachoInfo::Analog { unit } => format!("analog ({unit})"),
            TachoInfo::Edges => format!("{edges} edges"),
        },
        label: info.metadata.get("label").cloned(),
        losses: (!losses.is_empty()).then(|| losses.report(fs)),
    })
}

/// "out.mcap: 3 channel(s) (DE, FE, BA), 121265 samples @ 12000 Hz, 10.105 s, rpm 1797, tacho none, label inner_race"
pub fn summary_line(s: &ImportSummary) -> String {
    let rpm = s.rpm.map_or("unknown".to_string(), |r| format!("{r}"));
    let mut line = format!(
        "{}: {} channel(s) ({}), {} samples @ {} Hz, {:.3} s, rpm {rpm}, tacho {}",
        s.output,
        s.channels.len(),
        s.channels.join(", "),
        s.samples,
        s.sample_rate_hz,
        s.seconds,
        s.tacho
    );
    if let Some(l) = &s.label {
        line.push_str(&format!(", label {l}"));
    }
    if let Some(l) = &s.losses {
        line.push_str(&format!(
            "; {:.3} s ({} samples) lost in the input",
            l.seconds_lost, l.samples_lost
        ));
    }
    line
}
