//! `rigmon trend <recording or folder> --rig <toml> [--png out.png] [--json]`: a recording's
//! life window by window (a folder of captures: one window per capture, at its time), its
//! first part (`--baseline-fraction`) the healthy baseline, and two alarms over it: the
//! classic RMS 3-sigma rule ([`crate::model::rms_rule`]) and rigmon's departure test on the
//! speed-free health indicators ([`crate::model::departure`], the code the health state
//! machine runs in `replay` and the daemon), each with its alarm time and the lead time to
//! the end of the recording.

use crate::config::RigConfig;
use crate::model::departure::{fit_baseline, Departure, DepartureSettings, MEDIAN_OF};
use crate::model::indicator_series::{indicator_series, IndicatorWindow};
use crate::model::indicators::{Indicator, IndicatorBaseline, PerIndicator};
use crate::model::rms_rule::{rms_three_sigma, RmsRule};
use crate::plots::trend::{draw_trend, IndicatorPanels, TrendPlot};
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
    /// Windows an indicator must stand beyond its threshold before rigmon alarms (the
    /// `[health.departure] persist` of the daemon).
    #[arg(long, default_value_t = crate::model::departure::PERSIST)]
    pub persist: usize,
    /// Healthy spreads above the highest healthy smoothed score (`[health.departure] margin`).
    #[arg(long, default_value_t = crate::model::departure::MARGIN)]
    pub margin: f32,
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

/// The trend of one recording, the rule and rigmon's alarm over it.
#[derive(Debug, serde::Serialize)]
pub struct Trend {
    pub recording: String,
    pub channel: String,
    pub windows: usize,
    /// The last window's end, s since the first sample: the end of the test.
    pub end_s: f64,
    /// The last baseline window's end, s (a manifest row `end_s` that selects the baseline,
    /// for `rigmon align`).
    pub baseline_end_s: f64,
    pub rule: RmsRule,
    /// The rule's alarm (its window's start) and the lead time to the end, s.
    pub alarm_s: Option<f64>,
    pub lead_s: Option<f64>,
    /// rigmon's departure test over the same baseline.
    pub rigmon: RigmonAlarm,
}

/// rigmon's alarm over a recording.
#[derive(Debug, serde::Serialize)]
pub struct RigmonAlarm {
    /// The healthy indicator baseline fitted on the baseline windows (None: too few).
    pub baseline: Option<IndicatorBaseline>,
    pub settings: DepartureSettings,
    /// Each indicator's threshold on its smoothed score.
    pub threshold: Option<PerIndicator>,
    /// The window end at which the machine departed, and the lead time to the end, s.
    pub alarm_s: Option<f64>,
    pub lead_s: Option<f64>,
    /// The indicator that stood furthest beyond when it departed.
    pub leading: Option<Indicator>,
    /// Of the windows from the alarm on, the fraction in which some indicator's smoothed
    /// score stood beyond its threshold (the state itself holds the fault in all of them).
    pub beyond_after: Option<f64>,
    /// Windows inside the baseline at which the departure test alarmed (always 0 when the
    /// baseline is the test's own: it never reaches its own threshold).
    pub alarms_in_baseline: usize,
}

/// The departure test over the windows with the first `base` as the baseline; also the
/// smoothed scores per window (NaN where none) for the picture.
fn rigmon_alarm(
    w: &[IndicatorWindow],
    base: usize,
    settings: DepartureSettings,
) -> (RigmonAlarm, Vec<[f32; 4]>) {
    let healthy: Vec<_> = w[..base].iter().filter_map(|x| x.indicators).collect();
    let baseline = fit_baseline(&healthy, MEDIAN_OF);
    let mut out = RigmonAlarm {
        baseline,
        settings,
        threshold: None,
        alarm_s: None,
        lead_s: None,
        leading: None,
        beyond_after: None,
        alarms_in_baseline: 0,
    };
    let mut smoothed = vec![[f32::NAN; 4]; w.len()];
    let Some(b) = baseline else {
        return (out, smoothed);
    };
    let mut d = Departure::new(b, settings);
    out.threshold = Some(d.threshold());
    let (mut alarm_at, mut beyond) = (None, Vec::with_capacity(w.len()));
    for (k, x) in w.iter().enumerate() {
        let Some(i) = x.indicators else {
            beyond.push(false);
            continue;
        };
        let r = d.push(x.t_end, &i);
        if let Some(m) = r.smoothed {
            smoothed[k] = m.to_array();
        }
        beyond.push(r.excess.is_some_and(|e| e > 0.0));
        if alarm_at.is_none() && r.departed_since_s.is_some() {
            alarm_at = Some(k);
            out.alarm_s = r.departed_since_s;
            out.leading = r.leading;
        }
    }
    let end = w.last().map_or(0.0, |x| x.t_end);
    out.lead_s = out.alarm_s.map(|a| end - a);
    out.alarms_in_baseline = usize::from(alarm_at.is_some_and(|k| k < base));
    out.beyond_after = alarm_at.map(|k| {
        let after = &beyond[k..];
        after.iter().filter(|&&b| b).count() as f64 / after.len() as f64
    });
    (out, smoothed)
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let channel = rig
        .classifier_channel()
        .context("the rig file names no classifier channel (features.classifier_axis)")?
        .name
        .clone();
    if !(args.baseline_fraction > 0.0 && args.baseline_fraction < 1.0) {
        bail!(
            "--baseline-fraction {}: must be between 0 and 1",
            args.baseline_fraction
        );
    }
    let settings = DepartureSettings {
        persist: args.persist,
        margin: args.margin,
    };
    settings
        .validate()
        .map_err(|e| anyhow::anyhow!("{}", e.to_string().replace("health.departure.", "--")))?;
    let w = indicator_series(
        &args.recording,
        &rig,
        &args.read.import_options(),
        |_, _| true,
    )?;
    let t: Vec<f64> = w.iter().map(|x| x.t_start).collect();
    let rms: Vec<f64> = w.iter().map(|x| x.rms).collect();
    let what = args.recording.display().to_string();
    let base = (args.baseline_fraction * t.len() as f64).round() as usize;
    let rule = rms_three_sigma(&rms, base, 0.9).map_err(|e| anyhow::anyhow!("{what}: {e}"))?;
    let end_s = w.last().map_or(0.0, |x| x.t_end);
    let alarm_s = rule.alarm.map(|i| t[i]);
    let (rigmon, smoothed) = rigmon_alarm(&w, base, settings);
    let trend = Trend {
        recording: what,
        channel,
        windows: t.len(),
        end_s,
        baseline_end_s: base
            .checked_sub(1)
            .and_then(|k| w.get(k))
            .map_or(0.0, |x| x.t_end),
        alarm_s,
        lead_s: alarm_s.map(|a| end_s - a),
        rule,
        rigmon,
    };
    if let Some(png) = &args.png {
        picture(
            &args,
            &rig,
            &trend,
            (&t[..], &rms[..], &smoothed[..]),
            base,
            png,
        )?;
    }
    if args.json {
        println!("{}", serde_json::to_string(&trend)?);
    } else {
        println!("{}", text(&trend));
    }
    Ok(())
}

/// The picture: the RMS and the rule, the indicators and rigmon's alarm.
fn picture(
    args: &Args,
    rig: &RigConfig,
    trend: &Trend,
    (t, rms, smoothed): (&[f64], &[f64], &[[f32; 4]]),
    base: usize,
    png: &std::path::Path,
) -> Result<()> {
    let name = args.recording.file_name().map(|n| n.to_string_lossy());
    let channel = &trend.channel;
    let title = format!(
        "{}: {channel}, the RMS 3-sigma rule and rigmon's health indicators",
        name.unwrap_or_default()
    );
    let lead = |l: f64| format!("{:.2} h before the end", l / 3600.0);
    let alarm = trend
        .alarm_s
        .zip(trend.lead_s)
        .map(|(a, l)| (a, format!("RMS 3-sigma alarm, {}", lead(l))));
    let r = &trend.rigmon;
    let ours = r
        .alarm_s
        .zip(r.lead_s)
        .map(|(a, l)| (a, format!("rigmon alarm, {}", lead(l))));
    let unit = rig
        .acceleration_channels()
        .find(|c| &c.name == channel)
        .map_or(String::new(), |c| c.unit.to_string());
    let names = Indicator::ALL.map(Indicator::as_str);
    draw_trend(
        png,
        &TrendPlot {
            title: &title,
            t_s: t,
            value: rms,
            what: &format!("RMS [{unit}]"),
            baseline_end_s: t.get(base).copied().unwrap_or(0.0),
            mean: trend.rule.mean,
            threshold: trend.rule.threshold,
            alarm,
            indicators: r.threshold.map(|thr| IndicatorPanels {
                t_s: t,
                smoothed,
                names,
                threshold: thr.to_array(),
                alarm: ours,
            }),
        },
    )
}

/// Two lines: windows, baseline, the rule's threshold and alarm; rigmon's alarm.
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
    let g = &t.rigmon;
    let ours = match (g.alarm_s, g.lead_s, &g.baseline) {
        (Some(a), Some(l), _) => format!(
            "alarm at {:.3} h ({} leading), lead time {:.3} h; indicators beyond in {:.0} % of the windows after it, the state a fault in all",
            a / 3600.0,
            g.leading.map_or("-", Indicator::as_str),
            l / 3600.0,
            100.0 * g.beyond_after.unwrap_or(0.0)
        ),
        (_, _, None) => "no indicator baseline (too few sound windows in the baseline)".into(),
        _ => "no alarm".into(),
    };
    format!(
        "{}: {} windows over {:.3} h, channel {}; baseline the first {} windows: RMS mean {:.4}, sd {:.4}, threshold {:.4}; RMS 3-sigma rule: {alarm}\n  rigmon (persist {}, margin {}): {ours}",
        t.recording,
        t.windows,
        t.end_s / 3600.0,
        t.channel,
        r.baseline_windows,
        r.mean,
        r.sd,
        r.threshold,
        g.settings.persist,
        g.settings.margin
    )
}
