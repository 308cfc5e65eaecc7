//! PNG of an envelope order spectrum with labelled fault-order markers (FTF, BPFO, BPFI,
//! 2xBSF and their harmonics, shaft harmonics); several spectra of one recording (the fixed
//! low-pass envelope and a kurtogram band's) stack as panels of one picture.

use crate::plots::ensure_font;
use anyhow::{anyhow, bail, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// A vertical marker at an order.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    pub label: String,
    pub order: f64,
    /// Colour group: 0 shaft, 1 FTF, 2 BPFO, 3 BPFI, 4 2xBSF.
    pub group: usize,
}

/// What to draw.
pub struct SpectrumPlot<'a> {
    pub title: &'a str,
    /// Order step between lines.
    pub order_step: f64,
    /// Amplitude per line, from order 0.
    pub amplitude: &'a [f64],
    /// Right end of the x axis, orders.
    pub max_order: f64,
    pub markers: &'a [Marker],
    /// Unit of the amplitude axis.
    pub unit: &'a str,
}

fn colour(group: usize) -> RGBColor {
    match group {
        0 => RGBColor(120, 120, 120),
        1 => RGBColor(0, 150, 0),
        2 => RGBColor(220, 50, 30),
        3 => RGBColor(30, 90, 220),
        _ => RGBColor(200, 120, 0),
    }
}

/// Draw `plots` one above the other (1400 x 700 for one, 560 px high each for more) into a
/// PNG at `path`; each panel keeps its own amplitude scale.
pub fn draw_order_spectra(path: &Path, plots: &[SpectrumPlot]) -> Result<()> {
    if plots.is_empty() {
        bail!("drawing {}: no spectrum to draw", path.display());
    }
    ensure_font()?;
    let e = |err: &dyn std::fmt::Display| anyhow!("drawing {}: {err}", path.display());
    let height = if plots.len() == 1 {
        700
    } else {
        560 * plots.len() as u32
    };
    let root = BitMapBackend::new(path, (1400, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    for (area, plot) in root.split_evenly((plots.len(), 1)).iter().zip(plots) {
        draw_panel(area, plot, &e)?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

fn draw_panel(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    plot: &SpectrumPlot,
    e: &dyn Fn(&dyn std::fmt::Display) -> anyhow::Error,
) -> Result<()> {
    let (width, _) = root.dim_in_pixel();
    let last = ((plot.max_order / plot.order_step).ceil() as usize + 1).min(plot.amplitude.len());
    let first = (0.2 / plot.order_step).ceil() as usize; // skip the DC skirt
    let ymax = plot.amplitude[first.min(last)..last]
        .iter()
        .cloned()
        .fold(0.0, f64::max)
        .max(1e-12)
        * 1.15;
    let mut chart = ChartBuilder::on(root)
        .caption(plot.title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..plot.max_order, 0.0..ymax)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc("order (multiples of shaft speed)")
        .y_desc(format!("envelope amplitude [{}]", plot.unit))
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .light_line_style(WHITE)
        .draw()
        .map_err(|x| e(&x))?;
    for m in plot.markers.iter().filter(|m| m.order < plot.max_order) {
        let c = colour(m.group);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(m.order, 0.0), (m.order, ymax * 0.93)],
                6,
                4,
                c.mix(0.7).stroke_width(1),
            ))
            .map_err(|x| e(&x))?;
    }
    chart
        .draw_series(LineSeries::new(
            (0..last).map(|j| (j as f64 * plot.order_step, plot.amplitude[j])),
            BLACK.stroke_width(1),
        ))
        .map_err(|x| e(&x))?;
    // labels: stagger heights so neighbouring markers do not overlap
    let mut placed: Vec<(f64, usize)> = Vec::new();
    let width_orders = plot.max_order / width as f64 * 60.0;
    for m in plot.markers.iter().filter(|m| m.order < plot.max_order) {
        let mut row = 0;
        while placed
            .iter()
            .any(|&(o, r)| r == row && (o - m.order).abs() < width_orders)
        {
            row += 1;
        }
        placed.push((m.order, row));
        let y = ymax * (0.985 - 0.045 * row as f64);
        chart
            .draw_series(std::iter::once(Text::new(
                m.label.clone(),
                (m.order, y),
                ("sans-serif", 14).into_font().color(&colour(m.group)),
            )))
            .map_err(|x| e(&x))?;
    }
    Ok(())
}
