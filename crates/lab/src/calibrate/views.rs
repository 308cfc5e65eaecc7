//! The residual views of one recording, each physically meaningful and independent of the
//! overall signal level (every view is relative to the recording's own floor):
//! - `env`: normalised envelope order spectrum of the classifier channel (dB above its median,
//!   6 dB threshold), orders 0.3-[`ENV_MAX_ORDER`] on a [`ENV_STEP`] grid: fault-order peak
//!   locations, harmonic and sideband ratios;
//! - `lines`: raw spectrum in Hz (Welch, 1 Hz bins, 2-[`LINES_MAX_HZ`] Hz), dB above the local
//!   median (+-25 Hz), 6 dB threshold: narrowband content, order-locked or not (1x/2x,
//!   electrical lines);
//! - `bands`: energy in 100 Hz bands from 300 Hz to 0.4 fs, dB within [`BAND_RANGE_DB`] of
//!   the strongest band (0 below): where the structural resonances put the impact energy;
//! - `speed`: amplitude spectrum (0.1-5 Hz) of the relative shaft-speed deviation in percent,
//!   from the speed source: speed fluctuation;
//! - `fault_peaks`: the located fault orders of the recording's labelled faults, with their
//!   harmonic and sideband ratios ([`super::fault_peaks`]);
//! - `shaft`: the shaft-order lines 1x-30x and their floors ([`super::shaft_orders`]);
//! - `mode`: the dominant structural resonance ([`super::modes`]);
//! - `floor_db`: the absolute broadband floor (sensor noise);
//! - `fractional`: sub-synchronous and fractional shaft orders of the raw signal
//!   ([`super::fractional_orders`]), every recording, with the half-order lines 0.5x-3.5x
//!   (`half_orders`, [`super::half_orders`]);
//! - `impacts`: the envelope spectrum in Hz of the broadband band energy
//!   ([`super::impacts`]), every recording;
//! - `landings`: impacts once every two revolutions, read in the band where they ring
//!   ([`super::landing_comb`]), every recording; located and drawn, not part of the error.
//!
//! A recording longer than [`SEGMENT_S`] is analysed whole: every view but `speed` is
//! computed on each [`SEGMENT_S`] segment and averaged over the segments (the expected value
//! of one segment's view, with the variance of all of them), so a simulated twin of one
//! segment is compared like with like; `speed` is computed once over the whole recording, so
//! slow fluctuations (periods up to half the recording) are resolved.

use super::fault_peaks::{self, DbSpectrum, FaultPeak};
use super::half_orders::HalfOrders;
use super::landing_comb::{self, LandingComb};
use super::modes::{self, Mode};
use super::shaft_orders::{self, ShaftOrders};
use super::stats::{median, quantile};
use super::{fractional_orders, impacts};
use crate::config::RigConfig;
use crate::dsp::order_spectrum::whole_recording;
use crate::dsp::speed::SpeedTrack;
use crate::recording::Recording;
use crate::vocabulary::Condition;
use crate::vocabulary::ErrorComponent;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use realfft::RealFftPlanner;

pub const ENV_MAX_ORDER: f64 = 12.0;
pub const ENV_MIN_ORDER: f64 = 0.3;
pub const ENV_STEP: f64 = 0.02;
pub const LINES_MIN_HZ: usize = 2;
pub const LINES_MAX_HZ: usize = 1000;
pub const BAND_HZ: f64 = 100.0;
pub const BAND_MIN_HZ: f64 = 300.0;
/// Lowest sample rate the views are defined for: raw lines to [`LINES_MAX_HZ`], bands from
/// [`BAND_MIN_HZ`] to 0.4 fs.
pub const MIN_SAMPLE_RATE_HZ: f64 = 2.0 * LINES_MAX_HZ as f64;
pub const SPEED_MIN_HZ: f64 = 0.1;
pub const SPEED_MAX_HZ: f64 = 5.0;
/// Grid step of the speed view times the analysed length: 0.05 Hz over 2 s, 0.005 Hz over
/// 20 s, so a line spans the same number of grid points (and the `speed` component the same
/// size) whatever the length.
pub const SPEED_STEP_TIMES_S: f64 = 0.1;
/// Length of the segments a recording's views are averaged over, and of a simulated twin.
pub const SEGMENT_S: f64 = 2.0;
const THRESHOLD_DB: f64 = 6.0;
/// Bands more than this below the strongest band count as 0.
pub const BAND_RANGE_DB: f64 = 20.0;
const CAP_DB: f64 = 60.0;
/// Quantile of the spectrum taken as the broadband (sensor noise) floor.
pub const FLOOR_QUANTILE: f64 = 0.1;

/// All views of one recording.
#[derive(Debug, Clone, Default)]
pub struct Views {
    /// Mean shaft speed, rpm.
    pub rpm: f64,
    pub env: Vec<f64>,
    pub lines: Vec<f64>,
    pub bands: Vec<f64>,
    /// Lower edge of each band, Hz.
    pub band_lo_hz: Vec<f64>,
    pub speed: Vec<f64>,
    /// Envelope order spectrum in dB above its median (unthresholded), on the `env` grid.
    pub env_db: Vec<f64>,
    /// The recording is labelled healthy (`lines` is compared on healthy recordings only,
    /// see [`super::error`]).
    pub healthy: bool,
    /// Located fault orders of the labelled faults (those with a visible comb).
    pub fault_peaks: Vec<FaultPeak>,
    pub shaft: ShaftOrders,
    pub mode: Mode,
    /// The broadband floor: the [`FLOOR_QUANTILE`] quantile of the Welch amplitude spectrum
    /// from 300 Hz to 0.4 fs (the quietest part, where no resonance rings), dB re 1 channel
    /// unit (absolute: the other spectral views are relative to their floors).
    pub floor_db: f64,
    /// Sub-synchronous and fractional shaft orders, thresholded dB
    /// ([`fractional_orders::orders`]).
    pub fractional: Vec<f64>,
    /// The half-order lines (0.5x-3.5x) of the fractional view: amplitudes and floors
    /// ([`super::half_orders`]).
    pub half_orders: HalfOrders,
    /// Envelope spectrum of the broadband energy in Hz, thresholded dB
    /// ([`impacts::frequencies`]).
    pub impacts: Vec<f64>,
    /// The half-order comb of impacts in the band where they ring ([`landing_comb`]).
    pub landings: LandingComb,
    /// Seconds of signal analysed.
    pub seconds: f64,
    /// Segments averaged.
    pub segments: usize,
}

/// Order of `env[i]`.
pub fn env_order(i: usize) -> f64 {
    ENV_MIN_ORDER + i as f64 * ENV_STEP
}

/// Number of [`SEGMENT_S`] segments a recording of `seconds` is analysed in (at least 1;
/// a remainder shorter than a segment is left out of the segment views, so every segment
/// view has the statistics of a twin's).
pub fn segments(seconds: f64) -> usize {
    ((seconds + 1e-9) / SEGMENT_S).floor().max(1.0) as usize
}

/// Length of one analysed segment of a recording of `seconds`.
pub fn segment_seconds(seconds: f64) -> f64 {
    seconds.min(SEGMENT_S)
}

/// Length of a recording's simulated twin: one analysed segment; for a series of captures,
/// its shortest capture (each capture is a segment of its own, [`compute`]).
pub fn twin_seconds(rec: &Recording) -> f64 {
    match crate::recording::captures::spans(rec) {
        Ok(s) if crate::recording::captures::is_capture_series(&rec.metadata) => s
            .iter()
            .map(|s| (s.end - s.start) as f64 / rec.sample_rate)
            .fold(f64::INFINITY, f64::min)
            .min(SEGMENT_S),
        _ => segment_seconds(rec.duration_s()),
    }
}

/// The views of a series of captures: each capture's (one segment each), averaged. No
/// `speed` view: captures a few revolutions long, seconds apart, say nothing of how the speed
/// fluctuates (the error then leaves that component out).
fn compute_captures(
    captures: Vec<Recording>,
    rig: &RigConfig,
    faults: &[Condition],
) -> Result<Views> {
    let seconds: f64 = captures.iter().map(|c| c.duration_s()).sum();
    let parts = captures
        .into_par_iter()
        .enumerate()
        .map(|(i, r)| {
            compute_segment(&r, rig, faults)
                .with_context(|| format!("capture {} ({:.2} s)", i + 1, r.duration_s()))
        })
        .collect::<Result<Vec<_>>>()?;
    let n = parts.len() as f64;
    let rpm = parts.iter().map(|p| p.rpm).sum::<f64>() / n;
    let mut v = average(parts);
    v.rpm = rpm;
    v.speed = Vec::new();
    v.seconds = seconds;
    Ok(v)
}

/// Compute the views of a recording's classifier channel; `faults` is its label. A recording
/// longer than a segment is averaged over [`segments`]; `speed` covers it whole.
pub fn compute(rec: &Recording, rig: &RigConfig, faults: &[Condition]) -> Result<Views> {
    if let Some(captures) = crate::recording::captures::pieces(rec) {
        return compute_captures(captures, rig, faults);
    }
    let track = crate::analysis::whole_recording(rec, rig)?;
    let dur = rec.duration_s();
    let k = segments(dur);
    let seg = segment_seconds(dur);
    let parts = (0..k)
        .into_par_iter()
        .map(|i| {
            let mut r = rec.clone();
            super::measured::cut(&mut r, i as f64 * seg, seg);
            // A speed read from the vibration is not read again from a segment (it may be
            // shorter than the tracker's history); a tacho or a stored speed is the segment's.
            let views = if rec.tacho.is_none() && rec.rpm.is_none() {
                segment_track(&track, i as f64 * seg, seg)
                    .and_then(|t| compute_parts_along(&r, rig, faults, Parts::ALL, Some(&t)))
            } else {
                compute_segment(&r, rig, faults)
            };
            views.with_context(|| {
                format!(
                    "segment {} ({:.1} s from {:.1} s)",
                    i + 1,
                    seg,
                    i as f64 * seg
                )
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let mut v = average(parts);
    v.rpm = track.mean_rpm(0.0, dur);
    v.speed = speed_view(&track, dur, v.rpm);
    v.seconds = dur;
    Ok(v)
}

fn mean_vec(parts: &[Views], f: impl Fn(&Views) -> &Vec<f64>) -> Vec<f64> {
    let n = parts.len() as f64;
    let mut out = f(&parts[0]).clone();
    for p in &parts[1..] {
        for (o, v) in out.iter_mut().zip(f(p)) {
            *o += v;
        }
    }
    out.iter_mut().for_each(|o| *o /= n);
    out
}

/// The mean of segment views (one segment: itself). A fault family counts when located in
/// at least half the segments (its order, height and ratios averaged over those); the mode
/// is prominent when it is in most segments, at the median of their locations.
fn average(parts: Vec<Views>) -> Views {
    if parts.len() == 1 {
        let mut v = parts.into_iter().next().expect("one part");
        v.segments = 1;
        return v;
    }
    let n = parts.len();
    let mut v = parts[0].clone();
    v.env = mean_vec(&parts, |p| &p.env);
    v.lines = mean_vec(&parts, |p| &p.lines);
    v.bands = mean_vec(&parts, |p| &p.bands);
    v.env_db = mean_vec(&parts, |p| &p.env_db);
    v.fractional = mean_vec(&parts, |p| &p.fractional);
    v.half_orders.amplitude = mean_vec(&parts, |p| &p.half_orders.amplitude);
    v.half_orders.floor = mean_vec(&parts, |p| &p.half_orders.floor);
    v.impacts = mean_vec(&parts, |p| &p.impacts);
    v.landings = LandingComb::mean(&parts.iter().map(|p| &p.landings).collect::<Vec<_>>());
    v.shaft.amplitude = mean_vec(&parts, |p| &p.shaft.amplitude);
    v.shaft.floor = mean_vec(&parts, |p| &p.shaft.floor);
    v.floor_db = parts.iter().map(|p| p.floor_db).sum::<f64>() / n as f64;
    let mut families: Vec<&'static str> = parts
        .iter()
        .flat_map(|p| p.fault_peaks.iter().map(|f| f.family))
        .collect();
    families.sort_unstable();
    families.dedup();
    v.fault_peaks = families
        .into_iter()
        .filter_map(|fam| {
            let found: Vec<&FaultPeak> = parts
                .iter()
                .filter_map(|p| p.fault_peaks.iter().find(|f| f.family == fam))
                .collect();
            if 2 * found.len() < n {
                return None;
            }
            let m = found.len() as f64;
            let opt_mean = |g: &dyn Fn(&FaultPeak) -> Option<f64>| {
                let s: Vec<f64> = found.iter().filter_map(|f| g(f)).collect();
                (!s.is_empty()).then(|| s.iter().sum::<f64>() / s.len() as f64)
            };
            Some(FaultPeak {
                family: fam,
                nominal: found[0].nominal,
                order: found.iter().map(|f| f.order).sum::<f64>() / m,
                height_db: found.iter().map(|f| f.height_db).sum::<f64>() / m,
                harmonic_db: opt_mean(&|f| f.harmonic_db),
                sideband_db: opt_mean(&|f| f.sideband_db),
            })
        })
        .collect();
    let prominent: Vec<f64> = parts
        .iter()
        .filter(|p| p.mode.prominent)
        .map(|p| p.mode.hz)
        .collect();
    v.mode = if 2 * prominent.len() > n {
        Mode {
            hz: median(&prominent),
            prominent: true,
        }
    } else {
        Mode {
            hz: median(&parts.iter().map(|p| p.mode.hz).collect::<Vec<_>>()),
            prominent: false,
        }
    };
    v.segments = n;
    v
}

/// Amplitude spectrum (percent) of the relative speed deviation over `[0, dur]`: a
/// Hann-windowed direct DFT of the speed sampled at 100 Hz, from [`SPEED_MIN_HZ`] to
/// [`SPEED_MAX_HZ`] in steps of [`SPEED_STEP_TIMES_S`] / `dur`.
pub fn speed_view(track: &SpeedTrack, dur: f64, rpm: f64) -> Vec<f64> {
    let n_sp = (dur * 100.0) as usize;
    let dev: Vec<f64> = (0..n_sp)
        .map(|i| 100.0 * (track.rpm_at(i as f64 / 100.0) / rpm - 1.0))
        .collect();
    let w: Vec<f64> = (0..n_sp)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n_sp as f64).cos())
        .collect();
    let wsum: f64 = w.iter().sum::<f64>().max(1e-12);
    let dmean = dev.iter().zip(&w).map(|(d, w)| d * w).sum::<f64>() / wsum;
    let x: Vec<f64> = dev.iter().zip(&w).map(|(d, wi)| (d - dmean) * wi).collect();
    let step = SPEED_STEP_TIMES_S / dur.max(1e-9);
    let n_speed = ((SPEED_MAX_HZ - SPEED_MIN_HZ) / step + 1e-9) as usize + 1;
    (0..n_speed)
        .map(|k| {
            let f = SPEED_MIN_HZ + k as f64 * step;
            // phasor recurrence: one complex multiply per sample
            let (s, c) = (std::f64::consts::TAU * f / 100.0).sin_cos();
            let (mut pr, mut pi) = (1.0f64, 0.0f64);
            let (mut re, mut im) = (0.0, 0.0);
            for xi in &x {
                re += xi * pr;
                im += xi * pi;
                let t = pr * c - pi * s;
                pi = pr * s + pi * c;
                pr = t;
            }
            2.0 * (re * re + im * im).sqrt() / wsum
        })
        .collect()
}

/// Which groups of views to compute. A measured recording gets all of them; while an
/// effect's parameters are searched, its simulated twins need only the groups its own error
/// components read ([`Parts::for_components`]), so the others are not computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Parts {
    /// `env`, `env_db`, `fault_peaks` (the envelope order spectrum).
    pub env: bool,
    /// `lines`, `bands`, `band_lo_hz`, `floor_db`, `mode` (the Welch spectrum).
    pub spectrum: bool,
    /// `shaft` (the shaft-order lines).
    pub shaft: bool,
    /// `fractional`, `half_orders`.
    pub fractional: bool,
    /// `impacts`.
    pub impacts: bool,
    /// `landings` (no error component reads it: the locator and the looseness figure do).
    pub landings: bool,
}

impl Parts {
    pub const ALL: Parts = Parts {
        env: true,
        spectrum: true,
        shaft: true,
        fractional: true,
        impacts: true,
        landings: true,
    };
    pub const NONE: Parts = Parts {
        env: false,
        spectrum: false,
        shaft: false,
        fractional: false,
        impacts: false,
        landings: false,
    };

    /// The groups the simulated side of the named error components reads
    /// ([`super::error`]). `speed` reads none (a twin's comes from its speed profile), nor
    /// does `modes` (the model's dominant mode) unless `mode_from_spectrum` (a model
    /// without structural modes: the twin's own dominant band).
    pub fn for_components(components: &[ErrorComponent], mode_from_spectrum: bool) -> Parts {
        use ErrorComponent as C;
        let mut p = Parts::NONE;
        for c in components {
            match c {
                C::Env | C::Peaks | C::Ratios => p.env = true,
                C::Lines | C::Bands | C::Floor => p.spectrum = true,
                C::Modes => p.spectrum |= mode_from_spectrum,
                C::Orders | C::Harmonics => p.shaft = true,
                C::Fractional | C::HalfOrders => p.fractional = true,
                C::Impacts => p.impacts = true,
                C::Speed => {}
            }
        }
        p
    }

    /// Nothing to compute from the signal.
    pub fn is_empty(&self) -> bool {
        *self == Parts::NONE
    }
}

/// Compute the views of one segment (the whole of `rec`); `speed` is left empty (see
/// [`speed_view`]).
pub fn compute_segment(rec: &Recording, rig: &RigConfig, faults: &[Condition]) -> Result<Views> {
    compute_parts(rec, rig, faults, Parts::ALL)
}

/// [`compute_segment`] for the groups in `parts` only; the other fields stay empty (0 for
/// `floor_db`, a default `mode`). Each computed group is the same as [`compute_segment`]'s.
pub fn compute_parts(
    rec: &Recording,
    rig: &RigConfig,
    faults: &[Condition],
    parts: Parts,
) -> Result<Views> {
    compute_parts_along(rec, rig, faults, parts, None)
}

/// The part of a whole recording's speed track from `t0` for `seconds`, on the segment's own
/// clock (its first sample at 0): a segment of a recording read from the vibration keeps the
/// speed the whole recording gave, rather than reading it again from a span that may be
/// shorter than the speed tracker's history.
fn segment_track(track: &SpeedTrack, t0: f64, seconds: f64) -> Result<SpeedTrack> {
    const STEP_S: f64 = 0.05;
    let n = (seconds / STEP_S).ceil() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * STEP_S).collect();
    let hz: Vec<f64> = t.iter().map(|&u| track.rpm_at(t0 + u) / 60.0).collect();
    SpeedTrack::from_profile(&t, &hz, track.source())
}

/// The channel the views read: the rig's classifier channel, else the recording's first.
pub(super) fn classifier_channel<'a>(
    rec: &'a Recording,
    rig: &RigConfig,
) -> Option<&'a crate::recording::Channel> {
    rig.classifier_channel()
        .and_then(|c| rec.channel(&c.name))
        .or_else(|| rec.channels.first())
}

/// [`compute_parts`] along a given speed track (None: the recording's own, read after the
/// sample rate is checked).
fn compute_parts_along(
    rec: &Recording,
    rig: &RigConfig,
    faults: &[Condition],
    parts: Parts,
    track: Option<&SpeedTrack>,
) -> Result<Views> {
    let ch = classifier_channel(rec, rig).context("the recording has no acceleration channel")?;
    let fs = rec.sample_rate;
    if !(fs >= MIN_SAMPLE_RATE_HZ) {
        bail!(
            "channel {:?} is sampled at {fs} Hz; calibration compares raw lines up to \
             {LINES_MAX_HZ} Hz and band energies from {BAND_MIN_HZ} Hz to 0.4 fs, so it needs \
             at least {MIN_SAMPLE_RATE_HZ} Hz: record faster or check the file's sample rate",
            ch.name
        );
    }
    let own;
    let track = match track {
        Some(t) => t,
        None => {
            own = crate::analysis::whole_recording(rec, rig)?;
            &own
        }
    };
    let dur = rec.duration_s();
    let rpm = track.mean_rpm(0.0, dur);
    let mut v = Views {
        rpm,
        healthy: faults.is_empty(),
        seconds: dur,
        segments: 1,
        ..Views::default()
    };
    if parts.env {
        (v.env, v.env_db, v.fault_peaks) = envelope_views(&ch.samples, fs, track, rig, faults)?;
    }
    if parts.spectrum {
        spectrum_views(&ch.samples, fs, &mut v);
    }
    if parts.shaft {
        v.shaft = shaft_orders::measure(&ch.samples, fs, track);
    }
    if parts.fractional {
        let f = fractional_orders::measure(&ch.samples, fs, track);
        (v.fractional, v.half_orders) = (f.levels, f.half);
    }
    if parts.impacts {
        v.impacts = impacts::measure(&ch.samples, fs, BAND_MIN_HZ);
    }
    if parts.landings {
        let orders = rig.bearing.fault_orders();
        v.landings =
            landing_comb::measure(&ch.samples, fs, rpm / 60.0, BAND_MIN_HZ, faults, &orders);
    }
    Ok(v)
}

/// `env`, `env_db` and the located fault peaks, from the envelope order spectrum.
fn envelope_views(
    x: &[f32],
    fs: f64,
    track: &SpeedTrack,
    rig: &RigConfig,
    faults: &[Condition],
) -> Result<(Vec<f64>, Vec<f64>, Vec<FaultPeak>)> {
    let whole = whole_recording(
        x,
        fs,
        track,
        rig.features.lowpass_hz.min(0.45 * fs),
        ENV_MAX_ORDER.max(fault_peaks::MAX_ORDER) + 0.5,
    )?;
    let n_env = ((ENV_MAX_ORDER - ENV_MIN_ORDER) / ENV_STEP) as usize + 1;
    let lo_line = (ENV_MIN_ORDER / whole.order_step) as usize;
    let hi_line = (((ENV_MAX_ORDER + 0.5) / whole.order_step) as usize).min(whole.amplitude.len());
    let med = median(&whole.amplitude[lo_line.min(hi_line - 1)..hi_line]).max(1e-30);
    let env_db: Vec<f64> = (0..n_env)
        .map(|i| {
            let x = env_order(i) / whole.order_step;
            let j = (x.floor() as usize).min(whole.amplitude.len() - 2);
            let f = x - j as f64;
            let a = whole.amplitude[j] * (1.0 - f) + whole.amplitude[j + 1] * f;
            20.0 * (a / med).max(1e-6).log10()
        })
        .collect();
    let env = env_db.iter().map(|d| threshold(*d)).collect();
    let whole_db: Vec<f64> = whole
        .amplitude
        .iter()
        .map(|a| 20.0 * (a / med).max(1e-6).log10())
        .collect();
    let spec = DbSpectrum {
        db: &whole_db,
        step: whole.order_step,
    };
    let nominal = rig.bearing.fault_orders();
    let fault_peaks = faults
        .iter()
        .filter_map(|f| fault_peaks::locate(&spec, *f, &nominal))
        .collect();
    Ok((env, env_db, fault_peaks))
}

/// `lines`, `bands` (with `band_lo_hz`), `floor_db` and the measured `mode`, from the Welch
/// spectrum of `x`, into `v`.
fn spectrum_views(x: &[f32], fs: f64, v: &mut Views) {
    // Welch amplitude and power spectra, 1 Hz bins
    let nseg = (fs.round() as usize).min(x.len());
    let (amplitude_hz, power) = welch(x, nseg);
    let df = fs / nseg as f64;
    let hz_bin = |hz: f64| ((hz / df).round() as usize).min(amplitude_hz.len() - 1);
    v.lines = (LINES_MIN_HZ..=LINES_MAX_HZ)
        .map(|hz| {
            let k = hz_bin(hz as f64);
            let (a, b) = (hz_bin(hz as f64 - 25.0), hz_bin(hz as f64 + 25.0));
            let m = median(&amplitude_hz[a..=b]).max(1e-30);
            threshold(20.0 * (amplitude_hz[k] / m).max(1e-6).log10())
        })
        .collect();
    let band_hi = 0.4 * fs;
    v.floor_db = 20.0
        * quantile(
            &amplitude_hz[hz_bin(BAND_MIN_HZ)..=hz_bin(band_hi)],
            FLOOR_QUANTILE,
        )
        .max(1e-30)
        .log10();
    let mut bands = Vec::new();
    let mut band_lo_hz = Vec::new();
    let mut lo = BAND_MIN_HZ;
    while lo + BAND_HZ <= band_hi {
        let e: f64 = power[hz_bin(lo)..hz_bin(lo + BAND_HZ)].iter().sum();
        bands.push(10.0 * e.max(1e-30).log10());
        band_lo_hz.push(lo);
        lo += BAND_HZ;
    }
    v.mode = modes::dominant(&bands, &band_lo_hz, BAND_HZ);
    let top = bands.iter().copied().fold(f64::MIN, f64::max);
    bands
        .iter_mut()
        .for_each(|b| *b = (*b - top + BAND_RANGE_DB).max(0.0));
    v.bands = bands;
    v.band_lo_hz = band_lo_hz;
}

fn threshold(db: f64) -> f64 {
    (db - THRESHOLD_DB).clamp(0.0, CAP_DB)
}

/// Welch estimate (Hann, 50 % overlap): per-bin peak amplitude and power, `nseg/2+1` bins.
pub(super) fn welch(x: &[f32], nseg: usize) -> (Vec<f64>, Vec<f64>) {
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(nseg);
    let w: Vec<f64> = (0..nseg)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / nseg as f64).cos())
        .collect();
    let wsum: f64 = w.iter().sum();
    let mut input = fft.make_input_vec();
    let mut out = fft.make_output_vec();
    let mut pow = vec![0.0; out.len()];
    let mut count = 0usize;
    let mut start = 0;
    while start + nseg <= x.len() {
        let seg = &x[start..start + nseg];
        let mean = seg.iter().map(|v| *v as f64).sum::<f64>() / nseg as f64;
        for (i, v) in input.iter_mut().enumerate() {
            *v = (seg[i] as f64 - mean) * w[i];
        }
        fft.process(&mut input, &mut out).expect("fft sizes match");
        for (p, c) in pow.iter_mut().zip(&out) {
            *p += c.norm_sqr();
        }
        count += 1;
        start += nseg / 2;
    }
    let c = count.max(1) as f64;
    let amp = pow.iter().map(|p| 2.0 * (p / c).sqrt() / wsum).collect();
    let pw = pow.iter().map(|p| p / c).collect();
    (amp, pw)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Too slow a recording is an error that says why, not a panic on an empty band range.
    #[test]
    fn a_slow_recording_is_refused_with_its_rate() {
        let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
        let rig = RigConfig::load(&root.join("config/lut-rig.toml")).unwrap();
        let sc = crate::sim::Scenario::constant(&[], 588.0, 1.0, 7);
        let mut rec = crate::sim::simulate(&rig, &sc).unwrap();
        assert!(compute(&rec, &rig, &[]).is_ok());
        rec.sample_rate = 500.0;
        let e = format!("{:#}", compute(&rec, &rig, &[]).unwrap_err());
        assert!(e.contains("500 Hz") && e.contains("2000 Hz"), "{e}");
    }
}
