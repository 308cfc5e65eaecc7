//! SIGHUP reload: re-read the daemon config (when there is one) and load the model it names
//! on a helper thread, so the pipeline keeps consuming samples meanwhile; the pipeline swaps
//! the new model in between two windows. A model that cannot be loaded, does not fit the rig
//! (its layout, or its identity unless `[model] allow_foreign`) or fails a test inference is
//! rejected and the running one kept. Changes to sections that
//! need a restart (rig, source, zenoh, recording) are reported, not applied.

use crate::config::RigConfig;
use crate::daemon::config::DaemonConfig;
use crate::health::HealthPolicy;
use crate::model::onnx::OnnxClassifier;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError};

/// What a successful reload produced.
pub struct Loaded {
    pub model: OnnxClassifier,
    pub model_id: String,
    pub model_path: PathBuf,
    pub policy: HealthPolicy,
    /// The new config (None when running without a config file).
    pub config: Option<DaemonConfig>,
    /// Sections that changed but need a restart.
    pub needs_restart: Vec<&'static str>,
}

/// A reload in progress.
#[derive(Default)]
pub struct Reloader {
    pending: Option<Receiver<Result<Loaded>>>,
}

impl Reloader {
    /// Start loading. `config_path` is re-read when given; otherwise the model at
    /// `model_path` is reloaded with the current `policy`.
    pub fn start(
        &mut self,
        config_path: Option<PathBuf>,
        current: Option<DaemonConfig>,
        model_path: PathBuf,
        policy: HealthPolicy,
        rig: RigConfig,
    ) {
        if self.pending.is_some() {
            tracing::info!("reload already in progress; ignoring this SIGHUP");
            return;
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let spawned = std::thread::Builder::new()
            .name("rigmon-reload".into())
            .spawn(move || {
                let _ = tx.send(load(
                    config_path.as_deref(),
                    current.as_ref(),
                    &model_path,
                    policy,
                    &rig,
                ));
            });
        match spawned {
            Ok(_) => self.pending = Some(rx),
            Err(e) => tracing::warn!("cannot start the reload thread: {e}"),
        }
    }

    pub fn in_progress(&self) -> bool {
        self.pending.is_some()
    }

    /// The reload's result once it is done.
    pub fn poll(&mut self) -> Option<Result<Loaded>> {
        let rx = self.pending.as_ref()?;
        match rx.try_recv() {
            Ok(r) => {
                self.pending = None;
                Some(r)
            }
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                self.pending = None;
                Some(Err(anyhow::anyhow!("the reload thread died")))
            }
        }
    }
}

/// The model's id: its file stem.
pub fn model_id(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "model".into())
}

/// Load a model and check that it can serve this rig (read from `rig_file`; also used at
/// start-up): its feature layout, and its identity unless `allow_foreign` (then logged, and
/// flagged in every health message by the analyzer).
pub fn load_model(
    path: &Path,
    rig: &RigConfig,
    rig_file: &Path,
    allow_foreign: bool,
) -> Result<OnnxClassifier> {
    let model = OnnxClassifier::load(path)?;
    model.check_identity(rig, rig_file, allow_foreign)?;
    if model.meta().labels.is_empty() {
        bail!("model {}: it names no class labels", path.display());
    }
    // A test inference catches models whose graph does not fit their metadata.
    let p = model
        .predict(&vec![0.0; rig.features.n_bins()])
        .with_context(|| format!("model {}: a test inference failed", path.display()))?;
    if p.probs.len() != model.meta().labels.len() {
        bail!(
            "model {}: it returns {} probabilities for {} labels; re-export it with `rigmon train`",
            path.display(),
            p.probs.len(),
            model.meta().labels.len()
        );
    }
    Ok(model)
}

fn load(
    config_path: Option<&Path>,
    current: Option<&DaemonConfig>,
    model_path: &Path,
    policy: HealthPolicy,
    rig: &RigConfig,
) -> Result<Loaded> {
    let (config, model_path, policy, needs_restart) = match config_path {
        Some(p) => {
            let c = DaemonConfig::load(p)?;
            let mut needs = Vec::new();
            if let Some(cur) = current {
                if c.rig != cur.rig {
                    needs.push("rig");
                }
                if c.source != cur.source {
                    needs.push("source");
                }
                if c.zenoh != cur.zenoh {
                    needs.push("zenoh");
                }
                if c.recording != cur.recording {
                    needs.push("recording");
                }
                if c.pipeline != cur.pipeline {
                    needs.push("pipeline");
                }
            }
            let mp = c.model.path.clone();
            let pol = c.health.clone();
            (Some(c), mp, pol, needs)
        }
        None => (None, model_path.to_path_buf(), policy, Vec::new()),
    };
    // The new config decides, else the running one (a replay's flag). The rig is the running
    // one (a new rig file needs a restart).
    let running = config.as_ref().or(current);
    let allow_foreign = running.is_some_and(|c| c.model.allow_foreign);
    let rig_file = current.map_or(PathBuf::from("<the rig file>"), |c| c.rig.clone());
    let model = load_model(&model_path, rig, &rig_file, allow_foreign)?;
    Ok(Loaded {
        model_id: model_id(&model_path),
        model,
        model_path,
        policy,
        config,
        needs_restart,
    })
}
