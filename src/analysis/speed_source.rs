//! The one place that turns the rig file's `[speed]` into shaft speed: tacho edges (detected
//! from an analog tacho or delivered by the source), a fixed rpm, the source's stored rpm
//! (`recording`, falling back to edges, then to estimation over 300-3600 rpm), or an estimate
//! from the vibration itself. [`SpeedSource::track`] gives the speed of one window, for the
//! daemon and for whole recordings alike (features are computed window by window, so
//! training and serving see the same speed); [`whole_recording`] gives one track over a whole
//! recording for the analyses that are not per-window features (calibration, whole-recording
//! spectra, `rigmon inspect`), and [`analog_tacho_to_edges`] turns an analog tacho into the
//! edges it would read (before a recording is resampled). Also says when the tacho has gone
//! quiet inside a window (so the state goes `unknown` instead of raising a false alarm).

use crate::config::RigConfig;
use crate::dsp::speed::SpeedTrack;
use crate::dsp::speed_config::SpeedConfig;
use crate::dsp::speed_estimate::SpeedEstimator;
use crate::dsp::tacho;
use crate::recording::{Recording, Tacho};
use anyhow::{Context, Result};

/// Speed range searched when `recording` has neither a stored rpm nor tacho edges.
const FALLBACK_RPM: (f64, f64) = (300.0, 3600.0);

/// Missing pulses for longer than this many revolutions at a window edge = tacho lost.
const LOST_REVS: f64 = 2.5;

/// What `[speed]` asks for, with the source's stored rpm already applied.
#[derive(Debug)]
enum Mode {
    /// Tacho edges; `analog` names the analog tacho channel (source "tacho") or is None for
    /// edges delivered by the source (source "edges").
    Edges {
        pulses_per_rev: u32,
        analog: Option<String>,
    },
    Constant(SpeedTrack),
    Estimate {
        min_rpm: f64,
        max_rpm: f64,
    },
    /// `recording` without a stored rpm: edges when there are some, else estimate.
    EdgesOrEstimate {
        pulses_per_rev: u32,
    },
}

impl Mode {
    fn new(speed: &SpeedConfig, stored_rpm: Option<f64>) -> Result<Mode> {
        Ok(match speed {
            SpeedConfig::Tacho {
                channel,
                pulses_per_rev,
                ..
            } => Mode::Edges {
                pulses_per_rev: *pulses_per_rev,
                analog: Some(channel.clone()),
            },
            SpeedConfig::Edges { pulses_per_rev } => Mode::Edges {
                pulses_per_rev: *pulses_per_rev,
                analog: None,
            },
            SpeedConfig::Fixed { rpm } => Mode::Constant(SpeedTrack::fixed(*rpm)?),
            SpeedConfig::Recording { .. } => match stored_rpm {
                Some(rpm) => Mode::Constant(SpeedTrack::constant(rpm, "recording")?),
                None => Mode::EdgesOrEstimate {
                    pulses_per_rev: speed.pulses_per_rev(),
                },
            },
            SpeedConfig::Estimate { min_rpm, max_rpm } => Mode::Estimate {
                min_rpm: *min_rpm,
                max_rpm: *max_rpm,
            },
        })
    }
}

/// Builds a [`SpeedTrack`] per window. Buffers and FFT plans are made once and reused.
pub struct SpeedSource {
    mode: Mode,
    sample_rate: f64,
    edges: Vec<f64>,
    estimator: SpeedEstimator,
}

impl SpeedSource {
    /// The speed source `speed` asks for; `stored_rpm` is the speed the source knows up front
    /// (the recording's rpm, for `source = "recording"`).
    pub fn new(speed: &SpeedConfig, sample_rate: f64, stored_rpm: Option<f64>) -> Result<Self> {
        Ok(Self::with_mode(Mode::new(speed, stored_rpm)?, sample_rate))
    }

    /// Every window gets this track (e.g. `rigmon features --rpm`).
    pub fn given(track: SpeedTrack, sample_rate: f64) -> Self {
        Self::with_mode(Mode::Constant(track), sample_rate)
    }

    fn with_mode(mode: Mode, sample_rate: f64) -> Self {
        SpeedSource {
            mode,
            sample_rate,
            edges: Vec::with_capacity(256),
            estimator: SpeedEstimator::new(),
        }
    }

    /// Short name of the speed source (for messages before a window has been computed).
    pub fn source_name(&self) -> &'static str {
        match &self.mode {
            Mode::Edges {
                analog: Some(_), ..
            } => "tacho",
            Mode::Edges { analog: None, .. } => "edges",
            Mode::Constant(_) => "fixed",
            Mode::Estimate { .. } => "estimate",
            Mode::EdgesOrEstimate { .. } => "recording",
        }
    }

    /// The speed track of one window: `edges` = the window's tacho edge times (s), `signal` =
    /// the classifier channel's samples (for estimation).
    pub fn track(
        &mut self,
        edges: impl Iterator<Item = f64>,
        signal: &[f32],
    ) -> Result<SpeedTrack> {
        self.edges.clear();
        self.edges.extend(edges);
        match &self.mode {
            Mode::Edges {
                pulses_per_rev,
                analog,
            } => SpeedTrack::from_edges(
                &self.edges,
                *pulses_per_rev,
                if analog.is_some() { "tacho" } else { "edges" },
            ),
            Mode::Constant(t) => Ok(t.clone()),
            Mode::Estimate { min_rpm, max_rpm } => {
                let (lo, hi) = (*min_rpm, *max_rpm);
                self.estimate(signal, lo, hi)
            }
            Mode::EdgesOrEstimate { pulses_per_rev } => {
                if self.edges.len() >= 3 {
                    SpeedTrack::from_edges(&self.edges, *pulses_per_rev, "edges")
                } else {
                    self.estimate(signal, FALLBACK_RPM.0, FALLBACK_RPM.1)
                }
            }
        }
    }

    /// One speed for the whole window from the vibration (a constant track needs no clock).
    fn estimate(&mut self, x: &[f32], min_rpm: f64, max_rpm: f64) -> Result<SpeedTrack> {
        let e = self
            .estimator
            .estimate_constant(x, self.sample_rate, min_rpm, max_rpm)?;
        SpeedTrack::constant(e.rpm, "estimate")
    }

    /// True when tacho pulses stop (or have not started) more than a couple of revolutions
    /// inside the window: the speed there is a guess, so the window must not be classified.
    pub fn lost_pulses(&self, track: &SpeedTrack, t0: f64, t1: f64) -> bool {
        if !matches!(self.mode, Mode::Edges { .. } | Mode::EdgesOrEstimate { .. })
            || track.source() == "estimate"
        {
            return false;
        }
        let Some((first, last)) = track.span() else {
            return false;
        };
        let rpm = track.mean_rpm(first.max(t0 - 1.0), last);
        if !(rpm.is_finite() && rpm > 0.0) {
            return true;
        }
        let rev_s = 60.0 / rpm;
        first > t0 + LOST_REVS * rev_s || last < t1 - LOST_REVS * rev_s
    }

    /// Refuse a recording that cannot give what `[speed]` asks for window by window, with
    /// the fix.
    pub fn check_recording(&self, rec: &Recording) -> Result<()> {
        check_tacho(&self.mode, rec)?;
        match (&self.mode, &rec.tacho) {
            (Mode::Edges { analog: None, .. }, Some(Tacho::Analog { .. })) => anyhow::bail!(
                "{}: the rig file takes speed from tacho edges, but the recording has an analog tacho; use [speed] source = \"tacho\" with its threshold and hysteresis",
                rec.provenance.source_path
            ),
            _ => Ok(()),
        }
    }
}

/// A tacho-based mode needs a tacho in the recording.
fn check_tacho(mode: &Mode, rec: &Recording) -> Result<()> {
    let what = &rec.provenance.source_path;
    match (mode, &rec.tacho) {
            (Mode::Edges { analog: Some(channel), .. }, None) => anyhow::bail!(
                "{what}: the rig file takes speed from tacho channel {channel:?}, but the recording has no tacho; use --rpm or a rig file with [speed] source = \"estimate\""
            ),
            (Mode::Edges { analog: None, .. }, None) => anyhow::bail!(
                "{what}: the rig file takes speed from tacho edges, but the recording has none"
            ),
        _ => Ok(()),
    }
}

/// One speed track over a whole recording, as the rig file asks: `tacho` (analog channel, or
/// edges if the recording has those), `edges`, `fixed`, `recording` (the stored rpm; falls
/// back to the tacho, then to estimation) and `estimate` (tracking the 1x line of the
/// classifier channel). For whole-recording analyses; features use [`SpeedSource::track`]
/// window by window.
pub fn whole_recording(rec: &Recording, rig: &RigConfig) -> Result<SpeedTrack> {
    let mode = Mode::new(&rig.speed, rec.rpm)?;
    let from_tacho = |tacho: &Tacho, ppr: u32| -> Result<SpeedTrack> {
        match tacho {
            Tacho::Edges { times_s } => SpeedTrack::from_edges(times_s, ppr, "edges"),
            Tacho::Analog { samples, .. } => {
                let (thr, hyst) = analog_levels(samples, &rig.speed)?;
                SpeedTrack::from_analog(samples, rec.sample_rate, thr, hyst, ppr)
            }
        }
    };
    let estimate = |min_rpm: f64, max_rpm: f64| -> Result<SpeedTrack> {
        let ch = rig
            .classifier_channel()
            .and_then(|c| rec.channel(&c.name))
            .or_else(|| rec.channels.first())
            .context("the recording has no acceleration channel to estimate speed from")?;
        SpeedEstimator::new()
            .estimate_track(&ch.samples, rec.sample_rate, min_rpm, max_rpm)
            .with_context(|| format!("estimating speed from channel {:?}", ch.name))
    };
    match &mode {
        Mode::Edges { pulses_per_rev, .. } => {
            check_tacho(&mode, rec)?;
            let t = rec.tacho.as_ref().context("no tacho")?;
            from_tacho(t, *pulses_per_rev)
        }
        Mode::Constant(t) => Ok(t.clone()),
        Mode::Estimate { min_rpm, max_rpm } => estimate(*min_rpm, *max_rpm),
        Mode::EdgesOrEstimate { pulses_per_rev } => match &rec.tacho {
            Some(t) => from_tacho(t, *pulses_per_rev),
            None => estimate(FALLBACK_RPM.0, FALLBACK_RPM.1),
        },
    }
}

/// The switching levels of an analog tacho: the rig file's threshold and hysteresis, else
/// half-way between the channel's own levels ([`tacho::auto_threshold`]).
fn analog_levels(samples: &[f32], speed: &SpeedConfig) -> Result<(f64, f64)> {
    match speed.tacho_levels() {
        Some(levels) => Ok(levels),
        None => {
            tacho::auto_threshold(samples).context("the analog tacho channel has no usable levels")
        }
    }
}

/// Turn an analog tacho into the edge times [`whole_recording`] would detect in it, at the
/// recording's own rate: the speed track (and its mean speed) stays the same, and the
/// recording can then be resampled without its speed reference losing anything. Edges
/// delivered by the source, or no tacho, stay as they are. A tacho without usable levels is
/// an error when the rig's speed source reads it, and is dropped when it does not (a fixed,
/// stored or estimated speed).
pub fn analog_tacho_to_edges(rec: &mut Recording, rig: &RigConfig) -> Result<()> {
    let Some(Tacho::Analog { samples, .. }) = &rec.tacho else {
        return Ok(());
    };
    let reads_tacho = matches!(
        Mode::new(&rig.speed, rec.rpm)?,
        Mode::Edges { .. } | Mode::EdgesOrEstimate { .. }
    );
    rec.tacho = match analog_levels(samples, &rig.speed) {
        Ok((thr, hyst)) => Some(Tacho::Edges {
            times_s: tacho::detect_edges(samples, rec.sample_rate, thr, hyst),
        }),
        Err(e) if reads_tacho => {
            return Err(e.context(format!(
                "{}: the rig's speed source reads the analog tacho; check that channel, or take the speed from [speed] source = \"fixed\" or \"estimate\"",
                rec.provenance.source_path
            )))
        }
        Err(_) => None,
    };
    Ok(())
}
