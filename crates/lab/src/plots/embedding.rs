//! Embedding scatter (PNG): one point per feature window, colour = class, marker = domain
//! (circle = simulated, triangle = measured), as in the thesis' Fig. 4.5.

use crate::vocabulary::Condition;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// One point to draw.
#[derive(Debug, Clone)]
pub struct Point {
    pub x: f32,
    pub y: f32,
    pub label: String,
    pub simulated: bool,
}

fn class_color(label: &str) -> RGBColor {
    match Condition::parse(label) {
        Some(Condition::Healthy) => RGBColor(0, 150, 60),
        Some(Condition::OuterRace) => RGBColor(220, 60, 30),
        Some(Condition::InnerRace) => RGBColor(30, 90, 220),
        Some(Condition::Ball) => RGBColor(150, 50, 180),
        None => RGBColor(90, 90, 90),
    }
}

/// Draw the points to `path`.
pub fn draw(path: &Path, points: &[Point], title: &str) -> Result<()> {
    super::ensure_font()?;
    let err = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
    );
    for p in points {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(anyhow!("nothing to draw: no finite embedded points"));
    }
    let (mx, my) = (0.05 * (x1 - x0).max(1e-6), 0.05 * (y1 - y0).max(1e-6));
    let root = BitMapBackend::new(path, (900, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d((x0 - mx)..(x1 + mx), (y0 - my)..(y1 + my))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .label_style(("sans-serif", 12))
        .draw()
        .map_err(|e| err(&e))?;
    let mut groups: Vec<(String, bool)> = points
        .iter()
        .map(|p| (p.label.clone(), p.simulated))
        .collect();
    groups.sort();
    groups.dedup();
    for (label, sim) in groups {
        let color = class_color(&label);
        let pts: Vec<(f32, f32)> = points
            .iter()
            .filter(|p| p.label == label && p.simulated == sim)
            .map(|p| (p.x, p.y))
            .collect();
        let name = format!("{label} ({})", if sim { "simulated" } else { "measured" });
        if sim {
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y)| Circle::new((x, y), 3, color.mix(0.6).filled())),
                )
                .map_err(|e| err(&e))?
                .label(name)
                .legend(move |(x, y)| Circle::new((x, y), 4, color.filled()));
        } else {
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y)| TriangleMarker::new((x, y), 6, color.stroke_width(2))),
                )
                .map_err(|e| err(&e))?
                .label(name)
                .legend(move |(x, y)| TriangleMarker::new((x, y), 6, color.stroke_width(2)));
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
