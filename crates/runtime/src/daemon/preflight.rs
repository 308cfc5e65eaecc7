//! The checks a daemon makes before anything starts, written once: `rigmon run` (through
//! [`super::run`]), `rigmon replay` and `rigmon run --check` all call [`preflight`], so
//! `--check` says `ok` exactly when `run` would start. In order: the daemon config (its keys,
//! Zenoh endpoints and their ports), the rig file (with the recipe's bounds), the model (its
//! layout, and its identity unless `[model] allow_foreign`), the source (opened; the recipe at
//! its sample rate and stored speed, a recording long enough for one window), the Zenoh listen
//! ports free, and the recording folder. A recording folder that cannot be created does not
//! stop `run` (recording problems never stop monitoring): it comes back as a problem that
//! `run` reports and `--check` fails on.

use super::config::DaemonConfig;
use super::reload;
use crate::acquire::{Source, SourceConfig};
use crate::config::RigConfig;
use crate::model::identity::Mismatch;
use crate::model::onnx::OnnxClassifier;
use crate::recorder::RecordConfig;
use anyhow::{Context, Result};

/// What passed the checks, ready to run.
pub struct Checked {
    pub rig: RigConfig,
    pub model: OnnxClassifier,
    /// The source, opened.
    pub source: Box<dyn Source>,
    /// How the model differs from the rig (a foreign model allowed on purpose), else empty.
    pub foreign: Vec<Mismatch>,
    /// Problems monitoring survives (it starts, reports them and retries): a recording
    /// folder that cannot be created.
    pub problems: Vec<String>,
}

/// Run every check; the first that fails is the error, naming the file and key.
pub fn preflight(config: &DaemonConfig) -> Result<Checked> {
    config.validate()?;
    let rig = config.load_rig()?;
    let model = reload::load_model(
        &config.model.path,
        &rig,
        &config.rig,
        config.model.allow_foreign,
    )?;
    let foreign = model.foreign_to(&rig);
    let source = open_source(&config.source, &rig)?;
    if config.zenoh.enabled {
        config.zenoh.check_listen_ports()?;
    }
    let problems = recording_problem(&config.recording).into_iter().collect();
    Ok(Checked {
        rig,
        model,
        source,
        foreign,
        problems,
    })
}

/// Open the source and check the recipe at its sample rate (and a recording's stored speed)
/// before the pipeline sizes anything by it. A recording is streamed from disk
/// ([`crate::acquire::stream_replay::StreamReplay`], which makes these checks itself and
/// refuses a recording too short for one window: up front when its length is known, else at
/// its end).
fn open_source(config: &SourceConfig, rig: &RigConfig) -> Result<Box<dyn Source>> {
    if let SourceConfig::File(c) = config {
        return Ok(Box::new(c.open(rig).context("cannot start the source")?));
    }
    let source = config.build(rig).context("cannot start the source")?;
    let what = format!("source {}", source.describe());
    rig.check_recipe_at(source.sample_rate(), source.nominal_rpm(), &what)?;
    Ok(source)
}

/// Why recording cannot start (its folder cannot be created or written), if it cannot.
fn recording_problem(r: &RecordConfig) -> Option<String> {
    if !r.enabled {
        return None;
    }
    let probe = || -> std::io::Result<()> {
        std::fs::create_dir_all(&r.dir)?;
        let p = r.dir.join(format!(".rigmon-check-{}", std::process::id()));
        std::fs::File::create(&p)?;
        std::fs::remove_file(&p)
    };
    probe().err().map(|e| {
        format!(
            "recording.dir {}: cannot create the folder or a file in it ({e}); monitoring runs without recording and retries every {} s — fix the path or its permissions",
            r.dir.display(),
            super::record_sink::RETRY.as_secs()
        )
    })
}
