//! `rigmon embed`: t-SNE or PCA picture of feature windows from recordings, dataset folders
//! or manifests, coloured by class and marked by domain (simulated vs measured).

use crate::config::RigConfig;
use crate::embed::{pca, tsne, Method, TsneConfig};
use crate::importers::{self, ImportOptions};
use crate::manifest::{manifest_path, read_manifest, ManifestEntry};
use crate::model::preprocess::Preprocess;
use crate::plots::embedding::{draw, Point};
use crate::train::featurise::featurise_all;
use anyhow::{bail, Result};
use indicatif::ProgressBar;
use ndarray::{concatenate, Axis};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use std::path::PathBuf;

/// Arguments of `rigmon embed`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file used to compute the features.
    #[arg(long)]
    pub rig: PathBuf,
    /// Recordings, dataset folders (with labels.csv) or labels.csv manifests.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output PNG.
    #[arg(long)]
    pub png: PathBuf,
    /// Embedding method.
    #[arg(long, value_enum, default_value_t = Method::Tsne)]
    pub method: Method,
    /// At most this many windows (sampled evenly per recording; t-SNE is O(N^2)).
    #[arg(long, default_value_t = 2000)]
    pub max_points: usize,
    #[arg(long, default_value_t = 30.0)]
    pub perplexity: f64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    let inputs: Vec<(&str, &std::path::Path)> = std::iter::once(("--rig", args.rig.as_path()))
        .chain(args.inputs.iter().map(|p| ("", p.as_path())))
        .collect();
    super::same_file::refuse_output_naming_input(&[("--png", &args.png)], &inputs)?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let mut entries: Vec<ManifestEntry> = Vec::new();
    for p in &args.inputs {
        if p.is_dir()
            || p.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("csv") && is_manifest(p))
        {
            entries.extend(read_manifest(&manifest_path(p))?);
        } else {
            let rec = importers::load(p, &rig, &ImportOptions::default())?;
            let label = rec.label().unwrap_or("unlabelled").to_string();
            entries.push(ManifestEntry {
                path: p.clone(),
                path_text: p.display().to_string(),
                label,
                line: 0,
                sample_rate: None,
                span: None,
                nominal_rpm: None,
            });
        }
    }
    let recs = featurise_all(&entries, &rig, &ProgressBar::hidden())?;
    let total: usize = recs.iter().map(|r| r.windows.nrows()).sum();
    if total == 0 {
        bail!("no feature windows in the inputs");
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(args.seed);
    let keep_frac = (args.max_points as f64 / total as f64).min(1.0);
    let (mut parts, mut meta) = (Vec::new(), Vec::new());
    for r in &recs {
        let n = r.windows.nrows();
        let k = ((n as f64 * keep_frac).ceil() as usize).clamp(1, n);
        let mut idx: Vec<usize> = (0..n).collect();
        idx.shuffle(&mut rng);
        idx.truncate(k);
        idx.sort_unstable();
        parts.push(r.windows.select(Axis(0), &idx));
        meta.extend(std::iter::repeat_n((r.label.clone(), r.simulated), k));
    }
    let views: Vec<_> = parts.iter().map(|p| p.view()).collect();
    let x = concatenate(Axis(0), &views)?;
    // The model's own normalisation, fitted on the pooled windows.
    let z = Preprocess::fit(x.view(), Preprocess::DEFAULT_FLOOR).apply(x.view());
    let y = match args.method {
        Method::Pca => pca(z.view()),
        Method::Tsne => tsne(
            z.view(),
            &TsneConfig {
                perplexity: args.perplexity,
                seed: args.seed,
                ..Default::default()
            },
        )?,
    };
    let points: Vec<Point> = y
        .rows()
        .into_iter()
        .zip(meta)
        .map(|(r, (label, simulated))| Point {
            x: r[0],
            y: r[1],
            label,
            simulated,
        })
        .collect();
    let n_sim = points.iter().filter(|p| p.simulated).count();
    let title = format!(
        "{} of {} windows ({} simulated, {} measured), rig {}",
        if args.method == Method::Tsne {
            "t-SNE"
        } else {
            "PCA"
        },
        points.len(),
        n_sim,
        points.len() - n_sim,
        rig.machine.id
    );
    draw(&args.png, &points, &title)?;
    println!("wrote {} ({title})", args.png.display());
    Ok(())
}

/// A CSV whose first line has `path` and `label` columns is a manifest; other CSVs are recordings.
fn is_manifest(p: &std::path::Path) -> bool {
    std::fs::read_to_string(p)
        .ok()
        .and_then(|t| t.lines().next().map(|h| h.to_ascii_lowercase()))
        .is_some_and(|h| {
            h.split(',').any(|c| c.trim() == "path") && h.split(',').any(|c| c.trim() == "label")
        })
}
