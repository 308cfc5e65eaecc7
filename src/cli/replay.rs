//! `rigmon replay <file>`: a recording (any format the importers read) through the monitoring
//! pipeline, one health line per window on stdout and a summary on stderr. Publishes to Zenoh
//! only when zenoh flags are given; SIGHUP reloads the model file.

use crate::acquire::{FileSourceConfig, ReplaySpeed, SourceConfig};
use crate::daemon::config::{DaemonConfig, ModelConfig, PipelineConfig};
use crate::daemon::{self, DaemonOptions, Output};
use crate::health::HealthPolicy;
use crate::publish::zenoh::{ZenohArgs, ZenohSettings, REPLAY_WAIT_BEFORE_DROP};
use crate::recorder::RecordConfig;
use anyhow::{bail, Result};
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `rigmon replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The recording: rigmon MCAP, any-layout .mat, WAV or CSV.
    pub file: PathBuf,
    /// Rig file.
    #[arg(long, default_value = "config/lut-rig.toml")]
    pub rig: PathBuf,
    /// ONNX classifier.
    #[arg(long, default_value = "models/lut-rig.onnx")]
    pub model: PathBuf,
    /// Replay speed: a real-time factor (1 = real time) or "max".
    #[arg(long, default_value = "max")]
    pub speed: String,
    /// Print one JSON health message per line instead of text.
    #[arg(long)]
    pub json: bool,
    /// Print nothing per window (only the summary).
    #[arg(long, conflicts_with = "json")]
    pub quiet: bool,
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
    /// Health policy as a TOML file with the keys of `[health]` (vote_n, vote_k, dwell_s, ...).
    #[arg(long)]
    pub health: Option<PathBuf>,
    /// Record raw, features and health to MCAP files in this folder.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// With zenoh: wait up to this many seconds for a subscriber before starting.
    #[arg(long, value_name = "SECONDS")]
    pub wait_subscriber: Option<f64>,
    /// Print the summary as JSON on stderr.
    #[arg(long)]
    pub summary_json: bool,
    /// Use a model trained for another rig on purpose (its rig id, axis, bearing orders or
    /// recipe differ from the rig file's); every health message then lists the differences.
    #[arg(long)]
    pub allow_foreign_model: bool,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

pub fn run(args: Args) -> Result<()> {
    if !args.file.exists() {
        bail!("{}: no such file; the shipped replays are in replay/ (e.g. replay/lut-outer_race-588rpm.mcap)", args.file.display());
    }
    for (what, p, hint) in [
        ("rig file", &args.rig, "pass --rig <toml> (config/lut-rig.toml for the shipped replays, config/cwru-de.toml for CWRU files)"),
        ("model", &args.model, "pass --model <onnx>, or train one with `rigmon train`"),
    ] {
        if !p.exists() {
            bail!("{what} {} not found; {hint}", p.display());
        }
    }
    let speed: ReplaySpeed = args
        .speed
        .parse()
        .map_err(|e: String| anyhow::anyhow!("--speed: {e}"))?;
    let mut source = FileSourceConfig::new(&args.file);
    source.speed = speed;
    source.sample_rate_hz = args.read.sample_rate;
    source.rpm = args.read.rpm;
    let health = match &args.health {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| anyhow::anyhow!("--health {}: {e}", p.display()))?;
            toml::from_str::<HealthPolicy>(&text)
                .map_err(|e| anyhow::anyhow!("--health {}: {e}", p.display()))?
        }
        None => HealthPolicy::default(),
    };
    let zenoh = if args.zenoh.any() {
        ZenohSettings {
            wait_before_drop: Some(REPLAY_WAIT_BEFORE_DROP),
            ..args.zenoh.apply(ZenohSettings::default())
        }
    } else {
        ZenohSettings {
            enabled: false,
            ..Default::default()
        }
    };
    let recording = match &args.record {
        Some(dir) => RecordConfig {
            enabled: true,
            dir: dir.clone(),
            ..Default::default()
        },
        None => RecordConfig::default(),
    };
    let config = DaemonConfig {
        rig: args.rig.clone(),
        source: SourceConfig::File(source),
        model: ModelConfig {
            path: args.model.clone(),
            allow_foreign: args.allow_foreign_model,
        },
        health,
        pipeline: PipelineConfig::default(),
        zenoh,
        recording,
    };
    config.validate()?;
    let mut opts = DaemonOptions::new(config);
    opts.output = if args.json {
        Output::Json
    } else if args.quiet {
        Output::None
    } else {
        Output::Lines
    };
    opts.lossless = true;
    opts.use_signals = true;
    opts.wait_for_subscriber = args.wait_subscriber.map(Duration::from_secs_f64);
    let summary = daemon::run(opts)?;
    if args.summary_json {
        eprintln!("{}", serde_json::to_string(&summary)?);
    } else {
        eprintln!("{}", summary.text());
    }
    Ok(())
}
