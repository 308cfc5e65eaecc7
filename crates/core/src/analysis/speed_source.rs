//! The one place that turns the rig file's `[speed]` into shaft speed: tacho edges (detected
//! from an analog tacho or delivered by the source), a fixed rpm (checked against the
//! vibration), the source's stored rpm (`recording`, falling back to edges, then to the
//! vibration over 300-3600 rpm), or the vibration itself (`estimate`: the streaming
//! [`SpeedTracker`], which keeps its own signal history, so a window's speed is not limited
//! to what one window can resolve). A recording's nominal speed (a manifest's `rpm`) is a hint
//! the vibration is checked against. [`SpeedSource::track`] gives the speed of one window,
//! for the daemon and for whole recordings alike (features are computed window by window, so
//! training and serving see the same speed); [`whole_recording`] gives one track over a whole
//! recording for the analyses that are not per-window features (calibration, whole-recording
//! spectra, `rigmon inspect`), built from the same per-window speeds, and
//! [`analog_tacho_to_edges`] turns an analog tacho into the edges it would read (before a
//! recording is resampled). Also says when the tacho has gone quiet inside a window (so the
//! state goes `unknown` instead of raising a false alarm). The rig's bearing goes to the
//! tracker too ([`SpeedSource::with_fault_families`], applied by the analysis stage and by
//! [`whole_recording`]): its fault families in the envelope settle the octave where the shaft
//! lines leave it open. A stated speed is a prior, not the truth: where the vibration clearly
//! turns at the octave above or below it, the vibration's speed is used, and a whole
//! recording says so once ([`HintContradiction`], [`whole_recording_checked`]).

use super::windows::WindowView;
use crate::config::RigConfig;
use crate::dsp::fault_family::FamilySettings;
use crate::dsp::speed::SpeedTrack;
use crate::dsp::speed_config::SpeedConfig;
use crate::dsp::speed_tracker::{
    SpeedHint, SpeedStatus, SpeedTracker, TrackedSpeed, TrackerSettings, HISTORY_REVS,
};
use crate::dsp::tacho;
use crate::recording::{Recording, Tacho};
use crate::vocabulary::SpeedSourceKind;
use anyhow::{Context, Result};

/// Speed range searched when `recording` has neither a stored rpm nor tacho edges.
const FALLBACK_RPM: (f64, f64) = (300.0, 3600.0);

/// Missing pulses for longer than this many revolutions at a window edge = tacho lost.
const LOST_REVS: f64 = 2.5;

/// What `[speed]` asks for, with the source's stored rpm and nominal speed already applied.
#[derive(Debug)]
enum Mode {
    /// Tacho edges; `analog` names the analog tacho channel (source "tacho") or is None for
    /// edges delivered by the source (source "edges").
    Edges {
        pulses_per_rev: u32,
        analog: Option<String>,
    },
    Constant(SpeedTrack),
    /// The vibration, through the streaming tracker; a hint's own speed is reported under
    /// `hint_source` when it is used.
    Tracked {
        settings: TrackerSettings,
        hint_source: SpeedSourceKind,
    },
    /// `recording` without a stored rpm: edges when there are some, else the vibration.
    EdgesOrTracked {
        pulses_per_rev: u32,
        settings: TrackerSettings,
    },
}

/// A recording whose windows contradict the speed stated for it (a manifest's `rpm`, a
/// `[speed] fixed` rpm): in those windows the vibration clearly turns at another octave, and
/// its speed is used ([`SpeedStatus::OffHint`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HintContradiction {
    /// The stated speed, rpm.
    pub stated_rpm: f64,
    /// The vibration's speed in the windows that contradict it (their median), rpm.
    pub vibration_rpm: f64,
    /// Windows whose vibration contradicts the stated speed.
    pub windows: usize,
    /// Windows with a speed.
    pub of: usize,
}

impl HintContradiction {
    /// Tally the windows' speeds against `stated_rpm`: None when no window contradicts it.
    pub fn tally(stated_rpm: f64, windows: &[TrackedSpeed]) -> Option<HintContradiction> {
        let mut off: Vec<f64> = windows
            .iter()
            .filter(|w| w.status == SpeedStatus::OffHint)
            .map(|w| w.rpm)
            .collect();
        if off.is_empty() {
            return None;
        }
        off.sort_by(f64::total_cmp);
        Some(HintContradiction {
            stated_rpm,
            vibration_rpm: off[off.len() / 2],
            windows: off.len(),
            of: windows.len(),
        })
    }

    /// What the user reads after the recording's name: "rpm 600, the vibration turns at
    /// 1184 rpm in 9 of 9 windows: the vibration is used; check the label".
    pub fn message(&self) -> String {
        format!(
            "rpm {:.0}, the vibration turns at {:.0} rpm in {} of {} windows: the vibration is used; check the label",
            self.stated_rpm, self.vibration_rpm, self.windows, self.of
        )
    }
}

/// The tracker settings for a range and an optional hint (`within` in per cent; 0 = no check).
fn tracked(min_rpm: f64, max_rpm: f64, hint: Option<(f64, f64)>) -> TrackerSettings {
    TrackerSettings {
        min_rpm,
        max_rpm,
        hint: hint
            .filter(|&(_, within)| within > 0.0)
            .map(|(rpm, within)| SpeedHint {
                rpm,
                within: within / 100.0,
            }),
        families: None,
    }
}

/// The rig's bearing fault families, for the tracker (carrier band up to the feature low-pass).
fn rig_families(rig: &RigConfig) -> FamilySettings {
    FamilySettings {
        orders: rig.bearing.fault_orders(),
        band_top_hz: rig.features.lowpass_hz,
    }
}

impl Mode {
    fn new(speed: &SpeedConfig, stored_rpm: Option<f64>, nominal_rpm: Option<f64>) -> Result<Mode> {
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
            SpeedConfig::Fixed {
                rpm,
                check_within_percent,
            } => {
                SpeedTrack::fixed(*rpm)?;
                if *check_within_percent > 0.0 {
                    Mode::Tracked {
                        settings: tracked(
                            FALLBACK_RPM.0,
                            FALLBACK_RPM.1,
                            Some((*rpm, *check_within_percent)),
                        ),
                        hint_source: SpeedSourceKind::Fixed,
                    }
                } else {
                    Mode::Constant(SpeedTrack::fixed(*rpm)?)
                }
            }
            SpeedConfig::Recording {
                check_within_percent,
            } => match (stored_rpm, nominal_rpm) {
                (Some(rpm), _) => {
                    Mode::Constant(SpeedTrack::constant(rpm, SpeedSourceKind::Recording)?)
                }
                (None, Some(nominal)) if *check_within_percent > 0.0 => Mode::Tracked {
                    settings: tracked(
                        FALLBACK_RPM.0,
                        FALLBACK_RPM.1,
                        Some((nominal, check_within_percent.max(NOMINAL_WITHIN_PERCENT))),
                    ),
                    hint_source: SpeedSourceKind::Recording,
                },
                (None, Some(nominal)) => {
                    Mode::Constant(SpeedTrack::constant(nominal, SpeedSourceKind::Recording)?)
                }
                (None, None) => Mode::EdgesOrTracked {
                    pulses_per_rev: speed.pulses_per_rev(),
                    settings: tracked(FALLBACK_RPM.0, FALLBACK_RPM.1, None),
                },
            },
            SpeedConfig::Estimate {
                min_rpm,
                max_rpm,
                check_within_percent,
            } => Mode::Tracked {
                settings: tracked(
                    *min_rpm,
                    *max_rpm,
                    nominal_rpm.map(|rpm| (rpm, *check_within_percent)),
                ),
                hint_source: SpeedSourceKind::Estimate,
            },
        })
    }

    /// The tracker settings, for modes that read the vibration.
    fn tracker_settings(&self) -> Option<TrackerSettings> {
        match self {
            Mode::Tracked { settings, .. } | Mode::EdgesOrTracked { settings, .. } => {
                Some(*settings)
            }
            _ => None,
        }
    }
}

/// A nominal speed given beside a recording (labels.csv `rpm`) is searched at least this wide
/// (per cent) in `recording` mode: a motor setting can be 8 % off the shaft.
const NOMINAL_WITHIN_PERCENT: f64 = 10.0;

/// The speed of one window and what the vibration tracker said about it (for speeds read from
/// the vibration).
#[derive(Debug, Clone)]
pub struct WindowSpeed {
    pub track: SpeedTrack,
    /// 0-1 for speeds read from the vibration (None otherwise).
    pub confidence: Option<f64>,
    pub status: Option<SpeedStatus>,
    /// Half or twice the speed, when the spectrum supports it nearly as well, rpm.
    pub rival_rpm: Option<f64>,
    /// The speed is not known well enough to classify the window.
    pub uncertain: bool,
}

impl WindowSpeed {
    fn known(track: SpeedTrack) -> Self {
        WindowSpeed {
            track,
            confidence: None,
            status: None,
            rival_rpm: None,
            uncertain: false,
        }
    }
}

/// Builds a [`SpeedTrack`] per window. Buffers, FFT plans and the tracker's history are made
/// once and reused.
pub struct SpeedSource {
    mode: Mode,
    edges: Vec<f64>,
    tracker: Option<SpeedTracker>,
    /// Stream-clock sample up to which the tracker has been fed.
    fed_until: Option<u64>,
}

impl SpeedSource {
    /// The speed source `speed` asks for; `stored_rpm` is the speed the source knows up front
    /// (the recording's rpm, for `source = "recording"`).
    pub fn new(speed: &SpeedConfig, sample_rate: f64, stored_rpm: Option<f64>) -> Result<Self> {
        Self::with_nominal(speed, sample_rate, stored_rpm, None)
    }

    /// As [`new`](Self::new), with a nominal speed stated beside the recording (a hint the
    /// vibration is checked against).
    pub fn with_nominal(
        speed: &SpeedConfig,
        sample_rate: f64,
        stored_rpm: Option<f64>,
        nominal_rpm: Option<f64>,
    ) -> Result<Self> {
        Self::with_mode(Mode::new(speed, stored_rpm, nominal_rpm)?, sample_rate)
    }

    /// The speed source for a whole recording: `[speed]` with the recording's stored and
    /// nominal speeds, refused up front when the recording cannot give it (no tacho, too
    /// short for the lowest speed). A simulated recording whose rig reads the speed from the
    /// vibration gets the simulator's own speed instead (see [`simulator_speed`]).
    pub fn for_recording(rec: &Recording, rig: &RigConfig) -> Result<Self> {
        let mode = Mode::new(&rig.speed, rec.rpm, nominal_rpm(rec))?;
        if let Some(track) = simulator_speed(&mode, rec) {
            return Ok(Self::given(track?, rec.sample_rate));
        }
        let source = Self::with_mode(mode, rec.sample_rate)?;
        source
            .check_recording(rec)
            .with_context(|| format!("speed for {}", rec.provenance.source_path))?;
        Ok(source)
    }

    /// Let the vibration tracker weigh the rig's bearing fault families (the envelope lines a
    /// damaged bearing adds at fixed orders of the true shaft speed) where the shaft lines
    /// leave the octave open. The analysis stage applies it for every rig, before any window;
    /// speeds not read from the vibration are unaffected.
    pub fn with_fault_families(mut self, rig: &RigConfig, sample_rate: f64) -> Result<Self> {
        let families = Some(rig_families(rig));
        match &mut self.mode {
            Mode::Tracked { settings, .. } | Mode::EdgesOrTracked { settings, .. } => {
                settings.families = families;
                self.tracker = Some(SpeedTracker::new(*settings, sample_rate)?);
                self.fed_until = None;
            }
            _ => {}
        }
        Ok(self)
    }

    /// Every window gets this track (e.g. `rigmon features --rpm`).
    pub fn given(track: SpeedTrack, sample_rate: f64) -> Self {
        Self::with_mode(Mode::Constant(track), sample_rate).expect("a constant needs no tracker")
    }

    fn with_mode(mode: Mode, sample_rate: f64) -> Result<Self> {
        let tracker = match mode.tracker_settings() {
            Some(s) => Some(SpeedTracker::new(s, sample_rate)?),
            None => None,
        };
        Ok(SpeedSource {
            mode,
            edges: Vec::with_capacity(256),
            tracker,
            fed_until: None,
        })
    }

    /// The speed source (for messages before a window has been computed).
    pub fn kind(&self) -> SpeedSourceKind {
        match &self.mode {
            Mode::Edges {
                analog: Some(_), ..
            } => SpeedSourceKind::Tacho,
            Mode::Edges { analog: None, .. } => SpeedSourceKind::Edges,
            Mode::Constant(_) => SpeedSourceKind::Fixed,
            Mode::Tracked { hint_source, .. } => *hint_source,
            Mode::EdgesOrTracked { .. } => SpeedSourceKind::Recording,
        }
    }

    /// Seconds of signal the vibration tracker needs to resolve the lowest speed of its range
    /// (None for speeds not read from the vibration).
    pub fn history_s(&self) -> Option<f64> {
        self.tracker.as_ref().map(SpeedTracker::history_s)
    }

    /// The speed of one window: `view` supplies its tacho edges and its place on the stream
    /// clock, `signal` the classifier channel's samples of the window (NaN set to 0), which
    /// also feed the vibration tracker's history.
    pub fn track(&mut self, view: &WindowView, signal: &[f32]) -> Result<WindowSpeed> {
        self.edges.clear();
        self.edges.extend(view.edges());
        self.feed(view, signal);
        match &self.mode {
            Mode::Edges {
                pulses_per_rev,
                analog,
            } => SpeedTrack::from_edges(
                &self.edges,
                *pulses_per_rev,
                if analog.is_some() {
                    SpeedSourceKind::Tacho
                } else {
                    SpeedSourceKind::Edges
                },
            )
            .map(WindowSpeed::known),
            Mode::Constant(t) => Ok(WindowSpeed::known(t.clone())),
            Mode::Tracked { hint_source, .. } => {
                let source = *hint_source;
                self.tracked(source)
            }
            Mode::EdgesOrTracked { pulses_per_rev, .. } => {
                if self.edges.len() >= 3 {
                    SpeedTrack::from_edges(&self.edges, *pulses_per_rev, SpeedSourceKind::Edges)
                        .map(WindowSpeed::known)
                } else {
                    self.tracked(SpeedSourceKind::Recording)
                }
            }
        }
    }

    /// Give the tracker the window's samples it has not seen yet (a window that does not
    /// continue the last one restarts its history).
    fn feed(&mut self, view: &WindowView, signal: &[f32]) {
        let Some(tracker) = self.tracker.as_mut() else {
            return;
        };
        let (start, end) = (view.first_sample, view.first_sample + signal.len() as u64);
        let from = match self.fed_until {
            Some(f) if f > start && f <= end => f,
            _ => start,
        };
        tracker.push(from, &signal[(from - start) as usize..]);
        self.fed_until = Some(end);
    }

    /// The tracker's speed for the window; a hint's own speed is reported as `hint_source`.
    fn tracked(&mut self, hint_source: SpeedSourceKind) -> Result<WindowSpeed> {
        let tracker = self.tracker.as_mut().expect("tracked modes have a tracker");
        let t: TrackedSpeed = tracker.estimate()?;
        let track = if t.status == SpeedStatus::Hint {
            SpeedTrack::constant(t.rpm, hint_source)?
        } else {
            t.track.clone()
        };
        Ok(WindowSpeed {
            uncertain: t.uncertain(),
            track,
            confidence: Some(t.confidence),
            status: Some(t.status),
            rival_rpm: t.rival_rpm,
        })
    }

    /// True when tacho pulses stop (or have not started) more than a couple of revolutions
    /// inside the window: the speed there is a guess, so the window must not be classified.
    pub fn lost_pulses(&self, track: &SpeedTrack, t0: f64, t1: f64) -> bool {
        if !matches!(self.mode, Mode::Edges { .. } | Mode::EdgesOrTracked { .. })
            || track.source() == SpeedSourceKind::Estimate
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
        check_length(&self.mode, rec)?;
        match (&self.mode, &rec.tacho) {
            (Mode::Edges { analog: None, .. }, Some(Tacho::Analog { .. })) => anyhow::bail!(
                "{}: the rig file takes speed from tacho edges, but the recording has an analog tacho; use [speed] source = \"tacho\" with its threshold and hysteresis",
                rec.provenance.source_path
            ),
            _ => Ok(()),
        }
    }
}

/// The simulator's own speed (the exact revolution times it writes on a rig without a tacho
/// channel) for a simulated recording whose rig reads the speed from the vibration alone
/// (`estimate`, or `fixed` checked against the vibration); None for any other recording or
/// mode (`recording` uses the edges as a tacho anyway). Training data then has the speed the simulator ran at, not
/// what the tracker reads: healthy simulations below ~1000 rpm carry no shaft line the
/// tracker could follow, and a simulated recording need not be as long as the tracker's
/// history. What this leaves out, the tracker's error on a real machine, is measured in
/// `tests/fast/dsp.rs` (features from the tracked and the true speed of the same simulated
/// recordings: their difference against the difference between classes).
fn simulator_speed(mode: &Mode, rec: &Recording) -> Option<Result<SpeedTrack>> {
    match (&rec.tacho, mode) {
        (Some(Tacho::Edges { times_s }), Mode::Tracked { .. }) if rec.is_simulated() => Some(
            SpeedTrack::from_edges(times_s, 1, SpeedSourceKind::Simulator),
        ),
        _ => None,
    }
}

/// The nominal speed stated beside a recording (a hint, checked against the vibration).
pub fn nominal_rpm(rec: &Recording) -> Option<f64> {
    rec.nominal_rpm.as_ref().map(|n| n.rpm)
}

/// Speed read from the vibration alone (no hint, no tacho) needs [`HISTORY_REVS`]
/// revolutions at the range's lowest speed: a shorter recording is refused before any work.
fn check_length(mode: &Mode, rec: &Recording) -> Result<()> {
    let settings = match mode {
        Mode::Tracked { settings, .. } => settings,
        Mode::EdgesOrTracked { settings, .. } if rec.tacho.is_none() => settings,
        _ => return Ok(()),
    };
    if settings.hint.is_some() {
        return Ok(());
    }
    let need = HISTORY_REVS / (settings.min_rpm / 60.0);
    if rec.duration_s() < need {
        anyhow::bail!(
            "{}: {:.2} s of signal; reading the speed from the vibration down to {:.0} rpm needs at least {need:.2} s ({HISTORY_REVS} revolutions at the lowest speed); use a longer recording, raise [speed] min_rpm, or state the speed (labels.csv `rpm`, [speed] source = \"fixed\")",
            rec.provenance.source_path,
            rec.duration_s(),
            settings.min_rpm
        );
    }
    Ok(())
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
/// back to the tacho, then to the vibration) and `estimate`. Speeds read from the vibration
/// are the ones the windows get ([`SpeedSource::track`], every hop), joined into one track.
/// For whole-recording analyses; features use [`SpeedSource::track`] window by window.
pub fn whole_recording(rec: &Recording, rig: &RigConfig) -> Result<SpeedTrack> {
    whole_recording_checked(rec, rig).map(|(track, _)| track)
}

/// As [`whole_recording`], with the windows that contradict the recording's stated speed
/// (None: none do, or the speed is not read from the vibration with a hint).
pub fn whole_recording_checked(
    rec: &Recording,
    rig: &RigConfig,
) -> Result<(SpeedTrack, Option<HintContradiction>)> {
    let mode = Mode::new(&rig.speed, rec.rpm, nominal_rpm(rec))?;
    if let Some(track) = simulator_speed(&mode, rec) {
        return Ok((track?, None));
    }
    let from_tacho = |tacho: &Tacho, ppr: u32| -> Result<SpeedTrack> {
        match tacho {
            Tacho::Edges { times_s } => {
                SpeedTrack::from_edges(times_s, ppr, SpeedSourceKind::Edges)
            }
            Tacho::Analog { samples, .. } => {
                let (thr, hyst) = analog_levels(samples, &rig.speed)?;
                SpeedTrack::from_analog(samples, rec.sample_rate, thr, hyst, ppr)
            }
        }
    };
    match &mode {
        Mode::Edges { pulses_per_rev, .. } => {
            check_tacho(&mode, rec)?;
            let t = rec.tacho.as_ref().context("no tacho")?;
            Ok((from_tacho(t, *pulses_per_rev)?, None))
        }
        Mode::Constant(t) => Ok((t.clone(), None)),
        Mode::Tracked {
            settings,
            hint_source,
        } => tracked_whole(rec, rig, *settings, *hint_source),
        Mode::EdgesOrTracked {
            pulses_per_rev,
            settings,
        } => match &rec.tacho {
            Some(t) => Ok((from_tacho(t, *pulses_per_rev)?, None)),
            None => tracked_whole(rec, rig, *settings, SpeedSourceKind::Recording),
        },
    }
}

/// The vibration tracker run over a whole recording as the windows would run it (fed up to
/// every window end), its confident speeds joined into one track: constant when they all lie
/// within 1 % of their median, else a profile through them; with the windows that contradict
/// the hint.
fn tracked_whole(
    rec: &Recording,
    rig: &RigConfig,
    settings: TrackerSettings,
    hint_source: SpeedSourceKind,
) -> Result<(SpeedTrack, Option<HintContradiction>)> {
    check_length(
        &Mode::Tracked {
            settings,
            hint_source: SpeedSourceKind::Estimate,
        },
        rec,
    )?;
    let ch = rig
        .classifier_channel()
        .and_then(|c| rec.channel(&c.name))
        .or_else(|| rec.channels.first())
        .context("the recording has no acceleration channel to read the speed from")?;
    let fs = rec.sample_rate;
    let settings = TrackerSettings {
        families: Some(rig_families(rig)),
        ..settings
    };
    let mut tracker = SpeedTracker::new(settings, fs)?;
    let window = (rig.features.window_s * fs).round() as usize;
    let hop = ((rig.features.hop_s * fs).round() as usize).max(1);
    let x = &ch.samples;
    let (mut ts, mut hz, mut all) = (Vec::new(), Vec::new(), Vec::new());
    let mut fed = 0;
    let mut end = window.min(x.len());
    let mut hinted = 0usize;
    while end <= x.len() && end > fed {
        tracker.push(fed as u64, &x[fed..end]);
        fed = end;
        if let Ok(t) = tracker.estimate() {
            if t.status == SpeedStatus::Hint {
                hinted += 1;
            }
            if !t.uncertain() {
                ts.push(end as f64 / fs);
                hz.push(t.rpm / 60.0);
            }
            all.push(t);
        }
        end += hop;
    }
    if ts.is_empty() {
        anyhow::bail!(
            "{}: no clear shaft line in channel {:?} ({:.1} s) between {:.0} and {:.0} rpm; state the speed (labels.csv `rpm`, [speed] source = \"fixed\") or check the channel",
            rec.provenance.source_path,
            ch.name,
            rec.duration_s(),
            settings.min_rpm,
            settings.max_rpm
        );
    }
    let source = if hinted == ts.len() {
        hint_source
    } else {
        SpeedSourceKind::Estimate
    };
    let against = settings
        .hint
        .and_then(|h| HintContradiction::tally(h.rpm, &all));
    let mut sorted = hz.clone();
    sorted.sort_by(f64::total_cmp);
    let med = sorted[sorted.len() / 2];
    if hz.iter().all(|f| (f / med - 1.0).abs() < 0.01) {
        return Ok((SpeedTrack::constant(med * 60.0, source)?, against));
    }
    Ok((SpeedTrack::from_profile(&ts, &hz, source)?, against))
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
        Mode::new(&rig.speed, rec.rpm, nominal_rpm(rec))?,
        Mode::Edges { .. } | Mode::EdgesOrTracked { .. }
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
