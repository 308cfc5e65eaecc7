//! A stated speed is a prior, not the truth (issue 34 item 3): the streaming tracker
//! ([`super::speed_tracker`]) searches a hint's band, and this module asks whether the same
//! spectrum clearly shows the shaft at the octave below the line found there, inside
//! the rig's whole speed range. A file named 600 rpm whose shaft turns at 1200 shows the lines
//! of 1200 (20, 40, 60 Hz), which are the even harmonics of 600: inside the band the harmonic
//! sum reads 600, and without this check nothing says the name is wrong.
//!
//! The rules are the tracker's own octave rules, with the alternative required to be a clear
//! line on the tracker's scale ([`SCORE_CLEAR`]: a line 13x its floor; a bin of noise exceeds
//! that with probability e^-126), so a hint is kept wherever the evidence is unclear:
//! - **the octave below** (g / 2): the lines it adds to g's series (its odd harmonics, or its
//!   lone 1x line less [`LONE_ALLOW`]) are clear, and at least half as strong as g's series
//!   (the octave guard of [`super::harmonic_sum::fundamental`]);
//! - **the octave above** (2 g) is **not searched**: its only evidence is the absence of g's
//!   odd lines, and on the shared HIT-SM records (checked after the rule was chosen) that
//!   absence read a fault record at 600 rpm as 1200 in 1-2 of its 9 windows while missing the
//!   Normal record named 600 that turns at 1200 (docs/speed.md); a rule needs more than one
//!   window's spectrum (not built);
//! - **the bearing's fault families** veto a switch: when the envelope places a BPFO, BPFI or
//!   2xBSF family at g's orders rather than the alternative's
//!   ([`super::fault_family::FamilyEvidence::prefers`]), g stays. Neither rule looks at a
//!   bearing comb (its lines are not on an octave of g's series), so a comb never becomes the
//!   shaft here.
//!
//! Speeds other than the two octaves (a shaft comb elsewhere in the range) are not searched:
//! the hint's band already holds a nominal speed 10 % off.

use super::fault_family::{FamilyEvidence, FamilySettings};
use super::harmonic_sum::{Whitened, LONE_ALLOW};

/// Harmonic prominence of a clear line: the tracker's confidence scale reads 1 from here (the
/// stored-speed check's threshold: 2.6-5.2 on every CWRU record).
pub const SCORE_CLEAR: f64 = 2.0;

/// The octave of the hint band's line that the vibration shows instead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffHint {
    /// The vibration's speed, Hz.
    pub hz: f64,
    /// Its own lines' prominence (at least [`SCORE_CLEAR`]).
    pub score: f64,
}

/// The octave of `g` (the best line in the hint's band, Hz, with harmonic prominence
/// `g_score`) that spectrum `w` clearly shows instead, inside `range` (Hz), unless the fault
/// families in `env` (the envelope spectrum, scored up to `env_top` Hz) place their lines at
/// g's orders. None: the hint's band holds the speed.
pub fn octave_off_hint(
    w: &Whitened,
    g: f64,
    g_score: f64,
    range: (f64, f64),
    families: Option<(&FamilySettings, &Whitened, f64)>,
) -> Option<OffHint> {
    let alt = below(w, g, g_score, range.0)?;
    let keeps_g = families.is_some_and(|(fam, env, top)| {
        FamilyEvidence::new(env, &fam.orders, top)
            .prefers(g, alt.hz)
            .is_some()
    });
    (!keeps_g).then_some(alt)
}

/// g / 2 when the lines it adds are clear and at least half as strong as g's series.
fn below(w: &Whitened, g: f64, g_score: f64, lo: f64) -> Option<OffHint> {
    let half = g / 2.0;
    if half < lo {
        return None;
    }
    let (hz, odd) = w.odd_support(half, 2);
    let score = odd.max(lone(w, hz));
    (score >= SCORE_CLEAR && score >= 0.5 * g_score).then_some(OffHint { hz, score })
}

/// A lone line at `f` as shaft evidence (its prominence less [`LONE_ALLOW`]), off the mains.
fn lone(w: &Whitened, f: f64) -> f64 {
    if w.on_mains(f) {
        return f64::NEG_INFINITY;
    }
    w.at(f) - LONE_ALLOW
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat spectrum (prominence 0) with lines of prominence `p` at `lines` Hz.
    fn spectrum(lines: &[(f64, f64)]) -> Whitened {
        let df = 0.1;
        let mut w = Whitened {
            df,
            prom: vec![0.0; 1000],
            skip_mains: true,
            interpolate: false,
            ..Whitened::default()
        };
        for &(f, p) in lines {
            w.prom[(f / df).round() as usize] = p;
        }
        w
    }

    #[test]
    fn the_even_lines_of_the_band_are_not_searched_as_the_octave_above() {
        // a 12 Hz shaft (lines 12, 24, 36, 48) read at 6 Hz in a hint band around 6 Hz
        let w = spectrum(&[(12.0, 4.0), (24.0, 4.0), (36.0, 3.0), (48.0, 3.0)]);
        assert_eq!(
            octave_off_hint(&w, 6.0, w.full(6.0), (1.0, 20.0), None),
            None
        );
    }

    #[test]
    fn clear_lines_between_the_bands_lines_are_the_octave_below() {
        // a 5 Hz shaft (5, 10, 15, 20, 25) read at 10 Hz
        let w = spectrum(&[
            (5.0, 3.0),
            (10.0, 4.0),
            (15.0, 3.0),
            (20.0, 4.0),
            (25.0, 2.5),
        ]);
        let alt = octave_off_hint(&w, 10.0, w.full(10.0), (1.0, 20.0), None).unwrap();
        assert!((alt.hz - 5.0).abs() < 0.05, "{alt:?}");
        // weak lines in between (a little looseness) leave the hint's speed
        let w = spectrum(&[
            (5.0, 1.0),
            (10.0, 4.0),
            (15.0, 1.0),
            (20.0, 4.0),
            (25.0, 1.0),
        ]);
        assert_eq!(
            octave_off_hint(&w, 10.0, w.full(10.0), (1.0, 20.0), None),
            None
        );
    }
}
