//! PNG of a fast kurtogram: one row per level (0 at the top, the 1/3 levels between the
//! binary ones), each band a cell from its low to its high frequency, coloured by the kurtosis
//! of its complex envelope (negative values drawn as 0, as in Antoni's figures; the scale runs
//! to the highest value, at least 1), the best band outlined in red (the caller names it in
//! the title), and a colour bar.

use crate::dsp::kurtogram::{KurtogramBand, KurtogramRow};
use crate::plots::ensure_font;
use anyhow::{anyhow, bail, Result};
use plotters::prelude::*;
use std::path::Path;

/// What to draw.
pub struct KurtogramPlot<'a> {
    pub title: &'a str,
    /// Rows in the order 0, 1, 1.6, 2, ... (top to bottom).
    pub rows: &'a [KurtogramRow],
    /// The band to outline (name it in the title: centre, width, level, kurtosis).
    pub best: KurtogramBand,
    /// Right end of the frequency axis (the grid's top), Hz.
    pub top_hz: f64,
}

/// The colour scale runs to the highest kurtosis, but at least to this: a kurtogram of noise
/// (every band near 0) stays dark instead of showing its largest fluctuation in yellow.
const MIN_SCALE: f64 = 1.0;

/// Dark blue through teal and green to yellow (viridis' anchors).
const RAMP: [(f64, f64, f64); 5] = [
    (68.0, 1.0, 84.0),
    (59.0, 82.0, 139.0),
    (33.0, 145.0, 140.0),
    (94.0, 201.0, 98.0),
    (253.0, 231.0, 37.0),
];

/// Colour of `v` in 0..=1.
fn ramp(v: f64) -> RGBColor {
    let x = v.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f64;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    let mix = |p: f64, q: f64| (p + f * (q - p)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Draw `plot` into a 1400 x 700 PNG at `path`.
pub fn draw_kurtogram(path: &Path, plot: &KurtogramPlot) -> Result<()> {
    if plot.rows.is_empty() || !(plot.top_hz > 0.0) {
        bail!("drawing {}: the kurtogram is empty", path.display());
    }
    ensure_font()?;
    let e = |err: &dyn std::fmt::Display| anyhow!("drawing {}: {err}", path.display());
    let root = BitMapBackend::new(path, (1400, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let root = root
        .titled(plot.title, ("sans-serif", 22))
        .map_err(|x| e(&x))?;
    let (left, right) = root.split_horizontally(1270);
    let n = plot.rows.len();
    let kmax = plot
        .rows
        .iter()
        .flat_map(|r| r.kurtosis.iter().copied())
        .filter(|k| k.is_finite())
        .fold(0.0, f64::max)
        .max(MIN_SCALE);
    // row r (0 = level 0) is segment n - 1 - r: level 0 on top
    let seg = |r: usize| (n - 1 - r) as i32;
    let mut chart = ChartBuilder::on(&left)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..plot.top_hz, (0..n as i32 - 1).into_segmented())
        .map_err(|x| e(&x))?;
    let label_of = |y: &SegmentValue<i32>| match y {
        SegmentValue::CenterOf(v) | SegmentValue::Exact(v) => {
            let r = n as i32 - 1 - v;
            usize::try_from(r)
                .ok()
                .and_then(|r| plot.rows.get(r))
                .map(|row| row.label())
                .unwrap_or_default()
        }
        SegmentValue::Last => String::new(),
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("frequency [Hz]")
        .y_desc("level")
        .y_labels(n)
        .y_label_formatter(&label_of)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 18))
        .draw()
        .map_err(|x| e(&x))?;
    for (r, row) in plot.rows.iter().enumerate() {
        let (y0, y1) = (SegmentValue::Exact(seg(r)), SegmentValue::Exact(seg(r) + 1));
        chart
            .draw_series(row.kurtosis.iter().enumerate().map(|(i, &k)| {
                let (lo, hi) = (
                    i as f64 * row.bandwidth_hz,
                    (i + 1) as f64 * row.bandwidth_hz,
                );
                let v = if k.is_finite() {
                    k.max(0.0) / kmax
                } else {
                    0.0
                };
                Rectangle::new([(lo, y0.clone()), (hi, y1.clone())], ramp(v).filled())
            }))
            .map_err(|x| e(&x))?;
    }
    // the best band: outlined, named beside it
    let r = plot
        .rows
        .iter()
        .position(|row| (row.level - plot.best.level).abs() < 1e-9)
        .unwrap_or(0);
    let (y0, y1) = (SegmentValue::Exact(seg(r)), SegmentValue::Exact(seg(r) + 1));
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(plot.best.lo_hz, y0), (plot.best.hi_hz, y1)],
            RGBColor(230, 30, 30).stroke_width(3),
        )))
        .map_err(|x| e(&x))?;

    // colour bar
    let mut bar = ChartBuilder::on(&right)
        .margin_top(12)
        .margin_bottom(57)
        .margin_right(10)
        .y_label_area_size(55)
        .caption("kurtosis", ("sans-serif", 16))
        .build_cartesian_2d(0.0..1.0, 0.0..kmax)
        .map_err(|x| e(&x))?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&|v| {
            if kmax < 2.0 {
                format!("{v:.2}")
            } else {
                format!("{v:.1}")
            }
        })
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|x| e(&x))?;
    let steps = 100;
    bar.draw_series((0..steps).map(|s| {
        let (a, b) = (s as f64 / steps as f64, (s + 1) as f64 / steps as f64);
        Rectangle::new([(0.0, a * kmax), (1.0, b * kmax)], ramp(a).filled())
    }))
    .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_dark_to_bright() {
        let lum = |c: RGBColor| 0.3 * c.0 as f64 + 0.59 * c.1 as f64 + 0.11 * c.2 as f64;
        let steps: Vec<f64> = (0..=10).map(|i| lum(ramp(i as f64 / 10.0))).collect();
        assert!(steps.windows(2).all(|w| w[1] > w[0]), "{steps:?}");
        assert_eq!(ramp(-1.0), ramp(0.0));
        assert_eq!(ramp(2.0), RGBColor(253, 231, 37));
    }
}
