//! PNG of a health indicator over time (`rigmon trend --png`): one point per window (hours on
//! the x axis, log scale on the y axis), the baseline stretch shaded, the baseline's mean and
//! its 3-sigma threshold as lines, and the alarm marked.

use crate::plots::ensure_font;
use anyhow::{anyhow, bail, Result};
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
}

/// The x axis' end (h) and the y axis' bounds: every positive value, the mean and the
/// threshold, with a margin.
fn bounds(p: &TrendPlot) -> (f64, f64, f64) {
    let x_max = (p.t_s[p.t_s.len() - 1] / 3600.0).max(1e-6) * 1.02;
    let positive = p.value.iter().copied().filter(|v| *v > 0.0);
    let lo = positive.clone().fold(f64::INFINITY, f64::min).min(p.mean) * 0.8;
    let hi = positive.fold(0.0, f64::max).max(p.threshold) * 1.25;
    (x_max, lo, hi)
}

/// Draw the trend (1400 x 600) into a PNG at `path`.
pub fn draw_trend(path: &Path, p: &TrendPlot) -> Result<()> {
    if p.t_s.is_empty() || p.t_s.len() != p.value.len() {
        bail!("drawing {}: no trend to draw", path.display());
    }
    ensure_font()?;
    let e = |err: &dyn std::fmt::Display| anyhow!("drawing {}: {err}", path.display());
    let h = |t: f64| t / 3600.0;
    let (x_max, lo, hi) = bounds(p);
    let root = BitMapBackend::new(path, (1400, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(p.title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..x_max, (lo.max(1e-9)..hi.max(lo * 10.0)).log_scale())
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc("time since the first capture [h]")
        .y_desc(p.what)
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()
        .map_err(|x| e(&x))?;
    let band = RGBColor(120, 180, 120);
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, lo.max(1e-9)), (h(p.baseline_end_s), hi)],
            band.mix(0.2).filled(),
        )))
        .map_err(|x| e(&x))?
        .label("baseline")
        .legend(move |(x, y)| {
            Rectangle::new([(x, y - 5), (x + 15, y + 5)], band.mix(0.4).filled())
        });
    for (level, colour, name) in [
        (p.mean, RGBColor(0, 120, 0), "baseline mean"),
        (p.threshold, RGBColor(200, 120, 0), "mean + 3 sd"),
    ] {
        chart
            .draw_series(LineSeries::new(
                vec![(0.0, level), (x_max, level)],
                colour.stroke_width(2),
            ))
            .map_err(|x| e(&x))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
    }
    chart
        .draw_series(
            p.t_s
                .iter()
                .zip(p.value)
                .filter(|(_, v)| **v > 0.0)
                .map(|(t, v)| Circle::new((h(*t), *v), 1, BLACK.filled())),
        )
        .map_err(|x| e(&x))?;
    if let Some((t, label)) = &p.alarm {
        let red = RGBColor(220, 30, 30);
        chart
            .draw_series(LineSeries::new(
                vec![(h(*t), lo.max(1e-9)), (h(*t), hi)],
                red.stroke_width(2),
            ))
            .map_err(|x| e(&x))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], red));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 16))
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
