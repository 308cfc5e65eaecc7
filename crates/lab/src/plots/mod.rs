//! PNG pictures (plotters): shared set-up such as the font. One file per kind of picture.

pub mod confusion;
pub mod embedding;
pub mod kurtogram;
pub mod point_trend;
pub mod trend;

use anyhow::{bail, Result};
use std::sync::OnceLock;

/// Font files tried in order (Debian's fonts-dejavu-core ships the first).
const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

static FONT: OnceLock<Result<(), String>> = OnceLock::new();

/// Register a sans-serif font with plotters once per process. Call before drawing text.
/// Set `RIGMON_FONT` to a .ttf file to choose another font.
pub fn ensure_font() -> Result<()> {
    let r = FONT.get_or_init(|| {
        let mut candidates: Vec<String> = Vec::new();
        if let Ok(p) = std::env::var("RIGMON_FONT") {
            candidates.push(p);
        }
        candidates.extend(FONT_CANDIDATES.iter().map(|s| s.to_string()));
        for p in &candidates {
            if let Ok(bytes) = std::fs::read(p) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err(format!(
            "no TrueType font found for plot labels (tried {}); install fonts-dejavu-core or set RIGMON_FONT=/path/to/font.ttf",
            candidates.join(", ")
        ))
    });
    match r {
        Ok(()) => Ok(()),
        Err(e) => bail!("{e}"),
    }
}

pub mod spectrum;
