//! `rigmon repair <in.mcap> -o <out.mcap>`: rewrite a damaged, cut or unfinished MCAP file as
//! a clean, finished one that every MCAP reader opens (see [`crate::recording::mcap::repair`]);
//! prints what was copied and skipped, and for a rigmon recording the samples and seconds lost.

use crate::recording::mcap::repair::{repair, RepairReport};
use crate::recording::mcap::RecordingReader;
use crate::recording::LossReport;
use anyhow::Result;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Arguments of `rigmon repair`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The MCAP file to repair (left as it is).
    pub input: PathBuf,
    /// The repaired copy.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    repair: RepairReport,
    /// For a rigmon recording: the samples and seconds the input lost.
    #[serde(skip_serializing_if = "Option::is_none")]
    losses: Option<LossReport>,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(&[("-o", &args.output)], &[("", &args.input)])?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let repaired = repair(&args.input, &args.output)?;
    let losses = rigmon_losses(&args.input);
    if args.json {
        let r = Report {
            repair: repaired,
            losses,
        };
        println!("{}", serde_json::to_string(&r)?);
        return Ok(());
    }
    println!("{}: {}", args.output.display(), repaired.line());
    if let Some(l) = losses {
        println!("{}: {}", args.input.display(), l.summary);
    }
    Ok(())
}

/// The samples and seconds a rigmon recording lost (reading it as a stream), when it is one
/// and lost anything.
fn rigmon_losses(input: &Path) -> Option<LossReport> {
    let mut r = RecordingReader::open(input).ok()?;
    while let Ok(Some(_)) = r.next_block() {}
    let l = r.losses();
    (!l.is_empty()).then(|| l.report(r.info().sample_rate))
}
