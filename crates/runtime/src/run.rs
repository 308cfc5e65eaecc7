//! `rigmon run --config <rigmon.toml>` and the service binary `rigmon-daemon --config
//! <rigmon.toml>`: the monitoring daemon (under systemd or by hand), one set of arguments.
//! SIGHUP reloads the config and swaps the model; SIGTERM/SIGINT stop cleanly. `--check` runs
//! exactly the checks `run` makes before it starts ([`crate::daemon::preflight`]) and exits.

use crate::acquire::SourceConfig;
use crate::daemon::config::DaemonConfig;
use crate::daemon::preflight::{preflight, Checked};
use crate::daemon::{self, DaemonOptions, Output};
use crate::publish::zenoh::ZenohArgs;
use anyhow::{bail, Result};
use std::path::PathBuf;

/// Arguments of `rigmon run` (and of `rigmon-daemon`, which takes exactly these).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Daemon config file.
    #[arg(long, short, default_value = "config/rigmon.toml")]
    pub config: PathBuf,
    /// Replay this recording instead of the config's source (keeps its other settings).
    #[arg(long, value_name = "FILE")]
    pub replay: Option<PathBuf>,
    /// Also print one line per health message on stdout ("text" or "json").
    #[arg(long, value_parser = ["text", "json"])]
    pub print: Option<String>,
    /// Run the checks `run` makes before it starts (config, rig and its bounds, model and
    /// its identity, source, ports, recording folder), print what would run, and exit.
    #[arg(long)]
    pub check: bool,
    /// Serve a model trained for another rig on purpose (as `[model] allow_foreign = true`);
    /// every health message then lists the differences.
    #[arg(long)]
    pub allow_foreign_model: bool,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
}

pub fn run(args: Args) -> Result<()> {
    let mut config = DaemonConfig::load(&args.config)?;
    if let Some(f) = &args.replay {
        match &mut config.source {
            SourceConfig::File(c) => c.path = f.clone(),
            other => {
                let mut c = crate::acquire::FileSourceConfig::new(f);
                c.looping = false;
                *other = SourceConfig::File(c);
            }
        }
    }
    config.zenoh = args.zenoh.apply(config.zenoh.clone());
    config.model.allow_foreign |= args.allow_foreign_model;
    if args.check {
        return check(&config);
    }
    let mut opts = DaemonOptions::new(config);
    opts.config_path = Some(args.config.clone());
    opts.use_signals = true;
    opts.output = match args.print.as_deref() {
        Some("json") => Output::Json,
        Some(_) => Output::Lines,
        None => Output::None,
    };
    // Start-up touched far more code than the steady loop runs: hand those pages back.
    daemon::code_pages::release_after(std::time::Duration::from_secs(5));
    let summary = daemon::run(opts)?;
    tracing::info!("{}", summary.text());
    Ok(())
}

/// `--check`: the checks `run` makes, then one line saying what would run. A problem `run`
/// survives (a recording folder it cannot create) still fails the check: it must be fixed.
fn check(config: &DaemonConfig) -> Result<()> {
    let Checked {
        rig,
        model,
        source,
        foreign,
        problems,
    } = preflight(config)?;
    if !problems.is_empty() {
        bail!(
            "{}; `rigmon run` would start monitoring without it",
            problems.join("; ")
        );
    }
    let foreign = if foreign.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = foreign.iter().map(ToString::to_string).collect();
        format!(" FOREIGN (allowed: {})", list.join("; "))
    };
    println!(
        "ok: rig {} ({}), model {} [{}]{foreign}, source {}, zenoh {} listen {:?} connect {:?}, recording {}",
        rig.machine.id,
        config.rig.display(),
        config.model.path.display(),
        model.meta().labels.join(","),
        source.describe(),
        config.zenoh.mode,
        config.zenoh.listen,
        config.zenoh.connect,
        if config.recording.enabled {
            config.recording.dir.display().to_string()
        } else {
            "off".into()
        }
    );
    Ok(())
}

/// Log lines to stderr (journald under systemd), filtered by `RUST_LOG` or else `default`
/// (e.g. `info`, `rigmon=debug`). Both binaries call it once, first.
pub fn init_logging(default: &str) {
    let filter = std::env::var("RUST_LOG").unwrap_or_else(|_| default.to_string());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}
