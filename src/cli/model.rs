//! `rigmon model stamp <model.onnx> --rig <rig.toml> [-o out.onnx]`: write the identity keys a
//! model written before rigmon stored them lacks (bearing orders, envelope low-pass, window)
//! from the rig file it was trained for. Metadata only: the graph and its weights stay
//! bit-identical. Refused when what the model already says contradicts the rig file.

use crate::config::RigConfig;
use crate::model::digest::sha256_hex;
use crate::model::export;
use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `rigmon model`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub command: Command,
}

/// `rigmon model <command>`.
#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Stamp a model with the identity of the rig file it was trained for (bearing orders,
    /// low-pass, window); the weights stay bit-identical.
    Stamp(StampArgs),
}

/// Arguments of `rigmon model stamp`.
#[derive(clap::Args, Debug)]
pub struct StampArgs {
    /// The model (.onnx).
    pub model: PathBuf,
    /// The rig file the model was trained for.
    #[arg(long)]
    pub rig: PathBuf,
    /// Write the stamped model here (default: replace the model file).
    #[arg(short = 'o', long)]
    pub output: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<()> {
    match args.command {
        Command::Stamp(a) => stamp(a),
    }
}

fn stamp(args: StampArgs) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let bytes = std::fs::read(&args.model)
        .with_context(|| format!("cannot read model {}", args.model.display()))?;
    let what = args.model.display().to_string();
    let (stamped, added) = export::stamp_bytes(&bytes, &rig, &what)
        .with_context(|| format!("with rig file {}", args.rig.display()))?;
    let out = args.output.as_ref().unwrap_or(&args.model);
    // Write beside the target and rename, so a failed write never leaves half a model.
    let tmp = out.with_extension("onnx.stamping");
    std::fs::write(&tmp, &stamped).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, out).with_context(|| format!("cannot replace {}", out.display()))?;
    println!(
        "stamped {} for rig {:?} ({}): {}; sha256 {}",
        out.display(),
        rig.machine.id,
        args.rig.display(),
        if added.is_empty() {
            "already carried every identity key (values rewritten from the rig file)".to_string()
        } else {
            format!("added {}", added.join(", "))
        },
        sha256_hex(&stamped)
    );
    Ok(())
}
