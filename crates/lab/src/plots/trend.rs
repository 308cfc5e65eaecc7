//! PNG of a run to failure (`rigmon trend --png`): on top the RMS per window (hours on the x
//! axis, log scale) with the baseline stretch shaded, the baseline's mean and its 3-sigma
//! threshold and the RMS rule's alarm; below it, one panel per health indicator (its score
//! against the healthy baseline, smoothed as the departure test smooths it, and the
//! threshold), and a strip with the state over time (healthy, departed), rigmon's alarm
//! marked on every panel.

use crate::plots::ensure_font;
use anyhow::{anyhow, bail, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// What to draw.
pub struct TrendPlot<'a> {
    pub title: &'a str,
    /// Window times (s) and values.
    pub t_s: &'a [f64],
    pub value: &'a [f64],
    /// What the value is, with its unit ("RMS [g]").
    pub what: &'a str,
    /// End of the baseline, s.
    pub baseline_end_s: f64,
    pub mean: f64,
    pub threshold: f64,
    /// Alarm time, s, and its label.
    pub alarm: Option<(f64, String)>,
    /// The health indicators' panels (None: draw the RMS alone).
    pub indicators: Option<IndicatorPanels<'a>>,
}

/// The indicators' smoothed scores over time and rigmon's alarm.
pub struct IndicatorPanels<'a> {
    /// Window times (s) and per window the smoothed scores (NaN: none yet).
    pub t_s: &'a [f64],
    pub smoothed: &'a [[f32; 4]],
    /// Each panel's name and threshold.
    pub names: [&'a str; 4],
    pub threshold: [f32; 4],
    /// rigmon's alarm time, s, and its label.
    pub alarm: Option<(f64, String)>,
}

const RED: RGBColor = RGBColor(220, 30, 30);
const ORANGE: RGBColor = RGBColor(200, 120, 0);
const BAND: RGBColor = RGBColor(120, 180, 120);

/// The x axis' end (h) and the y axis' bounds: every positive value, the mean and the
/// threshold, with a margin.
fn bounds(p: &TrendPlot) -> (f64, f64, f64) {
    let x_max = (p.t_s[p.t_s.len() - 1] / 3600.0).max(1e-6) * 1.02;
    let positive = p.value.iter().copied().filter(|v| *v > 0.0);
    let lo = positive.clone().fold(f64::INFINITY, f64::min).min(p.mean) * 0.8;
    let hi = positive.fold(0.0, f64::max).max(p.threshold) * 1.25;
    (x_max, lo, hi)
}

/// Draw the trend into a PNG at `path` (1400 x 600, or 1400 x 1300 with the indicators).
pub fn draw_trend(path: &Path, p: &TrendPlot) -> Result<()> {
    if p.t_s.is_empty() || p.t_s.len() != p.value.len() {
        bail!("drawing {}: no trend to draw", path.display());
    }
    ensure_font()?;
    let e = |err: &dyn std::fmt::Display| anyhow!("drawing {}: {err}", path.display());
    let height = if p.indicators.is_some() { 1300 } else { 600 };
    let root = BitMapBackend::new(path, (1400, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let x_max = bounds(p).0;
    match &p.indicators {
        None => draw_rms(&root, p).map_err(|x| e(&x))?,
        Some(ind) => {
            let (top, rest) = root.split_vertically(560);
            draw_rms(&top, p).map_err(|x| e(&x))?;
            let (panels, strip) = rest.split_vertically(640);
            for (k, area) in panels.split_evenly((4, 1)).iter().enumerate() {
                draw_indicator(area, ind, k, x_max, p.baseline_end_s).map_err(|x| e(&x))?;
            }
            draw_state(&strip, ind, x_max).map_err(|x| e(&x))?;
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

/// The RMS panel with the rule.
fn draw_rms(area: &DrawingArea<BitMapBackend, Shift>, p: &TrendPlot) -> DrawResult {
    let h = |t: f64| t / 3600.0;
    let (x_max, lo, hi) = bounds(p);
    let lo = lo.max(1e-9);
    let mut chart = ChartBuilder::on(area)
        .caption(p.title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..x_max, (lo..hi.max(lo * 10.0)).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time since the first capture [h]")
        .y_desc(p.what)
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, lo), (h(p.baseline_end_s), hi)],
            BAND.mix(0.2).filled(),
        )))?
        .label("baseline")
        .legend(move |(x, y)| {
            Rectangle::new([(x, y - 5), (x + 15, y + 5)], BAND.mix(0.4).filled())
        });
    for (level, colour, name) in [
        (p.mean, RGBColor(0, 120, 0), "baseline mean"),
        (p.threshold, ORANGE, "mean + 3 sd"),
    ] {
        chart
            .draw_series(LineSeries::new(
                vec![(0.0, level), (x_max, level)],
                colour.stroke_width(2),
            ))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
    }
    chart.draw_series(
        p.t_s
            .iter()
            .zip(p.value)
            .filter(|(_, v)| **v > 0.0)
            .map(|(t, v)| Circle::new((h(*t), *v), 1, BLACK.filled())),
    )?;
    let marks = [
        (p.alarm.as_ref(), ORANGE),
        (p.indicators.as_ref().and_then(|i| i.alarm.as_ref()), RED),
    ];
    for (alarm, colour) in marks {
        if let Some((t, label)) = alarm {
            chart
                .draw_series(LineSeries::new(
                    vec![(h(*t), lo), (h(*t), hi)],
                    colour.stroke_width(2),
                ))?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .draw()?;
    Ok(())
}

/// One indicator's smoothed score, its threshold, the baseline shaded and the alarm.
fn draw_indicator(
    area: &DrawingArea<BitMapBackend, Shift>,
    ind: &IndicatorPanels,
    k: usize,
    x_max: f64,
    baseline_end_s: f64,
) -> DrawResult {
    let h = |t: f64| t / 3600.0;
    let pts: Vec<(f64, f64)> = ind
        .t_s
        .iter()
        .zip(ind.smoothed)
        .filter(|(_, z)| z[k].is_finite())
        .map(|(t, z)| (h(*t), f64::from(z[k])))
        .collect();
    let thr = f64::from(ind.threshold[k]);
    let lo = pts.iter().map(|p| p.1).fold(-1.0, f64::min).max(-20.0);
    let hi = pts.iter().map(|p| p.1).fold(thr, f64::max) * 1.1 + 1.0;
    let mut chart = ChartBuilder::on(area)
        .margin_left(15)
        .margin_right(15)
        .x_label_area_size(25)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..x_max, lo..hi)?;
    chart
        .configure_mesh()
        .y_desc(format!("{} score", ind.names[k]))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .y_labels(4)
        .draw()?;
    chart.draw_series(std::iter::once(Rectangle::new(
        [(0.0, lo), (h(baseline_end_s), hi)],
        BAND.mix(0.2).filled(),
    )))?;
    chart.draw_series(LineSeries::new(
        vec![(0.0, thr), (x_max, thr)],
        ORANGE.stroke_width(2),
    ))?;
    chart.draw_series(
        pts.iter()
            .map(|&(t, v)| Circle::new((t, v.clamp(lo, hi)), 1, BLACK.filled())),
    )?;
    if let Some((t, _)) = &ind.alarm {
        chart.draw_series(LineSeries::new(
            vec![(h(*t), lo), (h(*t), hi)],
            RED.stroke_width(2),
        ))?;
    }
    Ok(())
}

/// The state over time: healthy (green) until rigmon's alarm, departed (red) after it.
fn draw_state(
    area: &DrawingArea<BitMapBackend, Shift>,
    ind: &IndicatorPanels,
    x_max: f64,
) -> DrawResult {
    let mut chart = ChartBuilder::on(area)
        .margin_left(15)
        .margin_right(15)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..x_max, 0.0..1.0)?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(0)
        .y_desc("state")
        .x_desc("time since the first capture [h]")
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    let end = ind.t_s.last().copied().unwrap_or(0.0) / 3600.0;
    let turn = ind.alarm.as_ref().map_or(end, |(t, _)| t / 3600.0);
    let green = RGBColor(60, 160, 60);
    chart.draw_series([
        Rectangle::new([(0.0, 0.2), (turn, 0.8)], green.mix(0.6).filled()),
        Rectangle::new([(turn, 0.2), (end, 0.8)], RED.mix(0.6).filled()),
    ])?;
    Ok(())
}
