//! Localized defects: how far a ball drops while it rolls over a slot on the outer race
//! (fixed), the inner race (turns with the shaft) or on a ball (spins with the ball).
//!
//! The drop is limited by geometry: a ball of radius r over a slot of width w (rolling
//! direction) cannot sink deeper than the chord height r - sqrt(r^2 - (w/2)^2), corrected
//! by the race curvature (the concave outer race gives a little less, the convex inner race
//! a little more), and never deeper than the slot. A slot shorter than the contact patch
//! across the race drops the ball proportionally less. The profile along the slot follows
//! [`DefectShape`] (thesis Fig. 11 / eq. 9-10 for `Linear`).

use crate::config::simulation::{DefectConfig, DefectShape};

/// Which defects a scenario contains.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DefectSet {
    pub outer_race: bool,
    pub inner_race: bool,
    pub ball: bool,
}

/// One slot as seen along its rolling path.
#[derive(Debug, Clone, Copy)]
pub struct Slot {
    /// Half-width of the slot as an angle on its rolling circle (rad).
    pub half_angle: f64,
    /// tan(half_angle): a phasor (c, s) with c > 0 is off the slot when |s| >= c tan(half_angle).
    pub tan_half_angle: f64,
    /// Radius of the rolling circle (m): arc length = angle x radius.
    pub radius: f64,
    /// Maximum drop (m).
    pub max_drop: f64,
    pub width: f64,
    pub shape: DefectShape,
    /// Ball radius (m), for the geometric profile.
    pub ball_r: f64,
}

fn sagitta(r: f64, half_chord: f64) -> f64 {
    let h = half_chord.min(r);
    r - (r * r - h * h).sqrt()
}

impl Slot {
    /// A slot on a race of curvature radius `race_r` (`convex` for the inner race / ball side),
    /// rolled over along a circle of radius `path_r`.
    pub fn new(cfg: &DefectConfig, ball_r: f64, race_r: f64, convex: bool, path_r: f64) -> Slot {
        let w = cfg.width_mm * 1e-3;
        let s_ball = sagitta(ball_r, w / 2.0);
        let s_race = sagitta(race_r, w / 2.0);
        let geom = if convex {
            s_ball + s_race
        } else {
            (s_ball - s_race).max(0.0)
        };
        let patch = (cfg.length_mm / cfg.contact_patch_mm).min(1.0);
        let max_drop = geom.min(cfg.depth_mm * 1e-3) * patch;
        let half_angle = w / 2.0 / path_r;
        Slot {
            half_angle,
            tan_half_angle: half_angle.min(1.5).tan(),
            radius: path_r,
            max_drop,
            width: w,
            shape: cfg.shape,
            ball_r,
        }
    }

    /// [`Slot::drop_at`] for the angle of the phasor (`c` = cos, `s` = sin, c > 0, not
    /// necessarily of unit length): the angle (an `atan2`) is only taken when the phasor
    /// is within the slot's half-width, which the step loop asks of every ball near a
    /// defect at every step.
    #[inline]
    pub fn drop_at_phasor(&self, s: f64, c: f64) -> f64 {
        if s.abs() >= c * self.tan_half_angle {
            return 0.0;
        }
        self.drop_at(s.atan2(c))
    }

    /// Drop (m) when the ball centre is `angle` (rad, |angle| small) from the slot centre.
    #[inline]
    pub fn drop_at(&self, angle: f64) -> f64 {
        if angle.abs() >= self.half_angle {
            return 0.0;
        }
        // Position from the leading edge, 0..w.
        let s = angle * self.radius + 0.5 * self.width;
        let u = s.min(self.width - s).max(0.0);
        match self.shape {
            DefectShape::Step => self.max_drop,
            DefectShape::Linear => self.max_drop * (2.0 * u / self.width),
            DefectShape::Geometric => {
                let full = sagitta(self.ball_r, 0.5 * self.width);
                if full <= 0.0 {
                    0.0
                } else {
                    self.max_drop * (sagitta(self.ball_r, u) / full)
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ball_cannot_reach_the_bottom_of_a_narrow_slot() {
        let cfg = DefectConfig::default(); // 0.5 mm wide, 0.2 mm deep
        let r = 7.94e-3 / 2.0;
        let outer = Slot::new(&cfg, r, 24e-3 + r, false, 24e-3 + r);
        let inner = Slot::new(&cfg, r, 24e-3 - r, true, 24e-3 - r);
        // chord height of a 3.97 mm ball over 0.5 mm: 7.9 um
        assert!(
            outer.max_drop > 6.5e-6 && outer.max_drop < 7.9e-6,
            "{}",
            outer.max_drop
        );
        assert!(
            inner.max_drop > 7.9e-6 && inner.max_drop < 9.5e-6,
            "{}",
            inner.max_drop
        );
        assert_eq!(outer.drop_at(outer.half_angle * 1.01), 0.0);
        assert!((outer.drop_at(0.0) - outer.max_drop).abs() < 1e-12);
        assert!(outer.drop_at(0.5 * outer.half_angle) < 0.5 * outer.max_drop);
    }

    #[test]
    fn the_phasor_form_gives_the_drop_of_its_angle() {
        let cfg = DefectConfig::default();
        let r = 7.94e-3 / 2.0;
        for slot in [
            Slot::new(&cfg, r, 24e-3 + r, false, 24e-3 + r),
            Slot::new(&cfg, r, 24e-3 - r, true, 24e-3 - r),
            Slot::new(&cfg, r, r, true, r),
        ] {
            for k in -4000..=4000 {
                let a = k as f64 * 1e-4 * slot.half_angle.max(0.01) * 3.0;
                let (s, c) = a.sin_cos();
                for scale in [1.0, 0.97] {
                    let got = slot.drop_at_phasor(scale * s, scale * c);
                    let want = slot.drop_at((scale * s).atan2(scale * c));
                    assert_eq!(got.to_bits(), want.to_bits(), "angle {a}");
                }
            }
        }
    }

    #[test]
    fn shallow_slot_caps_the_drop() {
        let cfg = DefectConfig {
            depth_mm: 0.002,
            ..DefectConfig::default()
        };
        let s = Slot::new(&cfg, 3.97e-3, 28e-3, false, 28e-3);
        assert!((s.max_drop - 2e-6).abs() < 1e-12);
    }
}
