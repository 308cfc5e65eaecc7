//! `rigmon trend <recording or folder> --rig <toml> [--png out.png] [--json]`: the RMS of the
//! classifier channel per window over a recording's life (a folder of captures: one window per
//! capture, at its time) and the classic RMS 3-sigma rule over the first part as its healthy
//! baseline ([`crate::model::rms_rule`]): the alarm time and the lead time to the end of the
//! recording. rigmon's own indicators and alarm are not drawn yet (issue 35, items 3-4).

use crate::analysis::windows::Windower;
use crate::config::RigConfig;
use crate::importers;
use crate::model::rms_rule::{rms_three_sigma, RmsRule};
use crate::plots::trend::{draw_trend, TrendPlot};
use crate::recording::captures;
use anyhow::{bail, Context, Result};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording: rigmon .mcap, .mat, .wav, .csv, or a folder of periodic captures.
    pub recording: PathBuf,
    /// Rig file (channels, window, the classifier channel).
    #[arg(long)]
    pub rig: PathBuf,
    /// The first fraction of the windows that is the healthy baseline.
    #[arg(long, default_value_t = 0.1)]
    pub baseline_fraction: f64,
    /// Write the picture here.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub read: super::read_args::ReadArgs,
}

/// Refuse a `--png` that names the recording or the rig file (issue 38, F9).
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    let outputs: Vec<(&str, &std::path::Path)> =
        args.png.iter().map(|p| ("--png", p.as_path())).collect();
    super::same_file::refuse_output_naming_input(
        &outputs,
        &[("", &args.recording), ("--rig", &args.rig)],
    )
}

/// The trend of one recording and the rule over it.
#[derive(Debug, serde::Serialize)]
pub struct Trend {
    pub recording: String,
    pub channel: String,
    pub windows: usize,
    /// Start of the last window's end, s since the first sample: the end of the test.
    pub end_s: f64,
    pub rule: RmsRule,
    /// The alarm's window start and the lead time to the end, s.
    pub alarm_s: Option<f64>,
    pub lead_s: Option<f64>,
}

/// RMS of channel `ch` per window (window start times, s), streamed.
fn rms_per_window(args: &Args, rig: &RigConfig, ch: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    let mut stream = importers::open(&args.recording, rig, &args.read.import_options())?;
    let info = stream.info().clone();
    let mut w = Windower::for_rig(
        &rig.speed,
        &rig.features,
        info.sample_rate,
        info.channels.len(),
    )?;
    if captures::is_capture_series(&info.metadata) {
        w = w.capture_series();
    }
    let (mut t, mut rms) = (Vec::new(), Vec::new());
    while let Some(b) = stream.next_block()? {
        w.push(&b);
        while let Some(v) = w.window() {
            let x = v.channels[ch];
            let ms = x.iter().map(|&s| f64::from(s) * f64::from(s)).sum::<f64>() / x.len() as f64;
            t.push(v.t_start);
            rms.push(ms.sqrt());
            drop(v);
            w.advance();
        }
    }
    Ok((t, rms))
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let channel = rig
        .classifier_channel()
        .context("the rig file names no classifier channel (features.classifier_axis)")?
        .name
        .clone();
    let ch = rig
        .acceleration_channels()
        .position(|c| c.name == channel)
        .context("the classifier channel is not an acceleration channel")?;
    if !(args.baseline_fraction > 0.0 && args.baseline_fraction < 1.0) {
        bail!(
            "--baseline-fraction {}: must be between 0 and 1",
            args.baseline_fraction
        );
    }
    let (t, rms) = rms_per_window(&args, &rig, ch)?;
    let what = args.recording.display().to_string();
    let base = (args.baseline_fraction * t.len() as f64).round() as usize;
    let rule = rms_three_sigma(&rms, base, 0.9).map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
    let end_s = t.last().copied().unwrap_or(0.0) + rig.features.window_s;
    let alarm_s = rule.alarm.map(|i| t[i]);
    let trend = Trend {
        recording: what.clone(),
        channel: channel.clone(),
        windows: t.len(),
        end_s,
        alarm_s,
        lead_s: alarm_s.map(|a| end_s - a),
        rule,
    };
    if let Some(png) = &args.png {
        let name = args.recording.file_name().map(|n| n.to_string_lossy());
        let title = format!(
            "{}: RMS of {channel} per window, the RMS 3-sigma rule",
            name.unwrap_or_default()
        );
        let alarm = trend.alarm_s.map(|a| {
            let lead = (end_s - a) / 3600.0;
            (a, format!("RMS 3-sigma alarm, {lead:.2} h before the end"))
        });
        draw_trend(
            png,
            &TrendPlot {
                title: &title,
                t_s: &t,
                value: &rms,
                what: &format!(
                    "RMS [{}]",
                    rig.acceleration_channels()
                        .nth(ch)
                        .map_or("".into(), |c| c.unit.to_string())
                ),
                baseline_end_s: t.get(base).copied().unwrap_or(0.0),
                mean: trend.rule.mean,
                threshold: trend.rule.threshold,
                alarm,
            },
        )?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&trend)?);
    } else {
        println!("{}", text(&trend));
    }
    Ok(())
}

/// One line: windows, baseline, threshold, alarm and lead time.
fn text(t: &Trend) -> String {
    let r = &t.rule;
    let alarm = match (t.alarm_s, t.lead_s) {
        (Some(a), Some(l)) => format!(
            "alarm at {:.3} h, lead time {:.3} h ({:.0} % of the windows after it above)",
            a / 3600.0,
            l / 3600.0,
            100.0 * r.held.unwrap_or(0.0)
        ),
        _ => "no alarm".into(),
    };
    format!(
        "{}: {} windows over {:.3} h, channel {}; baseline the first {} windows: RMS mean {:.4}, sd {:.4}, threshold {:.4}; RMS 3-sigma rule: {alarm}",
        t.recording,
        t.windows,
        t.end_s / 3600.0,
        t.channel,
        r.baseline_windows,
        r.mean,
        r.sd,
        r.threshold
    )
}
