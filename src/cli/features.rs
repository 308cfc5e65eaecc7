//! `rigmon features <recording> --rig <toml>`: envelope-order-spectrum features per window,
//! as JSON Lines (`--json`) or a short text table.

use crate::analysis;
use crate::config::RigConfig;
use crate::dsp::{FeatureWindow, SpeedTrack};
use crate::importers;
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `rigmon features`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording: rigmon .mcap, any-layout .mat, .wav or .csv.
    pub recording: PathBuf,
    /// Rig file (channels, speed source, feature recipe).
    #[arg(long)]
    pub rig: PathBuf,
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
    /// Print one JSON object per window (JSON Lines).
    #[arg(long)]
    pub json: bool,
}

/// One JSON line: the window plus the bin layout.
#[derive(Serialize)]
struct Line<'a> {
    #[serde(flatten)]
    window: &'a FeatureWindow,
    bin_width: f64,
    max_order: f64,
}

pub fn run(args: Args) -> Result<()> {
    match features(args) {
        // `rigmon features ... | head` is fine
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        r => r,
    }
}

fn features(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let opts = args.read.import_options();
    let rec = importers::load(&args.recording, &rig, &opts)?;
    // The recipe at the file's rate and its length, before anything is sized by them.
    let what = format!("recording {}", args.recording.display());
    rig.check_recipe_at(rec.sample_rate, rec.rpm, &what)?;
    rig.features
        .check_length(rec.len(), rec.sample_rate)
        .with_context(|| what.clone())?;
    let windows = match args.read.rpm {
        Some(rpm) => analysis::extract_with_speed(&rec, &rig, &SpeedTrack::fixed(rpm)?)?,
        None => analysis::extract_recording(&rec, &rig)?,
    }
    .into_iter();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let classifier = rig
        .classifier_channel()
        .map(|c| c.name.clone())
        .unwrap_or_default();
    if !args.json {
        writeln!(
            out,
            "{:>8} {:>8} {:>8} {:>9} {:>6} {:>9}  {:<30} quality",
            "t_start",
            "t_end",
            "rpm",
            "source",
            "revs",
            "res(ord)",
            format!("top bins ({classifier})")
        )?;
    }
    for w in windows {
        if args.json {
            serde_json::to_writer(
                &mut out,
                &Line {
                    window: &w,
                    bin_width: rig.features.bin_width_order,
                    max_order: rig.features.max_order,
                },
            )
            .map_err(std::io::Error::from)?;
            writeln!(out)?;
        } else {
            let f = w.classifier_features(&rig);
            let mut idx: Vec<usize> = (0..f.len()).collect();
            idx.sort_by(|&a, &b| f[b].total_cmp(&f[a]));
            let top: Vec<String> = idx
                .iter()
                .take(3)
                .map(|&k| {
                    let w = rig.features.bin_width_order;
                    format!("{:.1}-{:.1}", k as f64 * w, (k + 1) as f64 * w)
                })
                .collect();
            let flags = w.quality.flags();
            writeln!(
                out,
                "{:>8.3} {:>8.3} {:>8.1} {:>9} {:>6.2} {:>9.3}  {:<30} {}",
                w.t_start,
                w.t_end,
                w.rpm,
                w.speed_source,
                w.quality.revolutions,
                w.quality.order_resolution,
                top.join(" "),
                if flags.is_empty() {
                    "ok".to_string()
                } else {
                    flags.join(",")
                }
            )?;
        }
    }
    out.flush().context("writing to stdout")?;
    Ok(())
}
