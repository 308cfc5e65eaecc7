//! `rigmon inspect <recording> --rig <toml> --png out.png`: the whole-recording envelope order
//! spectrum of one channel, drawn with fault-order markers, plus the top peaks and the fault
//! orders nearest to them as text.

use crate::config::RigConfig;
use crate::dsp::order_spectrum::whole_recording;
use crate::dsp::SpeedTrack;
use crate::importers::{self, ImportOptions};
use crate::plots::spectrum::{draw_order_spectrum, Marker, SpectrumPlot};
use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `rigmon inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording: rigmon .mcap, CWRU/MFPT .mat, .wav or .csv.
    pub recording: PathBuf,
    /// Rig file (bearing geometry, speed source, low-pass).
    #[arg(long)]
    pub rig: PathBuf,
    /// Write the picture here.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Channel (name or axis); default: the rig's classifier channel.
    #[arg(long)]
    pub channel: Option<String>,
    /// Sample rate in Hz, when the file does not say.
    #[arg(long)]
    pub sample_rate: Option<f64>,
    /// Use this constant speed (rpm) instead of the rig's speed source.
    #[arg(long)]
    pub rpm: Option<f64>,
    /// Right end of the order axis (default: a little above 3 x BPFI).
    #[arg(long)]
    pub max_order: Option<f64>,
    /// How many peaks to list.
    #[arg(long, default_value_t = 8)]
    pub peaks: usize,
}

pub fn run(args: Args) -> Result<()> {
    match inspect(args) {
        // `rigmon inspect ... | head` is fine
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(())
        }
        r => r,
    }
}

fn inspect(args: Args) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let rig = RigConfig::load(&args.rig)?;
    let opts = ImportOptions {
        sample_rate: args.sample_rate,
        rpm: args.rpm,
        ..Default::default()
    };
    let rec = importers::load(&args.recording, &rig, &opts)?;
    let want = match &args.channel {
        Some(c) => c.clone(),
        None => rig
            .classifier_channel()
            .map(|c| c.name.clone())
            .context("the rig file names no classifier channel; pass --channel")?,
    };
    let ch = rec.channel(&want).with_context(|| {
        let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
        format!(
            "{}: no channel {want:?}; the recording has {names:?}",
            args.recording.display()
        )
    })?;
    let speed = match args.rpm {
        Some(rpm) => SpeedTrack::fixed(rpm)?,
        None => crate::analysis::whole_recording(&rec, &rig)?,
    };
    let fo = rig.bearing.fault_orders();
    let max_order = args
        .max_order
        .unwrap_or((3.0 * fo.bpfi + 1.5).ceil())
        .min(rig.features.max_order);
    let spec = whole_recording(
        &ch.samples,
        rec.sample_rate,
        &speed,
        rig.features.lowpass_hz,
        max_order,
    )
    .with_context(|| format!("{}: channel {:?}", args.recording.display(), ch.name))?;

    let mut markers = Vec::new();
    for h in 1..=(max_order.floor() as usize) {
        markers.push(Marker {
            label: format!("{h}x"),
            order: h as f64,
            group: 0,
        });
    }
    for (g, (name, order)) in fo.named().iter().enumerate() {
        for h in 1..=3 {
            let label = if h == 1 {
                name.to_string()
            } else {
                format!("{h}x{name}")
            };
            markers.push(Marker {
                label,
                order: h as f64 * order,
                group: g + 1,
            });
        }
    }
    writeln!(
        out,
        "{} channel {:?}: {:.1} s, {:.0} revolutions, mean speed {:.1} rpm (source: {}), order resolution {:.4}",
        args.recording.display(),
        ch.name,
        rec.duration_s(),
        spec.revolutions,
        spec.rpm,
        speed.source(),
        spec.order_step
    )?;
    writeln!(
        out,
        "fault orders: FTF {:.4}  BPFO {:.4}  BPFI {:.4}  2xBSF {:.4}",
        fo.ftf, fo.bpfo, fo.bpfi, fo.two_bsf
    )?;
    writeln!(
        out,
        "{:>9} {:>12}  nearest fault order",
        "order", "amplitude"
    )?;
    let named: Vec<(String, f64)> = markers.iter().map(|m| (m.label.clone(), m.order)).collect();
    for p in spec.top_peaks(args.peaks, 0.3, max_order, 0.05) {
        let (name, o) = named
            .iter()
            .min_by(|a, b| (a.1 - p.order).abs().total_cmp(&(b.1 - p.order).abs()))
            .cloned()
            .unwrap_or_default();
        writeln!(
            out,
            "{:>9.3} {:>12.5}  {name} ({o:.3}, {:+.2} %)",
            p.order,
            p.amplitude,
            100.0 * (p.order / o - 1.0)
        )?;
    }
    if let Some(png) = &args.png {
        let title = format!(
            "{} - {} - envelope order spectrum ({:.0} rpm, {})",
            args.recording
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default(),
            ch.name,
            spec.rpm,
            speed.source()
        );
        draw_order_spectrum(
            png,
            &SpectrumPlot {
                title: &title,
                order_step: spec.order_step,
                amplitude: &spec.amplitude,
                max_order,
                markers: &markers,
                unit: &ch.unit,
            },
        )?;
        writeln!(out, "wrote {}", png.display())?;
    }
    Ok(())
}
