//! A point's trend as a PNG (`rigmon history --png`): three panels over the same time axis,
//! the smoothed state as coloured bands, the velocity RMS with its ISO 20816-3 zone limits,
//! and the envelope order-spectrum levels at the fault orders (first harmonic) with the
//! spectrum's floor.

use crate::health::UNKNOWN;
use crate::plots::ensure_font;
use crate::vocabulary::Condition;
use crate::wire::health::HealthMessage;
use anyhow::{anyhow, bail, Result};
use plotters::prelude::*;
use std::path::Path;

/// Colours of the states in [`Condition::NAMES`] order (healthy, outer race, inner race, ball).
const LABEL_COLOURS: [RGBColor; 4] = [
    RGBColor(60, 170, 80),
    RGBColor(220, 60, 50),
    RGBColor(240, 150, 30),
    RGBColor(150, 50, 180),
];

/// Colour of a state band.
fn state_colour(state: &str) -> RGBColor {
    if state == UNKNOWN {
        return RGBColor(170, 170, 170);
    }
    Condition::NAMES
        .iter()
        .position(|l| *l == state)
        .map_or(RGBColor(60, 90, 200), |i| LABEL_COLOURS[i])
}

/// Draw `windows` (one point, oldest first); `limits` are the zone limits A/B, B/C, C/D and
/// whether they are the point's own (false: the standard's defaults).
pub fn draw(path: &Path, windows: &[HealthMessage], limits: ([f64; 3], bool)) -> Result<()> {
    if windows.is_empty() {
        bail!("no windows to draw");
    }
    ensure_font()?;
    let t0 = windows[0].window.end_ns;
    let t = |m: &HealthMessage| (m.window.end_ns.saturating_sub(t0)) as f64 / 60e9;
    let span = t(windows.last().expect("non-empty")).max(1.0 / 60.0);
    let root = BitMapBackend::new(path, (1400, 900)).into_drawing_area();
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("drawing {}: {e:?}", path.display());
    root.fill(&WHITE).map_err(e)?;
    let start = humantime::format_rfc3339_seconds(
        std::time::UNIX_EPOCH + std::time::Duration::from_nanos(t0),
    );
    let title = format!(
        "{}  {}/{}/{}  from {start}",
        windows[0].site.as_deref().unwrap_or(""),
        windows[0].rig,
        windows[0].asset,
        windows[0].point
    );
    let root = root.titled(&title, ("sans-serif", 22)).map_err(e)?;
    let panels = root.split_by_breakpoints::<i32, i32, [i32; 0], [i32; 2]>([], [110, 480]);
    // States.
    let mut c = ChartBuilder::on(&panels[0])
        .margin(8)
        .x_label_area_size(20)
        .y_label_area_size(70)
        .caption("smoothed state", ("sans-serif", 16))
        .build_cartesian_2d(0.0..span, 0.0..1.0)
        .map_err(e)?;
    c.configure_mesh()
        .disable_mesh()
        .y_labels(0)
        .draw()
        .map_err(e)?;
    let mut seen: Vec<String> = Vec::new();
    for pair in windows.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let colour = state_colour(&a.state);
        c.draw_series(std::iter::once(Rectangle::new(
            [(t(a), 0.0), (t(b), 1.0)],
            colour.filled(),
        )))
        .map_err(e)?;
        if !seen.contains(&a.state) {
            seen.push(a.state.clone());
        }
    }
    for (i, s) in seen.iter().enumerate() {
        let x = span * (0.01 + 0.14 * i as f64);
        c.draw_series(std::iter::once(Text::new(
            s.clone(),
            (x, 0.5),
            ("sans-serif", 15).into_font().color(&WHITE),
        )))
        .map_err(e)?;
    }
    velocity_panel(&panels[1], windows, &t, span, limits).map_err(|x| anyhow!("{x}"))?;
    bands_panel(&panels[2], windows, &t, span).map_err(|x| anyhow!("{x}"))?;
    root.present().map_err(e)?;
    Ok(())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn velocity_panel(
    area: &Area,
    w: &[HealthMessage],
    t: &dyn Fn(&HealthMessage) -> f64,
    span: f64,
    limits: ([f64; 3], bool),
) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("drawing the velocity panel: {e:?}");
    let vmax = w
        .iter()
        .filter_map(|m| m.velocity_rms_mm_s)
        .fold(0.0, f64::max);
    let top = (vmax.max(limits.0[2]) * 1.15).max(0.1);
    let source = if limits.1 {
        "the point's own"
    } else {
        "ISO 20816-3 default (group 2, rigid)"
    };
    let mut c = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .caption(
            format!("velocity RMS 10-1000 Hz, mm/s; zone limits A/B, B/C, C/D: {source}"),
            ("sans-serif", 16),
        )
        .build_cartesian_2d(0.0..span, 0.0..top)
        .map_err(e)?;
    c.configure_mesh()
        .x_desc("minutes")
        .y_desc("mm/s")
        .draw()
        .map_err(e)?;
    for (l, name) in limits.0.iter().zip(["A/B", "B/C", "C/D"]) {
        let style = RGBColor(200, 80, 60).stroke_width(1);
        c.draw_series(LineSeries::new([(0.0, *l), (span, *l)], style))
            .map_err(e)?;
        c.draw_series(std::iter::once(Text::new(
            name.to_string(),
            (span * 0.005, *l),
            ("sans-serif", 13),
        )))
        .map_err(e)?;
    }
    let pts: Vec<(f64, f64)> = w
        .iter()
        .filter_map(|m| m.velocity_rms_mm_s.map(|v| (t(m), v)))
        .collect();
    c.draw_series(LineSeries::new(pts, BLUE.stroke_width(2)))
        .map_err(e)?;
    Ok(())
}

fn bands_panel(
    area: &Area,
    w: &[HealthMessage],
    t: &dyn Fn(&HealthMessage) -> f64,
    span: f64,
) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<_>| anyhow!("drawing the fault-band panel: {e:?}");
    type Pick = fn(&HealthMessage) -> Option<f32>;
    let series: [(&str, Pick, RGBColor); 4] = [
        (
            "BPFO",
            |m| m.fault_bands.bpfo.first().copied(),
            RGBColor(220, 60, 50),
        ),
        (
            "BPFI",
            |m| m.fault_bands.bpfi.first().copied(),
            RGBColor(240, 150, 30),
        ),
        (
            "2xBSF",
            |m| m.fault_bands.two_bsf.first().copied(),
            RGBColor(150, 50, 180),
        ),
        (
            "floor",
            |m| (!m.fault_bands.bpfo.is_empty()).then_some(m.fault_bands.floor),
            RGBColor(120, 120, 120),
        ),
    ];
    let top = w
        .iter()
        .flat_map(|m| series.iter().filter_map(|s| (s.1)(m)))
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::max);
    let unit = w
        .first()
        .map(|m| m.fault_bands.channel.clone())
        .unwrap_or_default();
    let mut c = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .caption(
            format!(
                "envelope order-spectrum level at the fault orders (1st harmonic), channel {unit}"
            ),
            ("sans-serif", 16),
        )
        .build_cartesian_2d(0.0..span, 0.0..(f64::from(top) * 1.15).max(1e-6))
        .map_err(e)?;
    c.configure_mesh().x_desc("minutes").draw().map_err(e)?;
    for (name, pick, colour) in series {
        let pts: Vec<(f64, f64)> = w
            .iter()
            .filter_map(|m| {
                pick(m)
                    .filter(|v| v.is_finite())
                    .map(|v| (t(m), f64::from(v)))
            })
            .collect();
        c.draw_series(LineSeries::new(pts, colour.stroke_width(2)))
            .map_err(e)?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    Ok(())
}
