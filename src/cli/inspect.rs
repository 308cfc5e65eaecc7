//! `rigmon inspect <recording> --rig <toml> --png out.png`: the whole-recording envelope order
//! spectrum of one channel, drawn with fault-order markers, plus the top peaks and the fault
//! orders nearest to them as text.
//!
//! `--kurtogram k.png`: the channel's fast kurtogram (`dsp::kurtogram`) as a heat map, its best
//! band printed (centre, bandwidth, level, kurtosis); `--png` then draws the envelope order
//! spectrum of that band under the fixed low-pass one. `--json`: one JSON document instead of
//! the text: the kurtogram (best band and grid) and the rule's statistic per fault family under
//! the three envelope bands of `model::band_ratios` (fixed low-pass, kurtogram band per window,
//! kurtogram band per record), per window and summarised; `docs/study/kurtogram_bands.py` runs
//! it over the development records.

use crate::config::RigConfig;
use crate::dsp::kurtogram::{self, level_label, KurtogramBand, KurtogramSettings};
use crate::dsp::order_spectrum::{whole_recording_band, WholeSpectrum};
use crate::dsp::SpeedTrack;
use crate::importers;
use crate::model::band_ratios::{band_ratios, BandChoice};
use crate::model::rule::{EnvelopeRule, RuleSettings};
use crate::plots::kurtogram::{draw_kurtogram, KurtogramPlot};
use crate::plots::spectrum::{draw_order_spectra, Marker, SpectrumPlot};
use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `rigmon inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording: rigmon .mcap, any-layout .mat, .wav or .csv.
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
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
    /// Right end of the order axis (default: a little above 3 x BPFI).
    #[arg(long)]
    pub max_order: Option<f64>,
    /// How many peaks to list.
    #[arg(long, default_value_t = 8)]
    pub peaks: usize,
    /// Draw the channel's fast kurtogram here (PNG) and print its best band; with --png, the
    /// envelope order spectrum of that band is drawn under the low-pass one.
    #[arg(long, value_name = "PNG")]
    pub kurtogram: Option<PathBuf>,
    /// Depth of the kurtogram: the narrowest bands are (top frequency) / 2^N wide. The
    /// per-window kurtogram of --json needs 2^(N+7) samples per feature window.
    #[arg(long, default_value_t = 6, value_name = "N")]
    pub kurtogram_levels: usize,
    /// Highest frequency the kurtogram searches, Hz (default: Nyquist). Recordings at
    /// different rates are searched on the same grid when given the same value.
    #[arg(long, value_name = "HZ")]
    pub kurtogram_max_hz: Option<f64>,
    /// Print one JSON document instead of the text: the kurtogram and the rule's ratio per
    /// fault family under the fixed low-pass and kurtogram-chosen envelope bands.
    #[arg(long)]
    pub json: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    let outputs: Vec<(&str, &std::path::Path)> = (args.png.iter().map(|p| ("--png", p.as_path())))
        .chain(args.kurtogram.iter().map(|p| ("--kurtogram", p.as_path())))
        .collect();
    super::same_file::refuse_output_naming_input(
        &outputs,
        &[("", &args.recording), ("--rig", &args.rig)],
    )?;
    Ok(())
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
    let opts = args.read.import_options();
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
    let what = || format!("{}: channel {:?}", args.recording.display(), ch.name);
    let speed = match args.read.rpm {
        Some(rpm) => SpeedTrack::fixed(rpm)?,
        None => crate::analysis::whole_recording(&rec, &rig)?,
    };
    let fo = rig.bearing.fault_orders();
    let max_order = args
        .max_order
        .unwrap_or((3.0 * fo.bpfi + 1.5).ceil())
        .min(rig.features.max_order);
    let lowpass = (0.0, rig.features.lowpass_hz.min(rec.sample_rate / 2.0));
    let spec = spectrum(&rec, &ch.samples, &speed, lowpass, max_order).with_context(what)?;
    let settings = KurtogramSettings {
        levels: args.kurtogram_levels,
        max_hz: args.kurtogram_max_hz,
    };
    let record_kurtogram = if args.kurtogram.is_some() || args.json {
        Some(
            kurtogram::of_recording(&ch.samples, rec.sample_rate, settings)
                .with_context(|| format!("{}: --kurtogram-levels / --kurtogram-max-hz", what()))?,
        )
    } else {
        None
    };

    let markers = fault_markers(&rig, max_order);
    if args.json {
        let k = record_kurtogram.as_ref().expect("computed for --json");
        let rule = EnvelopeRule::for_rig(&rig, RuleSettings::default());
        let mut bands = Vec::new();
        for choice in [
            BandChoice::LowPass,
            BandChoice::PerWindow(settings),
            BandChoice::Fixed(k.best()),
        ] {
            bands.push(
                band_ratios(&ch.samples, rec.sample_rate, &rig, &speed, choice, &rule)
                    .with_context(|| {
                        format!(
                            "{}: {} envelope (--kurtogram-levels {}, --kurtogram-max-hz {:?})",
                            what(),
                            choice.name(),
                            settings.levels,
                            settings.max_hz
                        )
                    })?,
            );
        }
        let doc = serde_json::json!({
            "recording": args.recording.display().to_string(),
            "channel": ch.name,
            "sample_rate_hz": rec.sample_rate,
            "duration_s": rec.duration_s(),
            "rpm": spec.rpm,
            "speed_source": speed.source(),
            "fault_orders": {"ftf": fo.ftf, "bpfo": fo.bpfo, "bpfi": fo.bpfi, "two_bsf": fo.two_bsf},
            "lowpass_hz": lowpass.1,
            "window_s": rig.features.window_s,
            "hop_s": rig.features.hop_s,
            "rule_threshold": rule.threshold(),
            "kurtogram": {
                "levels": settings.levels,
                "max_hz": settings.max_hz,
                "top_hz": k.top_hz(),
                "best": band_json(&k.best()),
                "rows": k.rows(),
            },
            "bands": bands,
        });
        serde_json::to_writer(&mut out, &doc)?;
        writeln!(out)?;
    } else {
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
        write!(out, "{}", series_note(&rec, &spec))?;
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
        print_peaks(&mut out, &spec, &markers, args.peaks, max_order)?;
        if let Some(k) = &record_kurtogram {
            let b = k.best();
            writeln!(
                out,
                "kurtogram ({} levels, 0-{:.0} Hz): best band centre {:.0} Hz, bandwidth {:.0} Hz ({:.0}-{:.0} Hz), level {}, kurtosis {:.3}",
                settings.levels,
                k.top_hz(),
                b.centre_hz(),
                b.bandwidth_hz(),
                b.lo_hz,
                b.hi_hz,
                level_label(b.level),
                b.kurtosis
            )?;
        }
    }
    // "wrote" lines go to stderr under --json, so stdout stays one JSON document
    let mut said = |text: String| -> Result<()> {
        if args.json {
            eprintln!("{text}");
        } else {
            writeln!(out, "{text}")?;
        }
        Ok(())
    };
    let file_name = args
        .recording
        .file_name()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    if let (Some(png), Some(k)) = (&args.kurtogram, &record_kurtogram) {
        let b = k.best();
        let title = format!(
            "{file_name} - {} - fast kurtogram: best band {:.0}-{:.0} Hz (centre {:.0}, width {:.0}), level {}, K = {:.2}",
            ch.name,
            b.lo_hz,
            b.hi_hz,
            b.centre_hz(),
            b.bandwidth_hz(),
            level_label(b.level),
            b.kurtosis
        );
        draw_kurtogram(
            png,
            &KurtogramPlot {
                title: &title,
                rows: k.rows(),
                best: b,
                top_hz: k.top_hz(),
            },
        )?;
        said(format!("wrote {}", png.display()))?;
    }
    if let Some(png) = &args.png {
        let title = format!(
            "{file_name} - {} - envelope order spectrum, low-pass {:.0} Hz ({:.0} rpm, {})",
            ch.name,
            lowpass.1,
            spec.rpm,
            speed.source()
        );
        let mut plots = vec![SpectrumPlot {
            title: &title,
            order_step: spec.order_step,
            amplitude: &spec.amplitude,
            max_order,
            markers: &markers,
            unit: &ch.unit,
        }];
        let band_spec;
        let band_title;
        if let Some(k) = &record_kurtogram {
            let b = k.best();
            band_spec = whole_recording_band(
                &ch.samples,
                rec.sample_rate,
                &speed,
                (b.lo_hz, b.hi_hz),
                max_order,
            )
            .with_context(what)?;
            band_title = format!(
                "{file_name} - {} - envelope order spectrum, kurtogram band {:.0}-{:.0} Hz (level {}, K = {:.2})",
                ch.name,
                b.lo_hz,
                b.hi_hz,
                level_label(b.level),
                b.kurtosis
            );
            plots.push(SpectrumPlot {
                title: &band_title,
                order_step: band_spec.order_step,
                amplitude: &band_spec.amplitude,
                max_order,
                markers: &markers,
                unit: &ch.unit,
            });
        }
        draw_order_spectra(png, &plots)?;
        said(format!("wrote {}", png.display()))?;
    }
    Ok(())
}

/// Shaft harmonics up to `max_order` and the first three harmonics of FTF, BPFO, BPFI, 2xBSF.
/// A line saying a capture series' spectrum is the mean of its captures' (empty otherwise).
fn series_note(rec: &crate::recording::Recording, spec: &WholeSpectrum) -> String {
    if !crate::recording::captures::is_capture_series(&rec.metadata) {
        return String::new();
    }
    format!(
        "a series of captures: the RMS mean of each capture's spectrum, {:.1} revolutions each: \
         resolution {:.3} orders (lines {:.4} apart are interpolated)\n",
        spec.revolutions,
        1.0 / spec.revolutions,
        spec.order_step
    )
}

/// The envelope order spectrum of a channel over the whole recording; for a series of
/// captures, the RMS mean of each capture's spectrum (a spectrum never spans two captures,
/// and its resolution is one capture's: 1 / its revolutions).
fn spectrum(
    rec: &crate::recording::Recording,
    samples: &[f32],
    speed: &SpeedTrack,
    band: (f64, f64),
    max_order: f64,
) -> Result<WholeSpectrum> {
    use crate::recording::captures;
    let fs = rec.sample_rate;
    if !captures::is_capture_series(&rec.metadata) {
        return whole_recording_band(samples, fs, speed, band, max_order);
    }
    let spans = captures::spans(rec).map_err(anyhow::Error::msg)?;
    let shortest = spans.iter().map(|s| s.end - s.start).min().unwrap_or(0);
    let mut mean: Option<WholeSpectrum> = None;
    for s in &spans {
        let one = whole_recording_band(
            &samples[s.start..s.start + shortest],
            fs,
            speed,
            band,
            max_order,
        )
        .with_context(|| format!("the capture at {:.1} s", s.clock as f64 / fs))?;
        match &mut mean {
            None => {
                let mut m = one;
                m.amplitude.iter_mut().for_each(|a| *a *= *a);
                mean = Some(m);
            }
            Some(m) => {
                for (a, b) in m.amplitude.iter_mut().zip(&one.amplitude) {
                    *a += b * b;
                }
                m.rpm += one.rpm;
            }
        }
    }
    let mut m = mean.context("no capture")?;
    let n = spans.len() as f64;
    m.amplitude.iter_mut().for_each(|a| *a = (*a / n).sqrt());
    m.rpm /= n;
    Ok(m)
}

fn fault_markers(rig: &RigConfig, max_order: f64) -> Vec<Marker> {
    let fo = rig.bearing.fault_orders();
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
    markers
}

/// The `n` highest peaks with the nearest marker each.
fn print_peaks(
    out: &mut impl Write,
    spec: &WholeSpectrum,
    markers: &[Marker],
    n: usize,
    max_order: f64,
) -> Result<()> {
    for p in spec.top_peaks(n, 0.3, max_order, 0.05) {
        let (name, o) = markers
            .iter()
            .min_by(|a, b| {
                (a.order - p.order)
                    .abs()
                    .total_cmp(&(b.order - p.order).abs())
            })
            .map(|m| (m.label.clone(), m.order))
            .unwrap_or_default();
        writeln!(
            out,
            "{:>9.3} {:>12.5}  {name} ({o:.3}, {:+.2} %)",
            p.order,
            p.amplitude,
            100.0 * (p.order / o - 1.0)
        )?;
    }
    Ok(())
}

/// A band as JSON, with its centre and width.
fn band_json(b: &KurtogramBand) -> serde_json::Value {
    serde_json::json!({
        "level": b.level,
        "level_label": level_label(b.level),
        "lo_hz": b.lo_hz,
        "hi_hz": b.hi_hz,
        "centre_hz": b.centre_hz(),
        "bandwidth_hz": b.bandwidth_hz(),
        "kurtosis": b.kurtosis,
    })
}
