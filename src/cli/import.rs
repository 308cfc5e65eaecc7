//! `rigmon import <file> --rig <toml> -o <out.mcap>`: read a `.mat` (any layout), WAV, CSV (or
//! rigmon MCAP) recording and write it in the rigmon MCAP layout; prints a one-line summary.

use crate::config::RigConfig;
use crate::importers::{self, ImportOptions};
use crate::recording::mcap::write_recording;
use crate::recording::{Recording, Tacho};
use anyhow::{Context, Result};
use std::path::PathBuf;

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
    /// Sample rate in Hz (overrides the file and the rig file).
    #[arg(long)]
    pub sample_rate: Option<f64>,
    /// Shaft speed in rpm (overrides the file).
    #[arg(long)]
    pub rpm: Option<f64>,
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let opts = ImportOptions {
        sample_rate: args.sample_rate,
        rpm: args.rpm,
        ..Default::default()
    };
    let rec = importers::load(&args.file, &rig, &opts)?;
    write_recording(&args.output, &rec)
        .with_context(|| format!("writing {}", args.output.display()))?;
    println!("{}", summary_line(&rec, &args.output.display().to_string()));
    Ok(())
}

/// "out.mcap: 3 channels (DE, FE, BA), 121265 samples @ 12000 Hz, 10.105 s, rpm 1797, tacho none, label inner_race"
pub fn summary_line(rec: &Recording, out: &str) -> String {
    let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
    let rpm = rec.rpm.map_or("unknown".to_string(), |r| format!("{r}"));
    let tacho = match &rec.tacho {
        None => "none".to_string(),
        Some(Tacho::Analog { unit, .. }) => format!("analog ({unit})"),
        Some(Tacho::Edges { times_s }) => format!("{} edges", times_s.len()),
    };
    let mut line = format!(
        "{out}: {} channel(s) ({}), {} samples @ {} Hz, {:.3} s, rpm {rpm}, tacho {tacho}",
        rec.channels.len(),
        names.join(", "),
        rec.len(),
        rec.sample_rate,
        rec.duration_s()
    );
    if let Some(l) = rec.label() {
        line.push_str(&format!(", label {l}"));
    }
    line
}
