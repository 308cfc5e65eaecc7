//! Calibration PNGs: measured vs simulated before and after calibration (envelope order
//! spectrum, band energies, shaft-order lines) and the residual (measured minus calibrated
//! simulation) of the envelope and raw-line views, for one recording; and where looseness
//! shows (fractional orders, the impacts' energy envelope, the band energies a ringing mode
//! lifts) for the recording whose looseness views differ most.

use super::views::{env_order, Views, BAND_HZ, LINES_MIN_HZ};
use crate::plots::ensure_font;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

type Series<'a> = (&'a str, RGBColor, Vec<(f64, f64)>);

fn chart(
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    title: &str,
    x: &str,
    y: &str,
    series: &[Series],
) -> Result<()> {
    let e = |err: &dyn std::fmt::Display| anyhow!("drawing {title}: {err}");
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (_, _, pts) in series {
        for &(a, b) in pts {
            x0 = x0.min(a);
            x1 = x1.max(a);
            y0 = y0.min(b);
            y1 = y1.max(b);
        }
    }
    if x0 >= x1 {
        x1 = x0 + 1.0;
    }
    if y0 >= y1 {
        y1 = y0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let mut c = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(|x| e(&x))?;
    c.configure_mesh()
        .x_desc(x)
        .y_desc(y)
        .label_style(("sans-serif", 14))
        .light_line_style(WHITE)
        .draw()
        .map_err(|x| e(&x))?;
    for (name, col, pts) in series {
        let col = *col;
        c.draw_series(LineSeries::new(pts.iter().copied(), col.stroke_width(1)))
            .map_err(|x| e(&x))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|x| e(&x))?;
    Ok(())
}

const MEAS: RGBColor = RGBColor(0, 0, 0);
const BEFORE: RGBColor = RGBColor(220, 50, 30);
const AFTER: RGBColor = RGBColor(30, 90, 220);

/// A drawing area of a picture.
type Panel<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

/// A 1400 x 1300 picture in three panels (450, 430 and the rest high): the root (to present)
/// and the panels, top to bottom.
fn three_panel_canvas(path: &Path) -> Result<(Panel<'_>, [Panel<'_>; 3])> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (1400, 1300)).into_drawing_area();
    root.fill(&WHITE)
        .map_err(|x| anyhow!("drawing {}: {x}", path.display()))?;
    let (top, rest) = root.split_vertically(450);
    let (middle, bottom) = rest.split_vertically(430);
    Ok((root, [top, middle, bottom]))
}

/// One view of the measured recording and of the simulation before and after, with their
/// names and colours.
fn measured_before_after(
    m: &Views,
    b: &Views,
    a: &Views,
    view: &dyn Fn(&Views) -> Vec<(f64, f64)>,
) -> [Series<'static>; 3] {
    [
        ("measured", MEAS, view(m)),
        ("simulated before", BEFORE, view(b)),
        ("simulated after", AFTER, view(a)),
    ]
}

/// The band energies of a view at their bands' centres, Hz.
fn band_energies(v: &Views) -> Vec<(f64, f64)> {
    v.bands
        .iter()
        .zip(&v.band_lo_hz)
        .map(|(d, lo)| (lo + BAND_HZ / 2.0, *d))
        .collect()
}

/// `spectra.png`: envelope order spectra, band energies and shaft-order lines, measured /
/// before / after.
pub fn spectra(path: &Path, name: &str, m: &Views, b: &Views, a: &Views) -> Result<()> {
    let (root, [top, bottom, orders_area]) = three_panel_canvas(path)?;
    // one view of the measured recording and of the simulation before and after
    let three = |view: &dyn Fn(&Views) -> Vec<(f64, f64)>| measured_before_after(m, b, a, view);
    let env = |v: &Views| {
        v.env_db
            .iter()
            .enumerate()
            .map(|(i, d)| (env_order(i), *d))
            .collect()
    };
    chart(
        &top,
        &format!("{name}: envelope order spectrum"),
        "order",
        "dB above median",
        &three(&env),
    )?;
    chart(
        &bottom,
        "band energy (100 Hz bands)",
        "Hz",
        "dB (0 = 20 dB below the strongest band)",
        &three(&band_energies),
    )?;
    let orders = |v: &Views| {
        v.shaft
            .amplitude
            .iter()
            .enumerate()
            .filter(|(_, x)| **x > 0.0)
            .map(|(k, x)| ((k + 1) as f64, 20.0 * x.log10()))
            .collect()
    };
    chart(
        &orders_area,
        "shaft-order lines (1x, 2x: unbalance; 3x and up: looseness)",
        "order",
        "dB re 1 channel unit",
        &three(&orders),
    )?;
    root.present()
        .map_err(|x| anyhow!("writing {}: {x}", path.display()))?;
    Ok(())
}

/// `residual.png`: measured minus calibrated simulation, envelope orders and raw lines.
pub fn residual(path: &Path, name: &str, m: &Views, a: &Views) -> Result<()> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (1400, 900)).into_drawing_area();
    root.fill(&WHITE)
        .map_err(|x| anyhow!("drawing {}: {x}", path.display()))?;
    let (top, bottom) = root.split_vertically(450);
    let env: Vec<(f64, f64)> = m
        .env
        .iter()
        .zip(&a.env)
        .enumerate()
        .map(|(i, (x, y))| (env_order(i), x - y))
        .collect();
    chart(
        &top,
        &format!("{name}: residual, envelope view"),
        "order",
        "dB (thresholded)",
        &[("measured - simulated after", AFTER, env)],
    )?;
    let lines: Vec<(f64, f64)> = m
        .lines
        .iter()
        .zip(&a.lines)
        .enumerate()
        .map(|(i, (x, y))| ((i + LINES_MIN_HZ) as f64, x - y))
        .collect();
    chart(
        &bottom,
        "residual, raw lines view",
        "Hz",
        "dB (thresholded)",
        &[("measured - simulated after", AFTER, lines)],
    )?;
    root.present()
        .map_err(|x| anyhow!("writing {}: {x}", path.display()))?;
    Ok(())
}

/// `looseness.png`: where looseness shows, measured / before / after: the sub-synchronous
/// and fractional orders of the raw signal (half orders 0.5x, 1.5x, ... of a housing rocking
/// every other revolution), the envelope spectrum of the broadband energy in Hz (an impact
/// train at half the shaft rate: a comb at rpm / 120 Hz) and the band energies (the mode
/// the landings ring).
pub fn looseness(path: &Path, name: &str, m: &Views, b: &Views, a: &Views) -> Result<()> {
    let (root, [top, middle, bottom]) = three_panel_canvas(path)?;
    let three = |view: &dyn Fn(&Views) -> Vec<(f64, f64)>| measured_before_after(m, b, a, view);
    let grid = super::fractional_orders::orders();
    let fractional = |v: &Views| {
        grid.iter()
            .copied()
            .zip(v.fractional.iter().copied())
            .collect()
    };
    chart(
        &top,
        &format!("{name}: fractional orders of the raw signal (half orders: looseness, rub)"),
        "order",
        "dB (thresholded)",
        &three(&fractional),
    )?;
    // landings the measured recording shows, in the band where they ring; else the
    // broadband energy's envelope
    match m.landings.strongest().filter(|_| m.landings.detected()) {
        Some(k) => {
            let (lo, hi) = m.landings.best_band_hz().unwrap_or_default();
            let levels = |v: &Views| {
                let l = v.landings.levels_db.get(k).copied().unwrap_or_default();
                l.iter()
                    .enumerate()
                    .map(|(j, d)| (j as f64 + 0.5, *d))
                    .collect()
            };
            let title = format!(
                "landings: half orders of the energy envelope in {lo:.0}-{hi:.0} Hz, where they ring"
            );
            chart(
                &middle,
                &title,
                "order",
                "dB (thresholded)",
                &three(&levels),
            )?;
        }
        None => {
            let hz = super::impacts::frequencies();
            let impacts = |v: &Views| hz.iter().copied().zip(v.impacts.iter().copied()).collect();
            let title = format!(
                "impacts: envelope of the broadband energy (landings every other revolution: {:.1} Hz)",
                m.rpm / 120.0
            );
            chart(&middle, &title, "Hz", "dB (thresholded)", &three(&impacts))?;
        }
    }
    chart(
        &bottom,
        "band energy (100 Hz bands: the mode the landings ring)",
        "Hz",
        "dB (0 = 20 dB below the strongest band)",
        &three(&band_energies),
    )?;
    root.present()
        .map_err(|x| anyhow!("writing {}: {x}", path.display()))?;
    Ok(())
}

/// The three report figures: `spectra.png` and `residual.png` for the recording `names`
/// indexes by `worst` (largest error before calibration), `looseness.png` for the one whose
/// looseness views (`impacts`, `half_orders`, `fractional`) differ most before calibration.
pub fn all(
    dir: &Path,
    names: &[&str],
    worst: usize,
    (m, b, a): (&[Views], &[Views], &[Views]),
) -> Result<()> {
    use crate::vocabulary::ErrorComponent as C;
    spectra(
        &dir.join("spectra.png"),
        names[worst],
        &m[worst],
        &b[worst],
        &a[worst],
    )?;
    residual(
        &dir.join("residual.png"),
        names[worst],
        &m[worst],
        &a[worst],
    )?;
    let loose = |i: usize| {
        let views = [C::Impacts, C::HalfOrders, C::Fractional];
        super::error::pair_only(&m[i], &b[i], &views).of(&views)
    };
    let l = (0..m.len())
        .max_by(|x, y| loose(*x).total_cmp(&loose(*y)))
        .unwrap_or(worst);
    looseness(&dir.join("looseness.png"), names[l], &m[l], &b[l], &a[l])
}
