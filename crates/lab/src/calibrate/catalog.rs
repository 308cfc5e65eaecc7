//! The effect catalog: each effect is a switchable change of the rig's `[simulation]`
//! section with bounded parameters. `apply` maps parameter values onto simulation keys.
//!
//! | effect | parameters (bounds) | `[simulation]` keys |
//! |---|---|---|
//! | `slip` | `slip` 0-0.06 | `bearing.slip` |
//! | `contact_angle` | `contact_angle_deg` 0-40 | `bearing.contact_angle_deg` |
//! | `resonance` | `hz` 800-0.4 fs (log), `damping` 0.01-0.12 (log) | `structure.resonances[0]` |
//! | `unbalance` | `line1_m_s2` 0.001-10 (log), `exponent` 0-6 (two speeds or more; else 2), `line2_m_s2` 0.0001-10 (log): the 1x and 2x lines added to the rotor's own response | `shaft_lines` at the highest measured speed |
//! | `line_interference` | `line_hz` {50, 60}, `amplitude_m_s2` 0.01-3 (log) | `structure.line_hz`, `line_amplitudes_m_s2` |
//! | `speed_fluctuation` | `period_s` 0.2-5 (log), `fraction` 0.002-0.1 (log); around a measured speed line ([`Context::speed_line`]): `period_s` over its frequency +- one resolution step (1 / the shortest length), `fraction` over its depth / 2-x2 (log), within those bounds, starting there | `speed_fluctuation.period_s`, `.fraction` |
//! | `looseness` | `harmonics_m_s2` 0.0005-3 (log), `slope` -2-3, `highest_order` {5, 10, 20, 30} | `shaft_lines` orders 3..highest: `harmonics_m_s2` (k / k_mid)^`slope`, k_mid the geometric mean order |
//! | `subharmonics` | `half_order_m_s2` 0.0005-3 (log), `exponent` 0-6 (two speeds or more; else 2), `slope` -1-4 (searched from 4, so the 0.5x line is fitted first): the half-order lines of looseness or a rub, 0.5x at `half_order_m_s2`, order o at (2 o)^-`slope` of it, up to 3.5x (the highest half order the fractional view compares) | `subharmonics` at the highest measured speed, `highest_order` 3.5 |
//! | `looseness_impacts` | `impact_m_s2` 0.01-300 (log, at the highest speed of the fit part's healthy recordings, where `floor` and `impacts` see it absolutely; else the highest measured speed), `mode_hz` 300-0.4 fs (log, starting in the band where the healthy recordings' landings ring, else where they exceed the uncalibrated model most; within the half-power width of the peak they ring where that width is read, [`Context::ring`]), `damping` 0.005-0.3 (log; not searched where the fit part's healthy recordings show the mode's half-power width, [`Context::ring`]: read from it), `exponent` 0-6 (two speeds or more; else 2); searched twice over (the impact's size and its mode's frequency pull on each other): a loose housing landing once every two revolutions, each landing ringing one mode | `loose_impacts` at that speed |
//! | `noise` | `noise_rms_m_s2` 0.003-3 (log) | `structure.noise_rms_m_s2` |

use super::half_orders;
use super::ring_width::RingWidth;
use super::speed_line::SpeedLine;
use crate::config::simulation::{
    LooseImpactsConfig, ShaftLinesConfig, SimulationConfig, SpeedFluctuationConfig,
    SubharmonicsConfig,
};
use crate::vocabulary::ErrorComponent;
use serde::Serialize;

/// Effects the calibrator can add.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    Slip,
    ContactAngle,
    Resonance,
    Unbalance,
    LineInterference,
    SpeedFluctuation,
    Looseness,
    Subharmonics,
    LoosenessImpacts,
    Noise,
}

/// The effects a calibration searches. `looseness_impacts` is not among them yet (issue 39,
/// docs/calibration.md): on the independent grid it is named first and fitted within 9-22 %
/// for strong landings (30 m/s^2, and 5 m/s^2 at 1 kHz), but refused or not found for weaker
/// ones (1-5 m/s^2), and its speed law is still read from relative views.
pub const ALL: [Effect; 9] = [
    Effect::Slip,
    Effect::ContactAngle,
    Effect::Resonance,
    Effect::Unbalance,
    Effect::LineInterference,
    Effect::SpeedFluctuation,
    Effect::Looseness,
    Effect::Subharmonics,
    Effect::Noise,
];

/// [`ALL`] with `looseness_impacts` (before `noise`): what a calibration searches where the
/// measured recordings show a loose housing's landings, or with `rigmon calibrate
/// --looseness-impacts` ([`super::fit::Options::looseness_impacts`]).
pub const WITH_LOOSENESS_IMPACTS: [Effect; 10] = [
    Effect::Slip,
    Effect::ContactAngle,
    Effect::Resonance,
    Effect::Unbalance,
    Effect::LineInterference,
    Effect::SpeedFluctuation,
    Effect::Looseness,
    Effect::Subharmonics,
    Effect::LoosenessImpacts,
    Effect::Noise,
];

/// How a parameter is searched.
#[derive(Debug, Clone, PartialEq)]
pub enum Range {
    Linear(f64, f64),
    Log(f64, f64),
    Choice(Vec<f64>),
}

/// One bounded parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Param {
    pub name: &'static str,
    pub range: Range,
}

/// What the measured data fix about the search: the lowest sample rate (bounds the
/// resonance), the highest speed (reference of the shaft and half-order lines) and whether
/// there are recordings at two or more distinct speeds (only then can a growth with speed be
/// fitted), and the speed-fluctuation line the fit part's speed spectra show, if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Context {
    pub fs: f64,
    pub max_rpm: f64,
    pub several_speeds: bool,
    /// The line of the measured speed spectra ([`super::speed_line::find`]):
    /// `speed_fluctuation` is searched around it (on a long recording the line is too narrow
    /// for a search over the whole period range to land on).
    pub speed_line: Option<SpeedLine>,
    /// The band where the fit part's healthy recordings exceed the uncalibrated model most
    /// (where a loose joint's landings would ring), Hz: `looseness_impacts` starts its mode
    /// there.
    pub ringing_hz: Option<f64>,
    /// The highest speed of the fit part's healthy recordings, rpm: the views that tell a
    /// landing's absolute size (`floor`, `impacts`) are compared on healthy recordings only,
    /// so `looseness_impacts` states its strength there (at another speed it is the speed
    /// law's extrapolation); `None` when the fit part has no healthy recording.
    pub healthy_fit_rpm: Option<f64>,
    /// The damping of the mode the fit part's healthy recordings ring, read from its
    /// half-power width ([`super::ring_width`]): `looseness_impacts` takes it rather than
    /// searching it (its other views trade the damping against the landing strength).
    pub ring: Option<RingWidth>,
}

impl Context {
    /// The speed `looseness_impacts` states its landing strength at ([`Self::healthy_fit_rpm`],
    /// else the highest measured speed).
    pub fn landing_rpm(&self) -> f64 {
        self.healthy_fit_rpm.unwrap_or(self.max_rpm)
    }
}

/// Bounds of `speed_fluctuation`'s `period_s`, s...
pub const PERIOD_S: (f64, f64) = (0.2, 5.0);
/// ... and of its `fraction`.
pub const FRACTION: (f64, f64) = (0.002, 0.1);

/// Log range `lo`-`hi` clamped to `bounds`, or the whole `bounds` when nothing is left.
fn log_within(lo: f64, hi: f64, bounds: (f64, f64)) -> (f64, f64) {
    let (a, b) = (lo.max(bounds.0), hi.min(bounds.1));
    if a.is_finite() && b.is_finite() && a > 0.0 && b > a * 1.0001 {
        (a, b)
    } else {
        bounds
    }
}

/// `speed_fluctuation`'s (period_s, fraction) ranges: around the measured line when there
/// is one (the period over the line's frequency +- one resolution step, the fraction over
/// its depth / 2 to x 2), within [`PERIOD_S`] and [`FRACTION`]; else those bounds.
pub fn fluctuation_ranges(cx: &Context) -> ((f64, f64), (f64, f64)) {
    match cx.speed_line {
        Some(l) => {
            let hi_hz = l.hz + l.resolution_hz;
            let lo_hz = l.hz - l.resolution_hz;
            let period = if lo_hz > 0.0 {
                log_within(1.0 / hi_hz, 1.0 / lo_hz, PERIOD_S)
            } else {
                log_within(1.0 / hi_hz, PERIOD_S.1, PERIOD_S)
            };
            let fraction = log_within(0.5 * l.fraction, 2.0 * l.fraction, FRACTION);
            (period, fraction)
        }
        None => (PERIOD_S, FRACTION),
    }
}

/// Bounds of `looseness_impacts`' `impact_m_s2` (the peak of one landing at
/// [`Context::landing_rpm`]): two decades either side of the 1-10 m/s^2 a loose housing gives.
pub const IMPACT_M_S2: (f64, f64) = (0.01, 300.0);

/// `looseness_impacts`' `mode_hz` range: within the half-power width of the peak the fit
/// part's healthy recordings ring ([`Context::ring`]: the mode is where that peak is), else
/// from [`IMPACT_MODE_MIN_HZ`] to 0.4 fs.
fn landing_mode_range(cx: &Context) -> Range {
    let whole = (IMPACT_MODE_MIN_HZ, 0.4 * cx.fs);
    match cx.ring {
        Some(r) => {
            let (lo, hi) = log_within(r.hz * (1.0 - r.damping), r.hz * (1.0 + r.damping), whole);
            Range::Log(lo, hi)
        }
        None => Range::Log(whole.0, whole.1),
    }
}

/// Bounds of `looseness_impacts`' `damping`: a bolted joint's mode rings with 0.5-30 %.
pub const IMPACT_DAMPING: (f64, f64) = (0.005, 0.3);

/// Lowest `looseness_impacts` mode, Hz: a housing's local modes lie above the rotor's.
pub const IMPACT_MODE_MIN_HZ: f64 = 300.0;

/// Exponent of the shaft lines when one speed cannot fix it: the unbalance force's speed^2.
pub const DEFAULT_EXPONENT: f64 = 2.0;

/// Bounds of `subharmonics`' `slope`: at -1 1.5x is three times 0.5x, at 4 it is 1/81 of it
/// (the search starts there, so the 0.5x line is fitted before the higher half orders).
pub const SLOPE: (f64, f64) = (-1.0, 4.0);

impl Effect {
    pub fn name(&self) -> &'static str {
        match self {
            Effect::Slip => "slip",
            Effect::ContactAngle => "contact_angle",
            Effect::Resonance => "resonance",
            Effect::Unbalance => "unbalance",
            Effect::LineInterference => "line_interference",
            Effect::SpeedFluctuation => "speed_fluctuation",
            Effect::Looseness => "looseness",
            Effect::Subharmonics => "subharmonics",
            Effect::LoosenessImpacts => "looseness_impacts",
            Effect::Noise => "noise",
        }
    }

    /// The error components this effect acts on: its parameters are searched, and it is
    /// accepted, on these alone, so an effect cannot win by absorbing a mismatch it does not
    /// model physically (e.g. a contact angle reshaping the resonance bands).
    pub fn components(&self) -> &'static [ErrorComponent] {
        use ErrorComponent as C;
        match self {
            Effect::Slip | Effect::ContactAngle => &[C::Env, C::Peaks],
            Effect::Resonance => &[C::Bands, C::Modes],
            Effect::Unbalance => &[C::Orders],
            Effect::LineInterference => &[C::Lines],
            Effect::SpeedFluctuation => &[C::Speed, C::Lines],
            Effect::Looseness => &[C::Harmonics],
            Effect::Subharmonics => &[C::HalfOrders],
            Effect::LoosenessImpacts => &[C::Impacts, C::HalfOrders, C::Bands, C::Modes, C::Floor],
            Effect::Noise => &[C::Floor],
        }
    }

    /// Whether the effect's signature is locked to the shaft angle (lines at orders or half
    /// orders, impacts at a fixed angle): such an effect explains a periodic residual that a
    /// free effect (broadband `noise`, a `resonance` at any frequency) can only absorb, so
    /// it is preferred when it cuts the whole error more ([`super::fit`]).
    pub fn locked_to_shaft(&self) -> bool {
        matches!(
            self,
            Effect::Unbalance | Effect::Looseness | Effect::Subharmonics | Effect::LoosenessImpacts
        )
    }

    /// Whether the effect is free of the shaft: it can absorb any residual of its kind.
    pub fn free(&self) -> bool {
        matches!(self, Effect::Noise | Effect::Resonance)
    }

    /// How many times the coordinate search goes over the parameters: twice where they
    /// pull on each other (an impact's size is judged through the mode it rings).
    pub fn search_passes(&self) -> usize {
        match self {
            Effect::LoosenessImpacts => 2,
            _ => 1,
        }
    }

    /// Parameters and bounds.
    pub fn params(&self, cx: &Context) -> Vec<Param> {
        let p = |name, range| Param { name, range };
        match self {
            Effect::Slip => vec![p("slip", Range::Linear(0.0, 0.06))],
            Effect::ContactAngle => vec![p("contact_angle_deg", Range::Linear(0.0, 40.0))],
            Effect::Resonance => vec![
                p("hz", Range::Log(800.0, 0.4 * cx.fs)),
                p("damping", Range::Log(0.01, 0.12)),
            ],
            Effect::Unbalance => {
                let mut v = vec![p("line1_m_s2", Range::Log(0.001, 10.0))];
                if cx.several_speeds {
                    v.push(p("exponent", Range::Linear(0.0, 6.0)));
                }
                v.push(p("line2_m_s2", Range::Log(0.0001, 10.0)));
                v
            }
            Effect::LineInterference => vec![
                p("line_hz", Range::Choice(vec![50.0, 60.0])),
                p("amplitude_m_s2", Range::Log(0.01, 3.0)),
            ],
            Effect::SpeedFluctuation => {
                let (period, fraction) = fluctuation_ranges(cx);
                vec![
                    p("period_s", Range::Log(period.0, period.1)),
                    p("fraction", Range::Log(fraction.0, fraction.1)),
                ]
            }
            Effect::Looseness => vec![
                p("harmonics_m_s2", Range::Log(0.0005, 3.0)),
                p("slope", Range::Linear(-2.0, 3.0)),
                p("highest_order", Range::Choice(vec![5.0, 10.0, 20.0, 30.0])),
            ],
            Effect::Subharmonics => {
                let mut v = vec![p("half_order_m_s2", Range::Log(0.0005, 3.0))];
                if cx.several_speeds {
                    v.push(p("exponent", Range::Linear(0.0, 6.0)));
                }
                v.push(p("slope", Range::Linear(SLOPE.0, SLOPE.1)));
                v
            }
            Effect::LoosenessImpacts => {
                let mut v = vec![
                    p("impact_m_s2", Range::Log(IMPACT_M_S2.0, IMPACT_M_S2.1)),
                    p("mode_hz", landing_mode_range(cx)),
                ];
                if cx.ring.is_none() {
                    v.push(p("damping", Range::Log(IMPACT_DAMPING.0, IMPACT_DAMPING.1)));
                }
                if cx.several_speeds {
                    v.push(p("exponent", Range::Linear(0.0, 6.0)));
                }
                v
            }
            Effect::Noise => vec![p("noise_rms_m_s2", Range::Log(0.003, 3.0))],
        }
    }

    /// Starting values for a search (the rig's current value where there is one).
    pub fn start(&self, sim: &SimulationConfig, cx: &Context) -> Vec<f64> {
        match self {
            Effect::Slip => vec![sim.bearing.slip],
            Effect::ContactAngle => vec![sim.bearing.contact_angle_deg.unwrap_or(0.0)],
            Effect::Resonance => match sim.structure.resonances.first() {
                Some(r) => vec![r.hz, r.damping],
                None => vec![0.2 * cx.fs, 0.03],
            },
            Effect::Unbalance => {
                let mut v = vec![0.01];
                if cx.several_speeds {
                    v.push(DEFAULT_EXPONENT);
                }
                v.push(0.001);
                v
            }
            Effect::LineInterference => vec![50.0, 0.1],
            Effect::SpeedFluctuation => {
                let (period, fraction) = fluctuation_ranges(cx);
                match cx.speed_line {
                    // the line's period and depth, within the ranges
                    Some(l) => vec![
                        (1.0 / l.hz).clamp(period.0, period.1),
                        l.fraction.clamp(fraction.0, fraction.1),
                    ],
                    None => vec![1.0, 0.01],
                }
            }
            Effect::Looseness => vec![0.01, 0.0, 10.0],
            Effect::Subharmonics => {
                let mut v = vec![0.01];
                if cx.several_speeds {
                    v.push(DEFAULT_EXPONENT);
                }
                // the steepest slope: the 0.5x line (and its speed law) is fitted first, with
                // the higher half orders too weak to pull it; then their decay
                v.push(SLOPE.1);
                v
            }
            Effect::LoosenessImpacts => {
                let mode = cx
                    .ring
                    .map(|r| r.hz)
                    .or(cx.ringing_hz)
                    .or(sim.structure.resonances.first().map(|r| r.hz))
                    .unwrap_or(0.1 * cx.fs)
                    .clamp(IMPACT_MODE_MIN_HZ, 0.4 * cx.fs);
                let mut v = vec![1.0, mode];
                if cx.ring.is_none() {
                    v.push(0.05);
                }
                if cx.several_speeds {
                    v.push(DEFAULT_EXPONENT);
                }
                v
            }
            Effect::Noise => vec![sim.structure.noise_rms_m_s2],
        }
    }

    /// The simulation section with this effect switched on at `values` (in the order of
    /// [`Effect::params`]).
    pub fn apply(&self, base: &SimulationConfig, values: &[f64], cx: &Context) -> SimulationConfig {
        let mut s = base.clone();
        match self {
            Effect::Slip => s.bearing.slip = values[0],
            Effect::ContactAngle => s.bearing.contact_angle_deg = Some(values[0]),
            Effect::Resonance => {
                if let Some(r) = s.structure.resonances.first_mut() {
                    r.hz = values[0];
                    r.damping = values[1];
                }
            }
            Effect::Unbalance => {
                let (exponent, order2) = if cx.several_speeds {
                    (values[1], values[2])
                } else {
                    (DEFAULT_EXPONENT, values[1])
                };
                let lines = shaft_lines(&mut s, cx, 2);
                lines.exponent = exponent;
                lines.amplitudes_m_s2[0] = values[0];
                lines.amplitudes_m_s2[1] = order2;
            }
            Effect::Looseness => {
                let highest = values[2].round().max(3.0) as usize;
                let mid = ((3..=highest).map(|k| (k as f64).ln()).sum::<f64>()
                    / (highest - 2) as f64)
                    .exp();
                let lines = shaft_lines(&mut s, cx, highest);
                lines.amplitudes_m_s2.truncate(highest);
                for (k, a) in (3..).zip(&mut lines.amplitudes_m_s2[2..]) {
                    *a = values[0] * (k as f64 / mid).powf(values[1]);
                }
            }
            Effect::Subharmonics => {
                let (exponent, slope) = if cx.several_speeds {
                    (values[1], values[2])
                } else {
                    (DEFAULT_EXPONENT, values[1])
                };
                s.subharmonics = Some(SubharmonicsConfig {
                    ref_rpm: cx.max_rpm,
                    exponent,
                    half_order_m_s2: values[0],
                    slope,
                    highest_order: half_orders::ORDERS[half_orders::ORDERS.len() - 1],
                    phase_deg: 0.0,
                });
            }
            Effect::LoosenessImpacts => {
                // [impact, mode, damping unless read from the ring's width, exponent?]
                let (damping, rest) = match cx.ring {
                    Some(r) => (r.damping, &values[2..]),
                    None => (values[2], &values[3..]),
                };
                s.loose_impacts = Some(LooseImpactsConfig {
                    ref_rpm: cx.landing_rpm(),
                    exponent: rest.first().copied().unwrap_or(DEFAULT_EXPONENT),
                    impact_m_s2: values[0],
                    mode_hz: values[1],
                    damping,
                    horizontal_ratio: 0.5,
                    phase_deg: 0.0,
                    timing_jitter: crate::config::simulation::DEFAULT_TIMING_JITTER,
                })
            }
            Effect::Noise => s.structure.noise_rms_m_s2 = values[0],

            Effect::LineInterference => {
                s.structure.line_hz = values[0];
                s.structure.line_amplitudes_m_s2 = vec![values[1]];
            }
            Effect::SpeedFluctuation => {
                s.speed_fluctuation = Some(SpeedFluctuationConfig {
                    period_s: values[0],
                    fraction: values[1],
                })
            }
        }
        s
    }
}

/// The section's shaft lines (created at the highest measured speed with the default
/// exponent when absent) with at least `orders` entries. Unbalance owns orders 1-2,
/// looseness 3 and up; they share the reference speed and the exponent.
fn shaft_lines<'a>(
    s: &'a mut SimulationConfig,
    cx: &Context,
    orders: usize,
) -> &'a mut ShaftLinesConfig {
    let lines = s.shaft_lines.get_or_insert_with(|| ShaftLinesConfig {
        ref_rpm: cx.max_rpm,
        exponent: DEFAULT_EXPONENT,
        amplitudes_m_s2: Vec::new(),
        phase_deg: 0.0,
    });
    if lines.amplitudes_m_s2.len() < orders {
        lines.amplitudes_m_s2.resize(orders, 0.0);
    }
    lines
}
