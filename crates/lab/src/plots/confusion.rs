//! Confusion-matrix picture (PNG): rows = true class, columns = predicted, cells shaded by the
//! row-normalised fraction and labelled with the count and the percentage.

use crate::evaluate::Confusion;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

/// Draw `cm` to `path` with a title and, above the matrix, a one-line note (the alarms the
/// matrix alone does not show).
pub fn draw(path: &Path, cm: &Confusion, title: &str, note: &str) -> Result<()> {
    super::ensure_font()?;
    let k = cm.labels.len().max(1);
    let cell = 120i32;
    let (left, top) = (150i32, 70i32);
    let w = (left + cell * k as i32 + 30) as u32;
    let h = (top + cell * k as i32 + 80) as u32;
    let err = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let font = |size: i32| ("sans-serif", size).into_font();
    root.draw(&Text::new(
        title.to_string(),
        (10, 10),
        font(20).color(&BLACK),
    ))
    .map_err(|e| err(&e))?;
    root.draw(&Text::new(note, (left, top - 28), font(16).color(&BLACK)))
        .map_err(|e| err(&e))?;
    root.draw(&Text::new(
        "true \\ predicted",
        (10, top - 28),
        font(16).color(&BLACK),
    ))
    .map_err(|e| err(&e))?;
    for (i, row) in cm.matrix.iter().enumerate() {
        let total: usize = row.iter().sum();
        for (j, &v) in row.iter().enumerate() {
            let frac = if total == 0 {
                0.0
            } else {
                v as f64 / total as f64
            };
            let x0 = left + cell * j as i32;
            let y0 = top + cell * i as i32;
            let shade = (255.0 * (1.0 - 0.8 * frac)) as u8;
            let color = if i == j {
                RGBColor(shade, 255, shade)
            } else {
                RGBColor(255, shade, shade)
            };
            root.draw(&Rectangle::new(
                [(x0, y0), (x0 + cell, y0 + cell)],
                color.filled(),
            ))
            .map_err(|e| err(&e))?;
            root.draw(&Rectangle::new(
                [(x0, y0), (x0 + cell, y0 + cell)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
            let pct = if total == 0 {
                "-".to_string()
            } else {
                format!("{:.1} %", 100.0 * frac)
            };
            root.draw(&Text::new(
                format!("{v}"),
                (x0 + 45, y0 + 40),
                font(22).color(&BLACK),
            ))
            .map_err(|e| err(&e))?;
            root.draw(&Text::new(pct, (x0 + 35, y0 + 70), font(14).color(&BLACK)))
                .map_err(|e| err(&e))?;
        }
    }
    for (i, l) in cm.labels.iter().enumerate() {
        root.draw(&Text::new(
            l.clone(),
            (left - 110, top + cell * i as i32 + cell / 2 - 8),
            font(15).color(&BLACK),
        ))
        .map_err(|e| err(&e))?;
        root.draw(&Text::new(
            l.clone(),
            (left + cell * i as i32 + 20, top + cell * k as i32 + 10),
            font(15).color(&BLACK),
        ))
        .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
