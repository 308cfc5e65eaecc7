//! The `[simulation]` section of a rig file: what the simulator needs to build this rig
//! (rotor, supports, the nonlinear test bearing, defects, structural path, tacho, channels).
//! Every key has a default that reproduces the thesis rig (Paper A, section 4), so
//! `[simulation]` alone is a valid section. [`crate::config::RigConfig`] holds it as its
//! `simulation` field; the simulator ([`crate::sim`]) reads it.
//!
//! Units are in the key names (`_mm`, `_n_per_m`, ...). Switchable effects (for calibration)
//! are plain parameters: set them to zero to switch them off.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Simulator description of a rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulationConfig {
    /// Output sample rate in Hz; default: the rig's `acquisition.sample_rate_hz` (else 10 kHz).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Internal integration steps per output sample (the stiff contact needs ~10 us steps).
    pub oversampling: u32,
    /// Simulated time discarded before the recording starts (settling), s.
    pub warmup_s: f64,
    pub gravity_m_s2: f64,
    pub rotor: RotorConfig,
    pub housing: HousingConfig,
    pub bearing: BallBearingConfig,
    pub defect: DefectConfig,
    pub structure: StructureConfig,
    pub tacho: TachoConfig,
    /// Rig channel name -> simulated signal (`axial`, `vertical`, `horizontal` of the test
    /// bearing housing; `support_vertical`, `support_horizontal` of the other housing).
    /// Channels not listed are matched by their axis; unmatched channels are left out.
    pub channel_map: BTreeMap<String, String>,
    /// Sinusoidal fluctuation of the shaft speed around a constant scenario speed (found by
    /// `rigmon calibrate`); off when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed_fluctuation: Option<SpeedFluctuationConfig>,
    /// Shaft-order lines at the sensor beyond what the rotor model transmits (found by
    /// `rigmon calibrate` as `unbalance`); off when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shaft_lines: Option<ShaftLinesConfig>,
    /// Half-order lines (0.5x, 1.5x, ...) at the sensor, as mechanical looseness or a rub
    /// gives (found by `rigmon calibrate` as `subharmonics`); off when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub subharmonics: Option<SubharmonicsConfig>,
    /// Impacts of a loose housing landing once every two revolutions, each ringing a
    /// structural mode (found by `rigmon calibrate` as `looseness_impacts`); off when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loose_impacts: Option<LooseImpactsConfig>,
}

/// `[simulation.shaft_lines]`: vibration locked to the shaft angle at orders 1, 2, ... on the
/// radial channels (vertical, horizontal 90 deg behind), added to what the rotor model gives.
/// Order k has amplitude `amplitudes_m_s2[k-1] * (rpm / ref_rpm)^exponent`: unbalance force
/// grows with speed^2, and the path to the sensor adds 0 (a mass-controlled support) to about
/// 2 (a stiff one below its resonance) to the exponent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShaftLinesConfig {
    /// Speed at which the amplitudes hold, rpm.
    pub ref_rpm: f64,
    /// Growth of every line with speed.
    pub exponent: f64,
    /// Amplitude of orders 1, 2, ... at `ref_rpm`, m/s^2.
    pub amplitudes_m_s2: Vec<f64>,
    /// Phase of order 1 relative to the tacho mark, degrees (order k: k times it).
    #[serde(default)]
    pub phase_deg: f64,
}

impl ShaftLinesConfig {
    /// Amplitude of order `k` (1-based) at `rpm`, m/s^2.
    pub fn amplitude(&self, k: usize, rpm: f64) -> f64 {
        let a = self
            .amplitudes_m_s2
            .get(k.wrapping_sub(1))
            .copied()
            .unwrap_or(0.0);
        a * self.speed_gain(rpm)
    }

    /// The speed law every order follows: (rpm / ref_rpm)^exponent.
    pub fn speed_gain(&self, rpm: f64) -> f64 {
        (rpm / self.ref_rpm).max(0.0).powf(self.exponent)
    }
}

/// `[simulation.subharmonics]`: vibration locked to the shaft angle at the half orders 0.5x,
/// 1.5x, 2.5x, ... up to `highest_order` on the radial channels (vertical, horizontal 90 deg
/// behind), as a loose support or a rub that repeats every other revolution gives. The line at
/// order o has amplitude `half_order_m_s2 (2 o)^-slope (rpm / ref_rpm)^exponent`: 0.5x is
/// `half_order_m_s2` at `ref_rpm`, slope 1 makes 1.5x a third of it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubharmonicsConfig {
    /// Speed at which `half_order_m_s2` holds, rpm.
    pub ref_rpm: f64,
    /// Growth of every line with speed.
    pub exponent: f64,
    /// Amplitude of the 0.5x line at `ref_rpm`, m/s^2.
    pub half_order_m_s2: f64,
    /// Decay of the lines over the order (0: all as strong as 0.5x).
    pub slope: f64,
    /// The highest half order: 0.5, 1.5, 2.5, ...
    pub highest_order: f64,
    /// Phase of the 0.5x line relative to the tacho mark, degrees (order o: 2 o times it).
    #[serde(default)]
    pub phase_deg: f64,
}

/// Highest half order `[simulation.subharmonics]` accepts.
pub const MAX_HALF_ORDER: f64 = 50.5;

impl SubharmonicsConfig {
    /// The half orders and their amplitudes at `ref_rpm`, m/s^2, ascending.
    pub fn lines(&self) -> Vec<(f64, f64)> {
        let n = (self.highest_order - 0.5).round().max(0.0) as usize + 1;
        (0..n)
            .map(|j| {
                let o = j as f64 + 0.5;
                (o, self.half_order_m_s2 * (2.0 * o).powf(-self.slope))
            })
            .collect()
    }

    /// The speed law every line follows: (rpm / ref_rpm)^exponent.
    pub fn speed_gain(&self, rpm: f64) -> f64 {
        (rpm / self.ref_rpm).max(0.0).powf(self.exponent)
    }

    /// Checks of the section; messages name the key and what to use.
    fn validate(&self) -> Result<()> {
        let key = "[simulation.subharmonics]";
        if !(self.ref_rpm.is_finite() && self.ref_rpm > 0.0) {
            bail!(
                "{key} ref_rpm = {}: the speed the amplitude holds at, rpm; must be > 0",
                self.ref_rpm
            );
        }
        if !(self.exponent.is_finite() && (0.0..=8.0).contains(&self.exponent)) {
            bail!("{key} exponent = {}: growth of the lines with speed; use 0..8 (2 for a force growing with speed^2)", self.exponent);
        }
        if !(self.half_order_m_s2.is_finite() && self.half_order_m_s2 >= 0.0) {
            bail!(
                "{key} half_order_m_s2 = {}: the 0.5x amplitude in m/s^2; must be zero or positive",
                self.half_order_m_s2
            );
        }
        if !(self.slope.is_finite() && (-4.0..=8.0).contains(&self.slope)) {
            bail!("{key} slope = {}: decay of the lines over the order; use -4..8 (1: 1.5x a third of 0.5x)", self.slope);
        }
        let h = self.highest_order;
        if !(h.is_finite()
            && (0.5..=MAX_HALF_ORDER).contains(&h)
            && ((h - 0.5) - (h - 0.5).round()).abs() < 1e-9)
        {
            bail!("{key} highest_order = {h}: use a half order from 0.5 to {MAX_HALF_ORDER} (0.5, 1.5, 2.5, ...)");
        }
        if !self.phase_deg.is_finite() {
            bail!(
                "{key} phase_deg = {}: must be a number of degrees",
                self.phase_deg
            );
        }
        Ok(())
    }
}

/// `[simulation.loose_impacts]`: a loose housing (or a part of it) that lifts and lands once
/// every two shaft revolutions. Each landing is an impact that rings one structural mode of
/// the loose joint: on the radial channels (vertical, and horizontal at `horizontal_ratio`),
/// `impact_m_s2 (rpm / ref_rpm)^exponent e^(-damping w t) sin(w_d t)` after the landing, w =
/// 2 pi `mode_hz`, w_d = w sqrt(1 - damping^2). The landings come at shaft angle
/// `phase_deg` + 720 k degrees (every other revolution), so the train repeats at 0.5x.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LooseImpactsConfig {
    /// Speed at which `impact_m_s2` holds, rpm.
    pub ref_rpm: f64,
    /// Growth of the impact with speed (2: the landing's speed squared).
    pub exponent: f64,
    /// Peak acceleration of one landing's ring-down at `ref_rpm`, m/s^2.
    pub impact_m_s2: f64,
    /// Frequency of the mode the landings ring, Hz.
    pub mode_hz: f64,
    /// Its damping ratio.
    pub damping: f64,
    /// The horizontal channel's share of the vertical impact.
    #[serde(default = "default_horizontal_ratio")]
    pub horizontal_ratio: f64,
    /// Shaft angle of the first landing relative to the tacho mark, degrees (0-720).
    #[serde(default)]
    pub phase_deg: f64,
    /// Each landing's time slips by this fraction of the landing spacing (standard
    /// deviation): a loose joint does not land the same way twice, and the slip smears the
    /// comb's high lines (0.01 by default, the slip the project's bearing-impact models use).
    #[serde(default = "default_timing_jitter")]
    pub timing_jitter: f64,
}

fn default_horizontal_ratio() -> f64 {
    0.5
}

/// Each landing's slip where the rig file does not say: the 1 % the project's bearing-impact
/// models use for a rolling element's slip.
pub const DEFAULT_TIMING_JITTER: f64 = 0.01;

fn default_timing_jitter() -> f64 {
    DEFAULT_TIMING_JITTER
}

impl LooseImpactsConfig {
    /// The speed law of the impacts: (rpm / ref_rpm)^exponent.
    pub fn speed_gain(&self, rpm: f64) -> f64 {
        (rpm / self.ref_rpm).max(0.0).powf(self.exponent)
    }

    /// Checks of the section; messages name the key and what to use.
    fn validate(&self) -> Result<()> {
        let key = "[simulation.loose_impacts]";
        let ok = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        if !(self.ref_rpm.is_finite() && self.ref_rpm > 0.0) {
            bail!(
                "{key} ref_rpm = {}: the speed the impact holds at, rpm; must be > 0",
                self.ref_rpm
            );
        }
        if !ok(self.exponent, 0.0, 8.0) {
            bail!(
                "{key} exponent = {}: growth of the impacts with speed; use 0..8 (2 for speed^2)",
                self.exponent
            );
        }
        if !ok(self.impact_m_s2, 0.0, 1e4) {
            bail!(
                "{key} impact_m_s2 = {}: the peak of one landing in m/s^2; use 0..10000",
                self.impact_m_s2
            );
        }
        if !(self.mode_hz.is_finite() && self.mode_hz > 0.0) {
            bail!(
                "{key} mode_hz = {}: the frequency of the mode the landings ring, Hz; must be > 0",
                self.mode_hz
            );
        }
        if !ok(self.damping, 1e-4, 0.5) {
            bail!("{key} damping = {}: the mode's damping ratio; use 0.0001..0.5 (0.02-0.1 is typical)", self.damping);
        }
        if !ok(self.timing_jitter, 0.0, 0.2) {
            bail!(
                "{key} timing_jitter = {}: each landing's slip as a fraction of the landing \
                 spacing; use 0..0.2 (0.01 by default)",
                self.timing_jitter
            );
        }
        if !ok(self.horizontal_ratio, 0.0, 10.0) {
            bail!(
                "{key} horizontal_ratio = {}: the horizontal channel's share; use 0..10",
                self.horizontal_ratio
            );
        }
        if !ok(self.phase_deg, -720.0, 720.0) {
            bail!(
                "{key} phase_deg = {}: use -720..720 degrees",
                self.phase_deg
            );
        }
        Ok(())
    }
}

/// `[simulation.speed_fluctuation]`: rpm(t) = rpm (1 + fraction sin(2 pi t / period_s)),
/// applied to constant-speed scenarios.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedFluctuationConfig {
    /// Peak speed deviation as a fraction of the mean speed.
    pub fraction: f64,
    /// Period of the fluctuation, s.
    pub period_s: f64,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        SimulationConfig {
            sample_rate_hz: None,
            oversampling: 10,
            warmup_s: 0.3,
            gravity_m_s2: 9.81,
            rotor: RotorConfig::default(),
            housing: HousingConfig::default(),
            bearing: BallBearingConfig::default(),
            defect: DefectConfig::default(),
            structure: StructureConfig::default(),
            tacho: TachoConfig::default(),
            channel_map: BTreeMap::new(),
            speed_fluctuation: None,
            shaft_lines: None,
            subharmonics: None,
            loose_impacts: None,
        }
    }
}

/// A rigid disc on the shaft.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscConfig {
    /// Distance from the drive end of the shaft, mm.
    pub position_mm: f64,
    pub mass_kg: f64,
    pub diameter_mm: f64,
    pub thickness_mm: f64,
    /// Residual unbalance (mass x eccentricity), g mm. 0 switches the 1x excitation off.
    #[serde(default)]
    pub unbalance_g_mm: f64,
    /// Angle of the unbalance relative to the tacho mark, degrees.
    #[serde(default)]
    pub unbalance_phase_deg: f64,
}

/// Flexible shaft (Euler-Bernoulli beam elements, Guyan-reduced onto the bearing and disc
/// nodes), drive-end coupling and drive-end bushing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RotorConfig {
    pub shaft_length_mm: f64,
    pub shaft_diameter_mm: f64,
    pub youngs_modulus_gpa: f64,
    pub density_kg_m3: f64,
    /// Beam elements before reduction.
    pub elements: u32,
    /// Axial position of the drive-end (linear bushing) bearing, mm from the drive end.
    pub de_bearing_mm: f64,
    /// Axial position of the non-drive-end (test) ball bearing, mm from the drive end.
    pub nde_bearing_mm: f64,
    pub discs: Vec<DiscConfig>,
    /// Flexible coupling to the motor at the drive end: lateral stiffness, N/m.
    pub coupling_stiffness_n_per_m: f64,
    /// Flexible coupling: bending (tilt) stiffness, N m/rad.
    pub coupling_tilt_stiffness_nm_per_rad: f64,
    /// Modal damping ratio of the shaft (stiffness-proportional, set at the first mode).
    pub shaft_damping_ratio: f64,
    /// Mass lumped at each bearing node (sleeve + inner ring), kg.
    pub journal_mass_kg: f64,
    /// Drive-end bearing as a linear bushing (Paper A: 2e4 N/mm, 20 Ns/mm).
    pub de_bushing_stiffness_n_per_mm: f64,
    pub de_bushing_damping_ns_per_mm: f64,
}

impl Default for RotorConfig {
    fn default() -> Self {
        RotorConfig {
            shaft_length_mm: 600.0,
            shaft_diameter_mm: 12.0,
            youngs_modulus_gpa: 210.0,
            density_kg_m3: 7850.0,
            elements: 24,
            de_bearing_mm: 30.0,
            nde_bearing_mm: 570.0,
            discs: vec![
                DiscConfig {
                    position_mm: 222.5,
                    mass_kg: 1.69,
                    diameter_mm: 150.0,
                    thickness_mm: 10.0,
                    unbalance_g_mm: 20.0,
                    unbalance_phase_deg: 0.0,
                },
                DiscConfig {
                    position_mm: 420.0,
                    mass_kg: 1.69,
                    diameter_mm: 150.0,
                    thickness_mm: 10.0,
                    unbalance_g_mm: 20.0,
                    unbalance_phase_deg: 120.0,
                },
            ],
            coupling_stiffness_n_per_m: 5.0e5,
            coupling_tilt_stiffness_nm_per_rad: 1.0e4,
            shaft_damping_ratio: 0.01,
            journal_mass_kg: 0.2,
            de_bushing_stiffness_n_per_mm: 2.0e4,
            de_bushing_damping_ns_per_mm: 20.0,
        }
    }
}

/// Both bearing housings: rigid masses on springs to the platform. The defaults place the
/// first vertical / lateral shaft bending modes at the measured 31.25 / 33.75 Hz (Table 3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HousingConfig {
    pub mass_kg: f64,
    pub vertical_stiffness_n_per_m: f64,
    pub horizontal_stiffness_n_per_m: f64,
    pub axial_stiffness_n_per_m: f64,
    /// Damping ratio of each housing on its springs.
    pub damping_ratio: f64,
}

impl Default for HousingConfig {
    fn default() -> Self {
        HousingConfig {
            mass_kg: 1.5,
            vertical_stiffness_n_per_m: 4.2e5,
            horizontal_stiffness_n_per_m: 9.0e6,
            axial_stiffness_n_per_m: 1.0e7,
            damping_ratio: 0.02,
        }
    }
}

/// The nonlinear test ball bearing (geometry from the rig's `[bearing]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BallBearingConfig {
    /// Hertz load-deflection constant k_total in F = k delta^e (Table 4: 2.953e5 N/mm^1.5).
    pub contact_stiffness_n_per_mm15: f64,
    pub contact_exponent: f64,
    /// Maximum contact damping c_max (Table 4: 295.3 Ns/mm), reached at `penetration_mm`.
    pub contact_damping_ns_per_mm: f64,
    /// Penetration over which the damping ramps up (Adams STEP, Table 4: 0.01 mm).
    pub penetration_mm: f64,
    /// Radial internal clearance (diametral), mm (Table 1: 0.03 mm).
    pub radial_clearance_mm: f64,
    /// Contact angle used by the simulator (cage speed, force direction); default: the rig's
    /// `[bearing].contact_angle_deg`. The thesis MBD had 28.3-28.9 deg from preload.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_angle_deg: Option<f64>,
    /// Axial preload, N (takes up the clearance when > 0 and the contact angle is > 0).
    pub preload_n: f64,
    /// Mean cage speed loss (fraction, 0.01 = 1 %): shifts every fault order down.
    pub slip: f64,
    /// Random ball-position jitter (fraction of the ball spacing, 1-2 % typical): smears
    /// fault harmonics like real rolling-element slip.
    pub slip_jitter: f64,
    /// Extra static radial load on the test bearing (e.g. belt, misalignment), N, downwards.
    pub radial_load_n: f64,
}

impl Default for BallBearingConfig {
    fn default() -> Self {
        BallBearingConfig {
            contact_stiffness_n_per_mm15: 2.953e5,
            contact_exponent: 1.5,
            contact_damping_ns_per_mm: 295.3,
            penetration_mm: 0.01,
            radial_clearance_mm: 0.03,
            contact_angle_deg: None,
            preload_n: 0.0,
            slip: 0.0,
            slip_jitter: 0.015,
            radial_load_n: 60.0,
        }
    }
}

/// Shape of the ball path through a localized defect (thesis Fig. 11 / eq. 9-10).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DefectShape {
    /// The ball rolls over the edges: drop limited by the ball's chord at each position
    /// (smooth entry, deepest at mid-slot, sharp-ish exit), capped by depth.
    Geometric,
    /// Linear drop over the first half of the slot and rise over the second (eq. 9-10,
    /// alpha_2 = alpha_1 / 2).
    Linear,
    /// Flat-bottomed step of the full drop (two sharp impacts per pass).
    Step,
}

/// Localized defects: size, shape and where they sit. Which defects are present is the
/// scenario's fault list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DefectConfig {
    /// Extent along the rolling direction, mm (the thesis' 0.5 mm "width" / L_defect).
    pub width_mm: f64,
    /// Extent across the raceway, mm (2 mm on the rig).
    pub length_mm: f64,
    /// Depth, mm (0.2 mm on the rig; the ball usually cannot reach the bottom).
    pub depth_mm: f64,
    pub shape: DefectShape,
    /// Outer-race defect position, degrees from the bottom of the bearing (0 = 6 o'clock,
    /// centre of the gravity load zone; 90 = 3 o'clock seen from the drive end).
    pub outer_race_position_deg: f64,
    /// Inner-race defect angle relative to the tacho mark, degrees.
    pub inner_race_position_deg: f64,
    /// Width of the contact patch across the raceway, mm: shorter defects drop the ball
    /// proportionally less.
    pub contact_patch_mm: f64,
}

impl Default for DefectConfig {
    fn default() -> Self {
        DefectConfig {
            width_mm: 0.5,
            length_mm: 2.0,
            depth_mm: 0.2,
            shape: DefectShape::Geometric,
            outer_race_position_deg: 0.0,
            inner_race_position_deg: 0.0,
            contact_patch_mm: 1.0,
        }
    }
}

/// One housing/sensor resonance of the high-frequency structural path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResonanceConfig {
    pub hz: f64,
    /// Damping ratio (0.03 = 3 %).
    pub damping: f64,
    /// Modal mass, kg: smaller rings louder.
    #[serde(default = "default_modal_mass")]
    pub modal_mass_kg: f64,
    /// Participation of the mode in each axis (drive and sensing), dimensionless.
    #[serde(default)]
    pub axial: f64,
    #[serde(default)]
    pub vertical: f64,
    #[serde(default)]
    pub horizontal: f64,
}

fn default_modal_mass() -> f64 {
    3.0
}

/// High-frequency structural path (housing and sensor resonances driven by the bearing
/// forces) and sensor noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StructureConfig {
    pub resonances: Vec<ResonanceConfig>,
    /// White sensor noise, RMS in m/s^2 per channel (up to Nyquist).
    pub noise_rms_m_s2: f64,
    /// DAQ resolution (quantisation step) in m/s^2, rounded to a power of two; 0 = none.
    pub adc_resolution_m_s2: f64,
    /// Electrical line frequency for interference pick-up, Hz (not locked to shaft speed).
    pub line_hz: f64,
    /// Interference amplitude (m/s^2) at 1x, 2x, ... the line frequency; empty = off.
    pub line_amplitudes_m_s2: Vec<f64>,
}

impl Default for StructureConfig {
    fn default() -> Self {
        StructureConfig {
            resonances: vec![
                ResonanceConfig {
                    hz: 2900.0,
                    damping: 0.03,
                    modal_mass_kg: 3.0,
                    axial: 0.3,
                    vertical: 1.0,
                    horizontal: 0.5,
                },
                ResonanceConfig {
                    hz: 3700.0,
                    damping: 0.04,
                    modal_mass_kg: 5.0,
                    axial: 0.6,
                    vertical: 0.5,
                    horizontal: 1.0,
                },
            ],
            noise_rms_m_s2: 0.3,
            adc_resolution_m_s2: 0.0,
            line_hz: 50.0,
            line_amplitudes_m_s2: Vec::new(),
        }
    }
}

/// The analog tacho: one pulse of `high_v` per `pulses_per_rev` (from `[speed]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TachoConfig {
    pub high_v: f64,
    /// Fraction of each pulse period spent high.
    pub duty: f64,
    /// Voltage noise, V RMS.
    pub noise_v: f64,
}

impl Default for TachoConfig {
    fn default() -> Self {
        TachoConfig {
            high_v: 5.0,
            duty: 0.1,
            noise_v: 0.01,
        }
    }
}

/// The signals the simulator can produce for a channel.
pub const SIGNALS: [&str; 5] = [
    "axial",
    "vertical",
    "horizontal",
    "support_vertical",
    "support_horizontal",
];

impl SimulationConfig {
    /// The section with the sensor-stage keys (noise, quantisation, electrical, shaft-order
    /// and half-order lines, tacho) at their defaults: what the mechanical simulation
    /// depends on (see `sim::EngineRun`).
    pub fn engine_part(&self) -> SimulationConfig {
        let d = SimulationConfig::default();
        let mut s = self.clone();
        s.structure.noise_rms_m_s2 = d.structure.noise_rms_m_s2;
        s.structure.adc_resolution_m_s2 = d.structure.adc_resolution_m_s2;
        s.structure.line_hz = d.structure.line_hz;
        s.structure.line_amplitudes_m_s2 = d.structure.line_amplitudes_m_s2;
        s.shaft_lines = None;
        s.subharmonics = None;
        s.loose_impacts = None;
        s.tacho = d.tacho;
        s
    }

    /// The sensor-stage sections locked to the shaft: shaft lines, half-order lines and a
    /// loose housing's landings.
    fn validate_lines(&self) -> Result<()> {
        if let Some(l) = &self.shaft_lines {
            if !(l.ref_rpm.is_finite() && l.ref_rpm > 0.0)
                || !(l.exponent.is_finite() && (0.0..=8.0).contains(&l.exponent))
                || l.amplitudes_m_s2
                    .iter()
                    .any(|a| !(a.is_finite() && *a >= 0.0))
                || !l.phase_deg.is_finite()
            {
                bail!("[simulation.shaft_lines]: ref_rpm must be > 0, exponent in [0, 8] and amplitudes_m_s2 >= 0 (got {}, {} and {:?})", l.ref_rpm, l.exponent, l.amplitudes_m_s2);
            }
        }
        if let Some(h) = &self.subharmonics {
            h.validate()?;
        }
        if let Some(l) = &self.loose_impacts {
            l.validate()?;
        }
        Ok(())
    }

    /// Physical sanity checks; messages name the key and what to do.
    pub fn validate(&self) -> Result<()> {
        if let Some(f) = &self.speed_fluctuation {
            if !(f.fraction >= 0.0 && f.fraction < 0.5 && f.period_s > 0.0) {
                bail!("[simulation.speed_fluctuation]: fraction must be in [0, 0.5) and period_s > 0 (got {} and {})", f.fraction, f.period_s);
            }
        }
        self.validate_lines()?;
        let pos = |name: &str, v: f64| -> Result<()> {
            if !(v.is_finite() && v > 0.0) {
                bail!("simulation.{name} = {v}: must be a positive number");
            }
            Ok(())
        };
        let nonneg = |name: &str, v: f64| -> Result<()> {
            if !(v.is_finite() && v >= 0.0) {
                bail!("simulation.{name} = {v}: must be zero or positive");
            }
            Ok(())
        };
        if let Some(fs) = self.sample_rate_hz {
            pos("sample_rate_hz", fs)?;
        }
        if !(2..=100).contains(&self.oversampling) {
            bail!("simulation.oversampling = {}: use 2..100 internal steps per output sample (10 is typical)", self.oversampling);
        }
        nonneg("warmup_s", self.warmup_s)?;
        nonneg("gravity_m_s2", self.gravity_m_s2)?;
        let r = &self.rotor;
        pos("rotor.shaft_length_mm", r.shaft_length_mm)?;
        pos("rotor.shaft_diameter_mm", r.shaft_diameter_mm)?;
        pos("rotor.youngs_modulus_gpa", r.youngs_modulus_gpa)?;
        pos("rotor.density_kg_m3", r.density_kg_m3)?;
        if r.elements < 4 {
            bail!(
                "simulation.rotor.elements = {}: use at least 4 beam elements",
                r.elements
            );
        }
        let inside = |name: &str, x: f64| -> Result<()> {
            if !(x >= 0.0 && x <= r.shaft_length_mm) {
                bail!(
                    "simulation.rotor.{name} = {x} mm lies outside the shaft (0..{} mm)",
                    r.shaft_length_mm
                );
            }
            Ok(())
        };
        inside("de_bearing_mm", r.de_bearing_mm)?;
        inside("nde_bearing_mm", r.nde_bearing_mm)?;
        if (r.de_bearing_mm - r.nde_bearing_mm).abs() < 1.0 {
            bail!(
                "simulation.rotor: de_bearing_mm and nde_bearing_mm must be at different positions"
            );
        }
        for (i, d) in r.discs.iter().enumerate() {
            inside(&format!("discs[{i}].position_mm"), d.position_mm)?;
            pos(&format!("rotor.discs[{i}].mass_kg"), d.mass_kg)?;
            nonneg(
                &format!("rotor.discs[{i}].unbalance_g_mm"),
                d.unbalance_g_mm,
            )?;
        }
        nonneg(
            "rotor.coupling_stiffness_n_per_m",
            r.coupling_stiffness_n_per_m,
        )?;
        nonneg(
            "rotor.coupling_tilt_stiffness_nm_per_rad",
            r.coupling_tilt_stiffness_nm_per_rad,
        )?;
        nonneg("rotor.shaft_damping_ratio", r.shaft_damping_ratio)?;
        pos("rotor.journal_mass_kg", r.journal_mass_kg)?;
        pos(
            "rotor.de_bushing_stiffness_n_per_mm",
            r.de_bushing_stiffness_n_per_mm,
        )?;
        nonneg(
            "rotor.de_bushing_damping_ns_per_mm",
            r.de_bushing_damping_ns_per_mm,
        )?;
        let h = &self.housing;
        pos("housing.mass_kg", h.mass_kg)?;
        pos(
            "housing.vertical_stiffness_n_per_m",
            h.vertical_stiffness_n_per_m,
        )?;
        pos(
            "housing.horizontal_stiffness_n_per_m",
            h.horizontal_stiffness_n_per_m,
        )?;
        pos("housing.axial_stiffness_n_per_m", h.axial_stiffness_n_per_m)?;
        nonneg("housing.damping_ratio", h.damping_ratio)?;
        let b = &self.bearing;
        pos(
            "bearing.contact_stiffness_n_per_mm15",
            b.contact_stiffness_n_per_mm15,
        )?;
        if !(1.0..=2.0).contains(&b.contact_exponent) {
            bail!(
                "simulation.bearing.contact_exponent = {}: use 1.0..2.0 (1.5 for ball bearings)",
                b.contact_exponent
            );
        }
        nonneg(
            "bearing.contact_damping_ns_per_mm",
            b.contact_damping_ns_per_mm,
        )?;
        pos("bearing.penetration_mm", b.penetration_mm)?;
        nonneg("bearing.radial_clearance_mm", b.radial_clearance_mm)?;
        if let Some(a) = b.contact_angle_deg {
            if !(0.0..60.0).contains(&a) {
                bail!("simulation.bearing.contact_angle_deg = {a}: use 0..60 degrees");
            }
        }
        nonneg("bearing.preload_n", b.preload_n)?;
        if !(0.0..0.2).contains(&b.slip) {
            bail!(
                "simulation.bearing.slip = {}: a fraction in 0..0.2 (0.01 = 1 %)",
                b.slip
            );
        }
        if !(0.0..0.2).contains(&b.slip_jitter) {
            bail!(
                "simulation.bearing.slip_jitter = {}: a fraction in 0..0.2 (0.015 = 1.5 %)",
                b.slip_jitter
            );
        }
        nonneg("bearing.radial_load_n", b.radial_load_n)?;
        let d = &self.defect;
        pos("defect.width_mm", d.width_mm)?;
        pos("defect.length_mm", d.length_mm)?;
        pos("defect.depth_mm", d.depth_mm)?;
        pos("defect.contact_patch_mm", d.contact_patch_mm)?;
        for (i, m) in self.structure.resonances.iter().enumerate() {
            pos(&format!("structure.resonances[{i}].hz"), m.hz)?;
            pos(&format!("structure.resonances[{i}].damping"), m.damping)?;
            pos(
                &format!("structure.resonances[{i}].modal_mass_kg"),
                m.modal_mass_kg,
            )?;
        }
        nonneg("structure.noise_rms_m_s2", self.structure.noise_rms_m_s2)?;
        nonneg(
            "structure.adc_resolution_m_s2",
            self.structure.adc_resolution_m_s2,
        )?;
        pos("tacho.high_v", self.tacho.high_v)?;
        if !(self.tacho.duty > 0.0 && self.tacho.duty < 1.0) {
            bail!(
                "simulation.tacho.duty = {}: a fraction in (0, 1)",
                self.tacho.duty
            );
        }
        nonneg("tacho.noise_v", self.tacho.noise_v)?;
        for (ch, sig) in &self.channel_map {
            if !SIGNALS.contains(&sig.as_str()) {
                bail!("simulation.channel_map.{ch} = {sig:?}: not a simulated signal; use one of {SIGNALS:?}");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_section_is_the_thesis_rig() {
        let c: SimulationConfig = toml::from_str("").unwrap();
        assert_eq!(c, SimulationConfig::default());
        assert_eq!(c.rotor.discs.len(), 2);
        assert_eq!(c.bearing.contact_stiffness_n_per_mm15, 2.953e5);
        c.validate().unwrap();
    }

    #[test]
    fn unknown_key_is_rejected_by_name() {
        let err = toml::from_str::<SimulationConfig>("[bearing]\nslipp = 0.01\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("slipp"), "{err}");
    }

    #[test]
    fn bad_values_are_named() {
        let mut c = SimulationConfig::default();
        c.bearing.slip = 0.5;
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("simulation.bearing.slip"));
        let mut c = SimulationConfig::default();
        c.channel_map.insert("DE".into(), "vertcal".into());
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("channel_map.DE"));
    }

    /// `[simulation.subharmonics]`: unknown keys are refused by name, bad values name the key
    /// and what to use, and the lines follow the documented law.
    #[test]
    fn subharmonics_are_checked_and_follow_their_law() {
        let text = "[subharmonics]\nref_rpm = 1200.0\nexponent = 2.0\nhalf_order_m_s2 = 0.3\nslope = 1.0\nhighest_order = 2.5\n";
        let c: SimulationConfig = toml::from_str(text).unwrap();
        c.validate().unwrap();
        let h = c.subharmonics.as_ref().unwrap();
        let lines = h.lines();
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert_eq!(lines[0], (0.5, 0.3));
        assert!(
            (lines[1].1 - 0.1).abs() < 1e-12 && lines[2].0 == 2.5,
            "{lines:?}"
        );
        assert!((h.speed_gain(600.0) - 0.25).abs() < 1e-12);
        assert_eq!(c.engine_part().subharmonics, None);
        let err = toml::from_str::<SimulationConfig>(&text.replace("slope", "slop"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("slop"), "{err}");
        for (bad, key) in [
            ("highest_order = 2.0", "highest_order"),
            ("highest_order = 0.0", "highest_order"),
            ("slope = 20.0", "slope"),
            ("exponent = -1.0", "exponent"),
        ] {
            let k = bad.split(' ').next().unwrap();
            let line = text.lines().find(|l| l.starts_with(k)).unwrap();
            let c: SimulationConfig = toml::from_str(&text.replace(line, bad)).unwrap();
            let err = c.validate().unwrap_err().to_string();
            assert!(
                err.contains("[simulation.subharmonics]") && err.contains(key),
                "{bad}: {err}"
            );
        }
    }

    /// `[simulation.loose_impacts]`: bad values name the key and what to use, the speed law
    /// holds, and the engine part leaves the landings (a sensor-stage signal) out.
    #[test]
    fn loose_impacts_are_checked() {
        let text = "[loose_impacts]\nref_rpm = 1200.0\nexponent = 2.0\nimpact_m_s2 = 3.0\nmode_hz = 900.0\ndamping = 0.04\n";
        let c: SimulationConfig = toml::from_str(text).unwrap();
        c.validate().unwrap();
        let l = c.loose_impacts.as_ref().unwrap();
        assert_eq!(l.horizontal_ratio, 0.5);
        assert!((l.speed_gain(600.0) - 0.25).abs() < 1e-12);
        assert_eq!(c.engine_part().loose_impacts, None);
        for (bad, key) in [
            ("damping = 0.9", "damping"),
            ("mode_hz = -1.0", "mode_hz"),
            ("impact_m_s2 = -2.0", "impact_m_s2"),
            ("exponent = 9.0", "exponent"),
        ] {
            let k = bad.split(' ').next().unwrap();
            let line = text.lines().find(|l| l.starts_with(k)).unwrap();
            let c: SimulationConfig = toml::from_str(&text.replace(line, bad)).unwrap();
            let err = c.validate().unwrap_err().to_string();
            assert!(
                err.contains("[simulation.loose_impacts]") && err.contains(key),
                "{bad}: {err}"
            );
        }
    }
}
