//! The dominant structural resonance of a recording: where the band-energy spectrum peaks,
//! when that peak stands clearly above the typical band (impacts ringing through a mode do;
//! white noise does not) and is broad (a resonance spreads over neighbouring bands; a single
//! strong line does not). Located on the band grid with a parabolic refinement.

/// The strongest band must stand this far above the median band, dB...
pub const MIN_PROMINENCE_DB: f64 = 10.0;
/// ... and a neighbouring band must lie within this of it, dB.
pub const MAX_NEIGHBOUR_DROP_DB: f64 = 10.0;

/// Location (Hz) of the dominant resonance, and whether it stands out.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Mode {
    pub hz: f64,
    pub prominent: bool,
}

/// `band_db`: band energies in dB (any reference); `lo_hz`: lower band edges; `width_hz`:
/// band width.
pub fn dominant(band_db: &[f64], lo_hz: &[f64], width_hz: f64) -> Mode {
    let n = band_db.len();
    if n == 0 {
        return Mode::default();
    }
    let k = (0..n)
        .max_by(|a, b| band_db[*a].total_cmp(&band_db[*b]))
        .unwrap_or(0);
    let mut offset = 0.0;
    if k > 0 && k + 1 < n {
        let (a, b, c) = (band_db[k - 1], band_db[k], band_db[k + 1]);
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            offset = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
        }
    }
    let med = super::stats::median(band_db);
    let neighbour = [k.checked_sub(1), Some(k + 1)]
        .into_iter()
        .flatten()
        .filter_map(|j| band_db.get(j))
        .copied()
        .fold(f64::MIN, f64::max);
    Mode {
        hz: lo_hz[k] + (0.5 + offset) * width_hz,
        prominent: band_db[k] - med >= MIN_PROMINENCE_DB
            && band_db[k] - neighbour <= MAX_NEIGHBOUR_DROP_DB,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locates_a_resonance_between_bands() {
        let lo: Vec<f64> = (0..30).map(|i| 300.0 + 100.0 * i as f64).collect();
        let db: Vec<f64> = lo
            .iter()
            .map(|f| {
                let c = f + 50.0;
                30.0 * (-((c - 2330.0) / 150.0).powi(2)).exp()
            })
            .collect();
        let m = dominant(&db, &lo, 100.0);
        assert!(m.prominent);
        assert!((m.hz - 2330.0).abs() < 20.0, "{m:?}");
        let flat = vec![3.0; 30];
        assert!(!dominant(&flat, &lo, 100.0).prominent);
        let mut line = vec![3.0; 30];
        line[4] = 30.0;
        assert!(
            !dominant(&line, &lo, 100.0).prominent,
            "one strong line is no resonance"
        );
    }
}
