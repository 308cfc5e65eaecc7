//! Shaft speed from the vibration alone, on-line: for machines with only an accelerometer.
//!
//! The tracker keeps the signal's recent history (decimated to the few hundred hertz the
//! shaft harmonics occupy), [`HISTORY_REVS`] revolutions at the slowest speed of the rig's
//! range, and at every window looks for the strongest harmonic series of the shaft line in
//! it ([`super::harmonic_sum`]: whitened spectrum, harmonics 1x-5x, octave guard, mains lines
//! never voting). It does not start from scratch each window:
//! - **continuity**: the line found before is followed (searched within a few per cent of
//!   where its trend puts it); a stronger line elsewhere is taken only once it has won two
//!   windows in a row, and the window where it first wins is marked uncertain; the followed
//!   line's own half, which it already reports as its octave rival, is held off the same way
//!   but without the mark (the window keeps the followed line, ambiguous);
//! - **run-ups**: the history is warped in time along the speed trend measured over the last
//!   windows before its spectrum is taken, so the harmonics of an accelerating shaft stay
//!   sharp lines; the speed reported is the speed at the end of the history, and the window's
//!   speed track follows the trend;
//! - **confidence** (0-1): how clearly the line stands above its background (the harmonic
//!   prominence that reads about 0.5 on noise and 2 or more on a clear shaft line, the same
//!   scale as the stored-speed check), how many revolutions the history holds, whether the
//!   line just jumped, and whether half or twice the speed explains the spectrum nearly as
//!   well (an octave rival, reported with its speed).
//! - **fault families**: where the shaft lines leave the octave open (f/2 explains every line
//!   f does; a ratio such as 2f/3 scores nearly as well), a damaged bearing's envelope lines
//!   decide: the speed under which a BPFO, BPFI or 2xBSF family falls on its order, and under
//!   which the other speed's lines do not, is taken; of two speeds an octave apart, a family
//!   at the higher one whose fundamental at the lower one is missing speaks for the higher
//!   ([`super::fault_family`]). A healthy machine shows no family and keeps what the shaft
//!   lines say.
//!
//! - **the joint reading** (issue 34, on by default, [`JointParts`]): a lone strong 1x line
//!   counts as shaft evidence, the speed is read from the harmonics' own interpolated peaks
//!   (no bias from the harmonic sum's grid), and a comb may be a bearing's impact train
//!   ([`super::speed_comb`]) when a slower shaft shows lines of its own beside it. The
//!   harmonics' phase over the history ([`super::speed_phase`]) shows a weak line in the
//!   newest second where its spectrum cannot (a matched filter), so the line stays followed,
//!   and gives the speed where it curves (a fluctuation); reading every window's speed from
//!   the phase is measured but off by default (`JointParts::default_on`; docs/speed.md says
//!   why).
//!
//! A hint (a fixed or nominal speed) narrows the search to a band around it and is used
//! itself when the vibration shows no clear line there; it is a prior, not the truth: where
//! the spectrum clearly shows the shaft at the octave below the band's line, inside
//! the rig's range, the vibration's speed is used and the window says so
//! ([`SpeedStatus::OffHint`], [`super::speed_hint`]).
//!
//! The input is the stream's samples in order; a discontinuity (a gap or restart of the
//! sample clock) restarts the history. Given the same samples, the result does not depend on
//! how they were cut into blocks, so a live stream and a whole recording get the same speeds.

use super::decimate::Decimator;
use super::fault_family::{EnvelopeFeed, FamilyEvidence, FamilySettings, FAMILY_PRESENT};
use super::harmonic_sum::{fundamental, on_mains_harmonic, Whitened, Whitener, HARMONICS};
use super::speed::SpeedTrack;
use super::speed_comb::{
    bare_comb, best_own, comb_spans, comb_speeds, train_present, train_support, unexplained,
};
use super::speed_hint::{octave_off_hint, OffHint, SCORE_CLEAR};
use super::speed_phase::{self, PhaseFit};
use crate::vocabulary::SpeedSourceKind;
use anyhow::{bail, Result};

/// Revolutions at the rig's lowest speed that the history holds.
pub const HISTORY_REVS: f64 = 20.0;
/// Fewest revolutions (at a candidate speed) for the candidate to be considered at all.
const MIN_REVS: f64 = 8.0;
/// Revolutions at which a clear line counts as fully resolved.
const FULL_REVS: f64 = 16.0;
/// Harmonic prominence of noise (about 0.5, the best of many candidates); a clear line's is
/// [`SCORE_CLEAR`].
const SCORE_NOISE: f64 = 1.0;
/// Mean prominence of the lines only one of two octave-related speeds predicts above which
/// that speed stays a rival (noise, searched as the octave guard searches, reads 0.3-0.5).
const RIVAL_SUPPORT: f64 = 0.7;
/// A window whose confidence is below this is flagged: its speed is not known.
pub const MIN_CONFIDENCE: f64 = 0.5;
/// Confidence from which a line is trusted enough to be followed (and a jump away from it
/// needs confirmation).
const LOCK_CONFIDENCE: f64 = 0.7;
/// The line followed is kept while it scores at least this share of the best line elsewhere.
const KEEP_SHARE: f64 = 0.7;
/// Relative band around the predicted speed in which the followed line is searched.
const FOLLOW_BAND: f64 = 0.03;
/// Largest speed trend followed, relative change per second (a run-up from 300 to 1800 rpm in
/// 20 s peaks at 0.25 /s).
const MAX_TREND: f64 = 0.5;
/// Share of the trend measured in one window that is taken into the followed trend (the rest
/// is the trend so far): a one-pole smoother against the scatter of a single window.
const TREND_GAIN: f64 = 0.5;
/// Trends tried while acquiring (relative speed change per second).
const ACQUIRE_TRENDS: [f64; 12] = [
    0.03, -0.03, 0.06, -0.06, 0.1, -0.1, 0.15, -0.15, 0.22, -0.22, 0.3, -0.3,
];
/// Windows a followed line may go unconfirmed before it is dropped.
const MAX_MISSES: u32 = 3;
/// Output rate of the history, in multiples of the highest frequency searched.
const OVERSAMPLE: f64 = 4.0;
/// Share of the output Nyquist the decimator keeps.
const KEEP: f64 = 0.8;
/// Shortest stretch of the newest signal (s) in which the window's speed must show a line of
/// its own ([`SpeedTracker::recent_support`]): a window's worth (the daemon's windows are 1 s).
const RECENT_S: f64 = 1.0;
/// Prominence the best line of the speed needs in that stretch. Measured on whitened
/// one-second spectra of Gaussian noise (`the_newest_seconds_line_threshold_on_noise`): a bin
/// exceeds 1.6 with probability 6e-5, 1.2 with 2e-3 (the analytic 1e-7 once written here
/// took the bins for independent exponential powers); with the 20-40 bins searched, noise
/// alone shows a line in about one window in 500. At 1.2, one mains-hum window in 39 still
/// passed check 4 of the shared hostile-input checks.
const RECENT_LINE: f64 = 1.6;
/// Confidence at most of a speed the newest signal does not show.
const UNSUPPORTED: f64 = 0.3;
/// Speeds related to the shaft lines' choice g that the fault families may prefer: g p / q.
const RELATED: [(f64, f64); 10] = [
    (1.0, 2.0),
    (2.0, 1.0),
    (1.0, 3.0),
    (3.0, 1.0),
    (2.0, 3.0),
    (3.0, 2.0),
    (3.0, 4.0),
    (4.0, 3.0),
    (3.0, 5.0),
    (5.0, 3.0),
];

/// Where the tracker looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerSettings {
    pub min_rpm: f64,
    pub max_rpm: f64,
    /// A fixed or nominal speed: searched within +-`within` (fraction), used itself when the
    /// vibration shows no clear line there.
    pub hint: Option<SpeedHint>,
    /// The rig's bearing, whose fault families may settle the octave (None: shaft lines only).
    pub families: Option<FamilySettings>,
}

/// A speed someone stated (a `fixed` rpm, a manifest's nominal rpm) and how far to trust it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedHint {
    pub rpm: f64,
    pub within: f64,
}

/// What the tracker knows about the window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SpeedStatus {
    /// A clear line, followed from window to window.
    Tracking,
    /// Not enough history yet for a confident estimate.
    Acquiring,
    /// No clear shaft line in the history.
    Unclear,
    /// A new line won this window; it is taken once it wins again.
    Jumped,
    /// The hint's own speed is used (no clear line near it).
    Hint,
    /// The vibration clearly turns at the octave above or below the hint's band: its speed
    /// is used, and the hint (a name, a label) is contradicted.
    OffHint,
}

/// The speed of one window.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedSpeed {
    /// Shaft angle and speed over the history, on the stream's clock.
    pub track: SpeedTrack,
    /// Speed at the end of the history, rpm.
    pub rpm: f64,
    /// 0 (a guess) to 1 (a clear line, followed, no rival).
    pub confidence: f64,
    pub status: SpeedStatus,
    /// Half or twice the speed, when the spectrum supports it nearly as well.
    pub rival_rpm: Option<f64>,
    /// Harmonic prominence of the line (natural-log units above the background).
    pub score: f64,
}

impl TrackedSpeed {
    /// The window's speed is not known well enough to classify it.
    pub fn uncertain(&self) -> bool {
        self.confidence < MIN_CONFIDENCE
    }
}

/// The line being followed.
#[derive(Debug, Clone, Copy)]
struct Lock {
    /// Shaft frequency at the end of the history, Hz, and that time (s, stream clock).
    hz: f64,
    t: f64,
    /// A confident estimate (else a guess while acquiring).
    confirmed: bool,
    /// Relative speed trend (1/s) the line was found along.
    trend: f64,
}

impl Lock {
    /// Where the line is predicted at time `t` (s, stream clock), along its trend.
    fn at(&self, t: f64) -> f64 {
        self.hz * (1.0 + self.trend * (t - self.t))
    }
}

/// The streaming tracker (see the module doc). Buffers and FFT plans are made once.
pub struct SpeedTracker {
    fs: f64,
    fmin: f64,
    fmax: f64,
    hint: Option<SpeedHint>,
    /// The rig's whole range (Hz), where a hint's octave may lie.
    range: (f64, f64),
    /// The last window saw the hint's octave ([`super::speed_hint`]).
    off_seen: bool,
    decimator: Decimator,
    fs_d: f64,
    /// Decimated history, oldest first; `cap` samples are kept.
    hist: Vec<f32>,
    cap: usize,
    /// Stream-clock index of the first input since the last restart, and of the next input.
    origin: u64,
    next: Option<u64>,
    /// Input index (since the restart) of the newest decimated sample.
    newest: u64,
    whitener: Whitener,
    spec: Whitened,
    /// Spectra of the span's halves ([`SpeedTracker::residual_trend`]), apart from `spec`
    /// so the span's own spectrum outlives the trend check.
    half_spec: Whitened,
    warped: Vec<f32>,
    lock: Option<Lock>,
    /// A rival line that won the last window (Hz).
    pending: Option<f64>,
    /// Windows since the followed line was last confirmed.
    misses: u32,
    /// The fault families' evidence: the bearing, the envelope of the carrier band decimated
    /// beside `hist` (same length, same times), its whitened spectrum and the history span
    /// that spectrum was taken over.
    families: Option<FamilySettings>,
    env_feed: Option<EnvelopeFeed>,
    env_hist: Vec<f32>,
    env_spec: Whitened,
    env_span: Option<(usize, usize)>,
    /// Spectrum of the newest stretch of the history ([`Self::recent_support`]).
    recent_spec: Whitened,
    /// The joint reading's parts (a lone 1x line counts, speeds read from the harmonics' own
    /// peaks, a comb may be a bearing's train: [`super::speed_comb`]).
    joint: JointParts,
    /// This window's phase fits, by the stretch, speed and trend they were made along: the
    /// newest-second check, the acquiring shortcut and the curving speed often ask for the
    /// same one ([`Self::phase_fit`]).
    phase_fits: Vec<(PhaseKey, Option<PhaseFit>)>,
}

/// What a phase fit was made along: samples of the history (the newest last), speed and
/// trend (bits, so equal inputs are equal keys).
type PhaseKey = (usize, u64, u64);

/// The parts of the joint reading (issue 34), each switchable for measuring one against the
/// others; all off is the reading before issue 34.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointParts {
    /// A lone 1x line counts as shaft evidence ([`Whitened::shaft`]).
    pub lone: bool,
    /// The speed is read from the harmonics' own peaks ([`Whitened::line_speed`]).
    pub line_speed: bool,
    /// A comb may be a bearing's train ([`super::speed_comb`]).
    pub comb: bool,
    /// The speed over the history is read from the harmonics' phase ([`super::speed_phase`]),
    /// which also says whether the newest second still shows the line.
    pub phase: bool,
    /// Where the phase fit over the whole history curves (a fluctuation; very strong evidence,
    /// [`PhaseFit::curved`]) and the newest second shows the line along it, the window's speed
    /// law is the spectrum's (steady along its trend) and the phase smoother's wandering law
    /// averaged by their posterior probabilities ([`PhaseFit::wander`]). Its status and
    /// confidence stay the spectrum's. Without [`Self::phase`] only.
    pub phase_wander: bool,
    /// Where the newest second's spectrum shows no line of the window's speed
    /// ([`RECENT_LINE`], one bin's bar), the matched filter along its harmonics' phase may
    /// ([`PhaseFit::newest_shows_line`]: P < 1e-3 on noise); and while acquiring, a line the
    /// whole history shows above noise and the newest second shows in phase is taken as it
    /// stands, without searching halves and quarters of the history along trends (a steady
    /// line needs no trend, and the best of those 36 searches is often noise's).
    pub newest_in_phase: bool,
    /// While acquiring, the line read in the last window, still the whole history's best line
    /// above noise, is held as it stands (continuity over time) without searching halves and
    /// quarters of the history along trends: the best of those 36 searches then is the same
    /// line along a wrong trend (5 % off at 588 rpm) or a bearing's line taken for a shaft
    /// (an outer race's 45 Hz read as 2,600 rpm), found by chance.
    pub held_line: bool,
}

impl JointParts {
    /// Every part on (`true`) or off.
    pub fn all(on: bool) -> JointParts {
        JointParts {
            lone: on,
            line_speed: on,
            comb: on,
            phase: on,
            phase_wander: on,
            newest_in_phase: on,
            held_line: on,
        }
    }

    /// The tracker's default: every part but the phase reading, which is measured
    /// (`tests/fast/speed_joint.rs`) but not yet on (docs/speed.md: it made mains hum and one
    /// CWRU record confident at a wrong speed); its speed is used where it curves
    /// ([`Self::phase_wander`]), which makes nothing confident.
    pub fn default_on() -> JointParts {
        JointParts {
            phase: false,
            ..JointParts::all(true)
        }
    }
}

impl SpeedTracker {
    /// A tracker for a signal sampled at `fs` Hz.
    pub fn new(settings: TrackerSettings, fs: f64) -> Result<SpeedTracker> {
        let (mut lo, mut hi) = (settings.min_rpm, settings.max_rpm);
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
            bail!("speed range {lo}-{hi} rpm: need 0 < min_rpm < max_rpm");
        }
        if let Some(h) = settings.hint {
            if !(h.rpm.is_finite() && h.rpm > 0.0 && h.within > 0.0 && h.within < 1.0) {
                bail!(
                    "speed hint {} rpm +-{} %: need a positive speed and a band between 0 and 100 %",
                    h.rpm,
                    h.within * 100.0
                );
            }
            (lo, hi) = (h.rpm * (1.0 - h.within), h.rpm * (1.0 + h.within));
        }
        let (fmin, fmax) = (lo / 60.0, hi / 60.0);
        let top = (HARMONICS as f64 + 1.0) * fmax;
        if top > fs / 2.0 {
            bail!(
                "sample rate {fs} Hz is too low to see {HARMONICS} shaft harmonics at {hi} rpm (needs more than {:.0} Hz)",
                2.0 * top
            );
        }
        let factor = ((fs / (OVERSAMPLE * top)).floor() as usize).max(1);
        let fs_d = fs / factor as f64;
        let cap = (HISTORY_REVS / fmin * fs_d).ceil() as usize;
        let env_feed = settings
            .families
            .and_then(|f| EnvelopeFeed::new(fs, factor, KEEP, f.band_top_hz));
        Ok(SpeedTracker {
            fs,
            fmin,
            fmax,
            hint: settings.hint,
            range: (settings.min_rpm / 60.0, settings.max_rpm / 60.0),
            off_seen: false,
            decimator: Decimator::new(factor, KEEP),
            fs_d,
            hist: Vec::with_capacity(2 * cap),
            cap,
            origin: 0,
            next: None,
            newest: 0,
            whitener: Whitener::new(),
            spec: Whitened {
                skip_mains: true,
                interpolate: true,
                lone: true,
                ..Whitened::default()
            },
            half_spec: Whitened {
                skip_mains: true,
                interpolate: true,
                lone: true,
                ..Whitened::default()
            },
            warped: Vec::with_capacity(cap),
            lock: None,
            pending: None,
            misses: 0,
            families: settings.families.filter(|_| env_feed.is_some()),
            env_hist: Vec::with_capacity(if env_feed.is_some() { 2 * cap } else { 0 }),
            env_feed,
            env_spec: Whitened {
                skip_mains: true,
                interpolate: true,
                ..Whitened::default()
            },
            env_span: None,
            recent_spec: Whitened::default(),
            joint: JointParts::default_on(),
            phase_fits: Vec::new(),
        })
    }

    /// Switch the joint reading on (the default) or off (the reading before issue 34: the
    /// mean of five harmonics, the harmonic sum's grid maximum, no comb explained as a
    /// train). For measuring one against the other.
    pub fn set_joint(&mut self, on: bool) {
        self.set_joint_parts(if on {
            JointParts::default_on()
        } else {
            JointParts::all(false)
        });
    }

    /// Search as before issue 37 item 4 (`true`): every grid point of the harmonic sum
    /// evaluated, and a followed line searched a second time along the trend it already had,
    /// instead of the bounded search ([`super::harmonic_bound`]) done once (the default). The
    /// speeds are the same either way; for measuring the cost of one against the other.
    pub fn set_exhaustive(&mut self, on: bool) {
        self.spec.scan = on;
        self.half_spec.scan = on;
        self.env_spec.scan = on;
        self.recent_spec.scan = on;
    }

    /// Switch the joint reading's parts one by one.
    pub fn set_joint_parts(&mut self, parts: JointParts) {
        self.joint = parts;
        self.spec.lone = parts.lone;
        self.half_spec.lone = parts.lone;
    }

    /// Seconds of signal the history holds when full ([`HISTORY_REVS`] at the lowest speed).
    pub fn history_s(&self) -> f64 {
        HISTORY_REVS / self.fmin
    }

    /// Seconds of signal the history holds now.
    pub fn buffered_s(&self) -> f64 {
        self.hist.len() as f64 / self.fs_d
    }

    /// Forget everything (a new stream).
    pub fn reset(&mut self) {
        self.decimator.reset();
        self.hist.clear();
        if let Some(e) = self.env_feed.as_mut() {
            e.reset();
        }
        self.env_hist.clear();
        self.next = None;
        self.lock = None;
        self.pending = None;
        self.misses = 0;
        self.off_seen = false;
    }

    /// Add the samples `x` that start at stream-clock sample `first`; a jump in the clock
    /// restarts the history. Non-finite samples count as 0.
    pub fn push(&mut self, first: u64, x: &[f32]) {
        if self.next != Some(first) {
            self.reset();
            self.origin = first;
        }
        self.next = Some(first + x.len() as u64);
        let (hist, newest) = (&mut self.hist, &mut self.newest);
        self.decimator.push(x, |i, v| {
            hist.push(v);
            *newest = i;
        });
        if let Some(e) = self.env_feed.as_mut() {
            e.push(x, &mut self.env_hist);
        }
        if self.hist.len() >= 2 * self.cap {
            let n = self.hist.len();
            self.hist.copy_within(n - self.cap.., 0);
            self.hist.truncate(self.cap);
            if !self.env_hist.is_empty() {
                self.env_hist.copy_within(n - self.cap.., 0);
                self.env_hist.truncate(self.cap);
            }
        }
    }

    /// Stream-clock time (s) of the newest history sample (the filter's delay removed).
    fn t_newest(&self) -> f64 {
        (self.origin as f64 + self.newest as f64 - self.decimator.delay()) / self.fs
    }

    /// The speed at the end of what was pushed so far. An error only when the history is too
    /// short to say anything (fewer than a few revolutions at the highest speed).
    pub fn estimate(&mut self) -> Result<TrackedSpeed> {
        let n = self.hist.len().min(self.cap);
        let span = n as f64 / self.fs_d;
        if span * self.fmax < MIN_REVS {
            bail!(
                "speed estimate: {span:.2} s of signal so far; at least {:.2} s are needed to see the shaft line at {:.0} rpm ({} s to resolve it down to {:.0} rpm)",
                MIN_REVS / self.fmax,
                self.fmax * 60.0,
                fmt_s(self.history_s()),
                self.fmin * 60.0
            );
        }
        let t_end = self.t_newest();
        self.env_span = None;
        self.phase_fits.clear();
        let mut best = match self.lock.filter(|l| l.confirmed) {
            Some(lock) => self.follow(lock, n),
            None => self.acquire(n),
        };
        // a speed read from a comb's train is seen in the newest stretch by the comb
        best.recent = self.recent_support(best.train_of.unwrap_or(best.hz), best.trend);
        if !best.recent && best.train_of.is_none() && self.joint.newest_in_phase {
            let m = (best.span * self.fs_d).round() as usize;
            best.recent = self
                .phase_fit(m, best.hz, best.trend)
                .is_some_and(|p| p.newest_shows_line());
        }
        let phase = self.phase_reading(&best);
        if let Some(p) = &phase {
            // the line followed in phase through the history and the newest second
            (best.recent, best.phase, best.hz) = (true, true, p.hz_end());
            best.followed = best.followed || self.near_lock(best.hz);
        }
        let mut e = self.decide(best, t_end);
        // the octave is taken once it is seen in two windows in a row, as any jump is
        let off = best.off_hint.filter(|_| best.recent);
        let seen_before = std::mem::replace(&mut self.off_seen, off.is_some());
        if let Some(alt) = off.filter(|_| seen_before) {
            // the lock stays on the band's line; the window gets the vibration's speed
            (e.rpm, e.status, e.rival_rpm) = (alt.hz * 60.0, SpeedStatus::OffHint, None);
            e.confidence = Candidate {
                hz: alt.hz,
                score: alt.score,
                ..best
            }
            .confidence();
            e.track = track_along(alt.hz, best.trend, t_end, best.span);
            return Ok(e);
        }
        if let Some(p) = phase.filter(|_| e.status == SpeedStatus::Tracking) {
            self.apply_phase(&mut e, &p, t_end);
        } else if let Some(p) = self.wandering_reading(&best, &e) {
            self.apply_phase(&mut e, &p, t_end);
        }
        Ok(e)
    }

    /// The speed law where the phase fit over the whole history curves and the newest second
    /// shows the line along it ([`JointParts::phase_wander`]), for a window that reads the
    /// candidate's own line (tracking it, or not yet clear about it; not a hint, a jump or the
    /// vibration off a hint) and whose mean the fit agrees with (within [`FOLLOW_BAND`]): at
    /// every knot of the fit, the spectrum's steady law (the candidate's speed along its trend,
    /// the fit's reference) and the phase's wandering law weighed by the posterior probability
    /// of each ([`PhaseFit::weighed_hz`]). The curve is the phase's evidence, not the
    /// spectrum's: a line too weak for a clear spectrum over the history may still show it
    /// there. (Without the curve's gate, the posterior alone moved
    /// the steady outer race of `tests/fast/speed_joint.rs` to p95 1.2 %: its phases wander
    /// in a way a walk explains; docs/speed.md.)
    fn wandering_reading(&mut self, c: &Candidate, e: &TrackedSpeed) -> Option<PhaseFit> {
        let own = matches!(
            e.status,
            SpeedStatus::Tracking | SpeedStatus::Unclear | SpeedStatus::Acquiring
        );
        if self.joint.phase || !self.joint.phase_wander || !own || c.train_of.is_some() {
            return None;
        }
        // the whole history: the longer the span, the clearer a wander
        let mut p = self.phase_fit(self.cap, c.hz, c.trend)?;
        let mean = p.hz.iter().sum::<f64>() / p.hz.len() as f64;
        let agrees = (mean * 60.0 / e.rpm - 1.0).abs() < FOLLOW_BAND;
        if !(p.curved() && p.newest_shows_line() && agrees) {
            return None;
        }
        p.hz = p.weighed_hz();
        Some(p)
    }

    /// The phase of the candidate's harmonics over the span it was found in
    /// ([`speed_phase::fit`]; joint reading only), when the newest second shows the line
    /// along it.
    fn phase_reading(&mut self, c: &Candidate) -> Option<PhaseFit> {
        if !self.joint.phase {
            return None;
        }
        let m = (c.span * self.fs_d).round() as usize;
        self.phase_fit(m, c.hz, c.trend)
            .filter(PhaseFit::newest_shows_line)
    }

    /// The phase fit ([`speed_phase::fit`]) over the newest `m` samples of the history (at
    /// most all of it) along speed `hz` and trend `r`, made once per window.
    fn phase_fit(&mut self, m: usize, hz: f64, r: f64) -> Option<PhaseFit> {
        let last = self.hist.len();
        let m = m.min(last);
        let key = (m, hz.to_bits(), r.to_bits());
        if let Some((_, p)) = self.phase_fits.iter().find(|(k, _)| *k == key) {
            return p.clone();
        }
        let p = speed_phase::fit(&self.hist[last - m..], self.fs_d, hz, r, RECENT_S);
        self.phase_fits.push((key, p.clone()));
        p
    }

    /// Where the line followed from the last windows is predicted now (Hz), if any: along
    /// its trend when it is trusted, else where it was (a guess's trend is a guess too).
    fn predicted(&self) -> Option<f64> {
        self.lock
            .map(|l| {
                if l.confirmed {
                    l.at(self.t_newest())
                } else {
                    l.hz
                }
            })
            .filter(|p| *p > 0.0)
    }

    /// `hz` is where the line followed is predicted now (within [`FOLLOW_BAND`]).
    fn near_lock(&self, hz: f64) -> bool {
        self.lock
            .is_some_and(|l| (hz / l.at(self.t_newest()) - 1.0).abs() < FOLLOW_BAND)
    }

    /// The window's speed from the phase fit: its track over the history (half a second
    /// beyond at the end's speed), its speed at the end, and the line followed from there.
    fn apply_phase(&mut self, e: &mut TrackedSpeed, p: &PhaseFit, t_end: f64) {
        let mut ts: Vec<f64> = p.t.iter().map(|t| t + t_end).collect();
        let mut hz = p.hz.clone();
        ts.push(t_end + 0.5);
        hz.push(p.hz_end());
        let Ok(track) = SpeedTrack::from_profile(&ts, &hz, SpeedSourceKind::Estimate) else {
            return;
        };
        e.track = track;
        e.rpm = p.hz_end() * 60.0;
        if let Some(l) = self.lock.as_mut().filter(|l| l.t == t_end) {
            l.hz = p.hz_end();
        }
    }

    /// Following a line: the spectrum over [`HISTORY_REVS`] revolutions at the line's speed
    /// (so an accelerating shaft smears no more at 300 than at 3000 rpm), warped along the
    /// trend of the last estimates, with the trend itself refined by a parabola through its
    /// neighbours.
    fn follow(&mut self, lock: Lock, n: usize) -> Candidate {
        let last = self.hist.len();
        let min_n = (MIN_REVS / self.fmax * self.fs_d).ceil() as usize;
        // the trend is held as a constant change in Hz per second (a linear run-up), so
        // relative to the speed now it is smaller than it was relative to the last speed
        let pred = lock.at(self.t_newest());
        let r0 = if pred > 0.0 {
            lock.trend * lock.hz / pred
        } else {
            lock.trend
        };
        // steady: the whole history (finest lines); changing: 20 revolutions of it, or half
        // of it if that is longer (a longer span lifts a line above the noise)
        let m = if r0.abs() < 0.002 {
            n
        } else {
            let revs = (HISTORY_REVS / lock.hz * self.fs_d).ceil() as usize;
            revs.max(self.cap / 2).clamp(min_n.min(n), n)
        };
        let mut best = self.search(last - m, last, r0);
        // the trend left over after warping moves the line between the halves of the span
        if let Some(dr) = self.residual_trend(last - m, last, r0, best.hz) {
            let r1 = (r0 + TREND_GAIN * dr).clamp(-MAX_TREND, MAX_TREND);
            // a trend that moves the line by less than a bin over the span is no trend
            let span = m as f64 / self.fs_d;
            let resolvable = r1.abs() * best.hz * span * span >= 1.0;
            let r = if resolvable { r1 } else { 0.0 };
            // the same trend is the same search (a steady line: every window), done once
            // (twice only when measuring against the search before issue 37 item 4)
            if self.spec.scan || r.to_bits() != r0.to_bits() {
                let c = self.search(last - m, last, r);
                if (c.followed || !best.followed) && c.score >= KEEP_SHARE * best.score {
                    best = c;
                }
            }
        }
        best
    }

    /// The relative trend left in `hist[first..last]` after warping along `r`: the line's
    /// speed in the second half of the span against the first (None when either half shows
    /// no line near `hz`).
    fn residual_trend(&mut self, first: usize, last: usize, r: f64, hz: f64) -> Option<f64> {
        let fs_u = if r == 0.0 {
            self.warped.clear();
            self.warped.extend_from_slice(&self.hist[first..last]);
            self.fs_d
        } else {
            warp(&self.hist[first..last], self.fs_d, r, &mut self.warped)
        };
        let n = self.warped.len();
        let h = n / 2;
        if (h as f64 / fs_u) * hz < MIN_REVS / 2.0 {
            return None;
        }
        let top = (HARMONICS as f64 + 1.0) * self.fmax;
        let mut f = [0.0; 2];
        for (k, (a, b)) in [(0, h), (n - h, n)].into_iter().enumerate() {
            self.whitener
                .whiten_into(&self.warped[a..b], fs_u, (4, 1), top, &mut self.half_spec);
            self.half_spec.mains_spread = r.abs() * (last - first) as f64 / self.fs_d;
            let (line, score) = self.half_spec.best_in(hz * 0.95, hz * 1.05);
            if score < SCORE_NOISE {
                return None;
            }
            f[k] = self.refine_in(&self.half_spec, line);
        }
        // half centres sit at -3/4 and -1/4 of the span (in warped time)
        let span = (n - 1) as f64 / fs_u;
        Some(2.0 * (f[1] - f[0]) / (hz * span))
    }

    /// Looking for a line: the whole history straight, then (while nothing is clear) halves
    /// and quarters of it along a grid of trends, since a fast run-up smears a long history.
    fn acquire(&mut self, n: usize) -> Candidate {
        let last = self.hist.len();
        let mut best = self.search(last - n, last, 0.0);
        if best.confidence() >= MIN_CONFIDENCE {
            return best;
        }
        // the last window's line is still the whole history's best line above noise: the
        // speed holds along it, and trends searched over parts of the history would only add
        // chances for a line read along a wrong trend ([`JointParts::held_line`])
        if self.joint.held_line && best.score > SCORE_NOISE && self.near_lock(best.hz) {
            return best;
        }
        // a line above noise that the newest second shows in phase needs no trend
        let steady = self.joint.newest_in_phase && best.score > SCORE_NOISE;
        if steady
            && best.train_of.is_none()
            && self
                .phase_fit(n, best.hz, 0.0)
                .is_some_and(|p| p.newest_shows_line())
        {
            return best;
        }
        for part in [1, 2, 4] {
            let m = n / part;
            if (m as f64 / self.fs_d) * self.fmax < MIN_REVS {
                break;
            }
            for r in ACQUIRE_TRENDS {
                let c = self.search(last - m, last, r);
                if (c.confidence(), c.score) > (best.confidence(), best.score) {
                    best = c;
                }
            }
        }
        best
    }

    /// The best line of the history `hist[first..last]`, warped along relative trend `r`:
    /// the line followed from the last window when it holds, else the best anywhere.
    fn search(&mut self, first: usize, last: usize, r: f64) -> Candidate {
        let top = (HARMONICS as f64 + 1.0) * self.fmax;
        let span = (last - first) as f64 / self.fs_d;
        let lo = self.fmin.max(MIN_REVS / span);
        let stride = 4;
        if r == 0.0 {
            self.whitener.whiten_into(
                &self.hist[first..last],
                self.fs_d,
                (2, stride),
                top,
                &mut self.spec,
            );
        } else {
            let fs_u = warp(&self.hist[first..last], self.fs_d, r, &mut self.warped);
            self.whitener
                .whiten_into(&self.warped, fs_u, (2, stride), top, &mut self.spec);
            self.spec.mains_spread = r.abs() * span;
        }
        let global = fundamental(&self.spec, lo, self.fmax);
        let mut c = Candidate {
            hz: global.rpm / 60.0,
            score: global.score,
            followed: false,
            trend: r,
            span,
            rival: None,
            unresolved: false,
            by_family: false,
            held: None,
            recent: true,
            phase: false,
            off_hint: None,
            train_of: None,
        };
        if let Some(lock) = self.lock {
            let t = self.t_newest();
            let pred = lock.at(t);
            let band = FOLLOW_BAND + 0.5 * lock.trend.abs() * (t - lock.t);
            let (f, s) = self.spec.best_in(
                (pred * (1.0 - band)).max(lo),
                (pred * (1.0 + band)).min(self.fmax),
            );
            if s >= KEEP_SHARE * global.score {
                (c.hz, c.score, c.followed) = (f, s, true);
                // the octave guard applies to a followed line too: a longer history may
                // now show the half speed it could not resolve before
                let (half, support) = self.spec.odd_support(f / 2.0, 2);
                if f / 2.0 >= lo && support >= 0.5 * s && support > SCORE_NOISE {
                    (c.hz, c.score, c.followed) = (half, self.spec.shaft(half), false);
                    c.held = Some((f, s));
                }
            }
        }
        c.hz = self.refine(c.hz);
        c.rival = self.rival(c.hz);
        self.settle_by_family(&mut c, (first, last), lo);
        c.off_hint = self.off_hint(c.hz, c.score);
        // half this speed is in the rig's range but not yet resolvable in this span
        c.unresolved = lo > self.fmin && c.hz / 2.0 >= self.fmin && c.hz / 2.0 < lo;
        c
    }

    /// Let the bearing's fault families settle what the shaft lines leave open: a related
    /// speed ([`RELATED`]) the shaft spectrum allows and the families prefer replaces the
    /// candidate (which stays as its rival); else an octave rival the families rule out no
    /// longer limits the confidence. Nothing changes without a family.
    fn settle_by_family(&mut self, c: &mut Candidate, span: (usize, usize), lo: f64) {
        let Some(fam) = self.families else {
            return;
        };
        if self.env_span != Some(span) {
            let fs_d = self.fs_d;
            self.whitener.whiten_into(
                &self.env_hist[span.0..span.1],
                fs_d,
                (2, 4),
                KEEP * fs_d / 2.0,
                &mut self.env_spec,
            );
            self.env_span = Some(span);
        }
        let ev = FamilyEvidence::new(&self.env_spec, &fam.orders, KEEP * self.fs_d / 2.0);
        let g = c.hz;
        let mut best: Option<(f64, f64)> = None;
        for (p, q) in RELATED {
            let r = g * p / q;
            if r < lo || r > self.fmax || !self.shaft_allows(r, g) {
                continue;
            }
            if let Some(s) = ev.prefers(r, g) {
                if best.is_none_or(|(_, b)| s > b) {
                    best = Some((r, s));
                }
            }
        }
        let mut bare = false;
        if best.is_none() && self.joint.comb {
            if let Some((r, s, b)) = self.comb_as_train(g, lo) {
                (best, bare) = (Some((r, s)), b);
            }
        }
        if let Some((r, _)) = best {
            // a train read without a line of its own is at its kinematic order exactly, and
            // its evidence is the comb it explains
            let r = if bare { r } else { self.refine(r) };
            c.score = if bare {
                self.spec.shaft(g)
            } else {
                self.explained_score(r, g)
            };
            (c.hz, c.rival, c.by_family) = (r, Some(g), true);
            c.train_of = bare.then_some(g);
            c.followed = self.near_lock(r);
        } else if let Some(r) = c.rival {
            if ev.prefers(g, r).is_some() {
                c.score = self.explained_score(g, r);
                c.by_family = true;
            }
        }
    }

    /// The shaft spectrum allows speed `r` in place of `g`: r's own series stands above noise
    /// (its clarity on the tracker's scale is above 0: [`SCORE_NOISE`]), and r explains every
    /// line of g (g is a multiple of r), or the lines of g it does not explain are no
    /// stronger than a rival's lines ([`RIVAL_SUPPORT`]), or r's series scores nearly as well
    /// ([`KEEP_SHARE`]).
    fn shaft_allows(&self, r: f64, g: f64) -> bool {
        let own = self.spec.shaft(r);
        if own <= SCORE_NOISE {
            return false;
        }
        let on = |f: f64| ((f / r) - (f / r).round()).abs() * r <= 0.005 * f + self.spec.df;
        let tol = 1.5 * self.spec.df;
        let (mut sum, mut n) = (0.0, 0);
        for k in 1..=HARMONICS {
            let f = k as f64 * g;
            if on(f) || on_mains_harmonic(f, tol) {
                continue;
            }
            sum += self.spec.at(f);
            n += 1;
        }
        n == 0 || sum / n as f64 <= RIVAL_SUPPORT || own >= KEEP_SHARE * self.spec.shaft(g)
    }

    /// The speed that explains the shaft lines' choice `g` as a bearing's train
    /// ([`super::speed_comb`]): the clearest shaft line of its own (off g's series) among the
    /// speeds whose BPFO train would sit on g's comb, whose train the envelope shows, and under which
    /// the rest of g's series is noise; with its clarity and false (the line followed from
    /// the last windows stands for a line of its own where this span shows none: then true,
    /// its evidence the comb it explains, as for a bare comb). Where no such speed
    /// shows a line of its own and g's comb has no line at its fundamental
    /// ([`bare_comb`]), the speed at the train's kinematic order whose train the envelope
    /// shows best and under which the rest of g's series is noise, with the train's
    /// support and true.
    fn comb_as_train(&self, g: f64, lo: f64) -> Option<(f64, f64, bool)> {
        let fam = self.families?;
        let top = KEEP * self.fs_d / 2.0;
        // (speed, its own lines' clarity, read without a line of its own in this span)
        let mut best: Option<(f64, f64, bool)> = None;
        for (a, b, order) in comb_spans(g, &fam.orders, lo, self.fmax) {
            // c's evidence from its own lines only: its train and any harmonic of it that
            // falls on g's series are g's lines
            let (mut c, s) = best_own(&self.spec, g, a, b);
            // continuity: the line followed from the last windows, found there over a longer
            // history, stands for a line of its own where this span is too short to show it
            let followed = self
                .predicted()
                .filter(|p| s <= SCORE_NOISE && (a..=b).contains(p));
            if s <= SCORE_NOISE && followed.is_none() {
                continue;
            }
            c = followed.unwrap_or(c);
            if !train_present(&self.env_spec, order, c, top)
                || unexplained(&self.spec, g, c, order).is_some_and(|u| u > RIVAL_SUPPORT)
            {
                continue;
            }
            if best.is_none_or(|(_, v, _)| s > v) {
                best = Some((c, s, followed.is_some()));
            }
        }
        if best.is_some() {
            return best;
        }
        if !bare_comb(&self.spec, g) {
            return None;
        }
        let mut bare: Option<(f64, f64)> = None;
        for (c, order) in comb_speeds(g, &fam.orders, lo, self.fmax) {
            let s = train_support(&self.env_spec, order, c, top);
            if s < FAMILY_PRESENT
                || unexplained(&self.spec, g, c, order).is_some_and(|u| u > RIVAL_SUPPORT)
            {
                continue;
            }
            if bare.is_none_or(|(_, v)| s > v) {
                bare = Some((c, s));
            }
        }
        bare.map(|(c, s)| (c, s, true))
    }

    /// The speed near `hz` read from its harmonics' own peaks (joint reading:
    /// [`Whitened::line_speed`]), else the harmonic sum's maximum between grid points.
    fn refine(&self, hz: f64) -> f64 {
        self.refine_in(&self.spec, hz)
    }

    /// As [`Self::refine`], in spectrum `w`.
    fn refine_in(&self, w: &Whitened, hz: f64) -> f64 {
        if self.joint.line_speed {
            if let Some(f) = w.line_speed(hz) {
                return f;
            }
        }
        refine(w, hz)
    }

    /// The harmonic prominence behind speed `hz`: its own series, or that of `other` when hz
    /// explains every line of it (other a multiple of hz), whichever is stronger.
    fn explained_score(&self, hz: f64, other: f64) -> f64 {
        let k = other / hz;
        let own = self.spec.shaft(hz);
        if k > 1.5 && (k - k.round()).abs() < 0.01 {
            own.max(self.spec.shaft(other))
        } else {
            own
        }
    }

    /// Turn the best candidate into the window's speed, update the lock and the trend.
    fn decide(&mut self, c: Candidate, t_end: f64) -> TrackedSpeed {
        let following = self.lock.is_some_and(|l| l.confirmed);
        let (c, holding) = self.hold_octave(c, following);
        let mut status = SpeedStatus::Tracking;
        if following && !c.followed {
            // a new line won: it is taken once it wins twice in a row
            if self.pending_is(c.hz) {
                self.pending = None;
            } else {
                self.pending = Some(c.hz);
                status = SpeedStatus::Jumped;
            }
        } else if !holding {
            self.pending = None;
        }
        let filled = c.filled();
        let rival = c.rival;
        let mut confidence = c.confidence();
        if status == SpeedStatus::Jumped {
            confidence = confidence.min(0.3);
        } else if confidence < MIN_CONFIDENCE {
            status = if filled < 1.0 {
                SpeedStatus::Acquiring
            } else {
                SpeedStatus::Unclear
            };
        }
        let mut hz = c.hz;
        if let (Some(h), true) = (self.hint, confidence < MIN_CONFIDENCE) {
            hz = h.rpm / 60.0;
            status = SpeedStatus::Hint;
            confidence = 1.0;
        }
        if matches!(status, SpeedStatus::Tracking | SpeedStatus::Hint) {
            self.misses = 0;
        } else {
            self.misses += 1;
        }
        // the line followed is gone, or has left the newest signal (a step, a stop): look afresh
        if self.misses > MAX_MISSES || (following && c.followed && !c.recent) {
            self.forget_lock();
        }
        match status {
            SpeedStatus::Tracking | SpeedStatus::Hint => {
                self.lock = Some(Lock {
                    hz,
                    t: t_end,
                    // a barely clear line is followed, not yet trusted; an octave rival
                    // does not unsettle a line that was already being followed
                    confirmed: status == SpeedStatus::Hint
                        || confidence >= LOCK_CONFIDENCE
                        || (c.followed && c.clear().min(c.filled()) >= LOCK_CONFIDENCE),
                    trend: if status == SpeedStatus::Tracking {
                        c.trend
                    } else {
                        0.0
                    },
                });
            }
            SpeedStatus::Jumped | SpeedStatus::OffHint => {}
            // not yet sure: follow the best guess, without a trend
            SpeedStatus::Acquiring | SpeedStatus::Unclear => {
                if !following {
                    self.lock = Some(Lock {
                        hz,
                        t: t_end,
                        confirmed: false,
                        trend: c.trend,
                    });
                }
            }
        }
        let trend = if status == SpeedStatus::Hint {
            0.0
        } else {
            c.trend
        };
        TrackedSpeed {
            track: track_along(hz, trend, t_end, c.span),
            rpm: hz * 60.0,
            confidence,
            status,
            rival_rpm: rival.map(|f| f * 60.0),
            score: c.score,
        }
    }

    /// Drop the line followed (and any pending one): the next window looks afresh.
    fn forget_lock(&mut self) {
        self.lock = None;
        self.pending = None;
        self.misses = 0;
    }

    /// The newest stretch of the history ([`RECENT_S`], or [`MIN_REVS`] revolutions at `hz`
    /// if longer), warped along `trend`, shows a line of speed `hz`: one of its harmonics 1x-5x
    /// off the mains series stands [`RECENT_LINE`] above its floor within 1 % of where it
    /// belongs. A speed read from a longer history is otherwise the history's, not the
    /// window's: after a step the old line fills most of it (a window wholly after a step
    /// 600 -> 1500 rpm read 600.3 rpm at confidence 0.98).
    fn recent_support(&mut self, hz: f64, trend: f64) -> bool {
        let last = self.hist.len();
        let m = ((RECENT_S.max(MIN_REVS / hz) * self.fs_d).ceil() as usize).min(last);
        if m < 8 {
            return false;
        }
        let fs_u = if trend == 0.0 {
            self.warped.clear();
            self.warped.extend_from_slice(&self.hist[last - m..]);
            self.fs_d
        } else {
            warp(&self.hist[last - m..], self.fs_d, trend, &mut self.warped)
        };
        let top = (HARMONICS as f64 + 1.0) * hz;
        self.whitener
            .whiten_into(&self.warped, fs_u, (2, 1), top, &mut self.recent_spec);
        self.recent_spec.mains_spread = trend.abs() * m as f64 / self.fs_d;
        let w = &self.recent_spec;
        (1..=HARMONICS).any(|k| {
            let f = k as f64 * hz;
            if w.on_mains(f) {
                return false;
            }
            let band = 1.5 * w.df + 0.01 * f;
            let lo = ((f - band) / w.df).ceil().max(0.0) as usize;
            let hi = (((f + band) / w.df).floor() as usize).min(w.prom.len().saturating_sub(1));
            (lo..=hi).any(|i| w.prom[i] >= RECENT_LINE)
        })
    }

    /// The line that won the last window without being taken is at `hz` (its second win).
    fn pending_is(&self, hz: f64) -> bool {
        self.pending
            .is_some_and(|p| (p / hz - 1.0).abs() < FOLLOW_BAND)
    }

    /// Octave continuity: when the octave guard moved a followed line to its half (the
    /// half's odd harmonics crossed half the line's strength), the half is the rival the
    /// followed line already reported, not a new line. The window keeps the followed line,
    /// with the half as its rival (so at most [`MIN_CONFIDENCE`]: ambiguous, not unknown),
    /// and the half is taken once it wins twice in a row, as any jump is. Without this a
    /// line whose half reads at the guard's threshold flips octave every other window, and
    /// every other window is flagged.
    fn hold_octave(&mut self, c: Candidate, following: bool) -> (Candidate, bool) {
        let Some((f, s)) = c.held.filter(|_| following && !c.followed) else {
            return (c, false);
        };
        if self.pending_is(c.hz) || (c.hz / (f / 2.0) - 1.0).abs() >= FOLLOW_BAND {
            return (c, false);
        }
        self.pending = Some(c.hz);
        let held = Candidate {
            hz: f,
            score: s,
            followed: true,
            rival: Some(c.hz),
            by_family: false,
            held: None,
            ..c
        };
        (held, true)
    }

    /// With a hint, the octave of the band's line `hz` that the spectrum clearly shows
    /// instead, inside the rig's range ([`octave_off_hint`]; the fault families, where the
    /// envelope of this span was taken, may keep `hz`).
    fn off_hint(&self, hz: f64, score: f64) -> Option<OffHint> {
        self.hint?;
        let top = KEEP * self.fs_d / 2.0;
        let families = self
            .families
            .as_ref()
            .filter(|_| self.env_span.is_some())
            .map(|f| (f, &self.env_spec, top));
        let alt = octave_off_hint(&self.spec, hz, score, self.range, families)?;
        // read from the octave's own peaks, as every speed is (its 1x line first: the band's
        // line may sit a per cent or two from half or twice it)
        let near = self.spec.peak_near(alt.hz, 0.025 * alt.hz);
        let f = self.refine(near.map_or(alt.hz, |(f, _)| f));
        let hz = if (f / alt.hz - 1.0).abs() < 0.025 {
            f
        } else {
            alt.hz
        };
        Some(OffHint { hz, ..alt })
    }

    /// Half or twice `hz` when the spectrum supports it nearly as well: for half, the odd
    /// harmonics of hz / 2 (the lines it would add) stand out; for twice, the odd harmonics
    /// of `hz` (the lines that rule out 2 hz) do not.
    fn rival(&self, hz: f64) -> Option<f64> {
        if self.hint.is_some() {
            return None;
        }
        let half = hz / 2.0;
        if half >= self.fmin && self.spec.odd_support(half, 2).1 > RIVAL_SUPPORT {
            return Some(half);
        }
        let double = 2.0 * hz;
        if double <= self.fmax && self.spec.score(hz, (1..=HARMONICS).step_by(2)) < RIVAL_SUPPORT {
            return Some(double);
        }
        None
    }
}

/// A line found in one spectrum.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    hz: f64,
    score: f64,
    /// The line followed from the last window (else the best line anywhere).
    followed: bool,
    trend: f64,
    /// Seconds of history the spectrum was taken over.
    span: f64,
    /// Half or twice the speed, when the spectrum supports it nearly as well (Hz).
    rival: Option<f64>,
    /// Half the speed is in range but the span is too short to rule it out.
    unresolved: bool,
    /// The bearing's fault families settled the octave (the rival does not limit confidence).
    by_family: bool,
    /// The followed line (Hz, score) when the octave guard moved the candidate to its half.
    held: Option<(f64, f64)>,
    /// The newest stretch of the signal shows a line of this speed.
    recent: bool,
    /// The harmonics' phase follows the line through the history and the newest second
    /// ([`super::speed_phase`]): a line, however low its prominence.
    phase: bool,
    /// With a hint: the octave the vibration clearly shows instead ([`super::speed_hint`]).
    off_hint: Option<OffHint>,
    /// The comb (Hz) this speed's bearing train makes, where the speed shows no line of its
    /// own ([`super::speed_comb::bare_comb`]): the newest stretch must show the comb.
    train_of: Option<f64>,
}

impl Candidate {
    /// How clearly the line stands above its background (0-1).
    fn clear(&self) -> f64 {
        if self.phase {
            return 1.0;
        }
        ((self.score - SCORE_NOISE) / (SCORE_CLEAR - SCORE_NOISE)).clamp(0.0, 1.0)
    }

    /// How many revolutions the span holds, relative to a fully resolved line (0-1).
    fn filled(&self) -> f64 {
        (self.span * self.hz / FULL_REVS).clamp(0.0, 1.0)
    }

    /// Confidence before continuity: the weaker of clarity and resolution, at most
    /// [`MIN_CONFIDENCE`] with an octave rival.
    fn confidence(&self) -> f64 {
        let c = self.clear().min(self.filled());
        let c = if self.recent { c } else { c.min(UNSUPPORTED) };
        if self.unresolved {
            c.min(0.49 * MIN_CONFIDENCE / 0.5)
        } else if self.rival.is_some() && !self.by_family {
            c.min(MIN_CONFIDENCE)
        } else {
            c
        }
    }
}

/// Sub-grid position of the harmonic-sum maximum near `hz` (a parabola through three
/// points of the search grid).
fn refine(w: &Whitened, hz: f64) -> f64 {
    let step = w.df / (2 * HARMONICS) as f64;
    let (a, b, c) = (w.full(hz - step), w.full(hz), w.full(hz + step));
    let den = a - 2.0 * b + c;
    if !(den < 0.0) || !a.is_finite() || !c.is_finite() {
        return hz;
    }
    hz + step * (0.5 * (a - c) / den).clamp(-0.5, 0.5)
}

/// Resample `x` (rate `fs`, its last sample at t = 0) uniformly in the time `u` a shaft would
/// need at its final speed to turn as far as it did along f(t) = f_end (1 + r t): harmonics of
/// such a shaft become steady lines at multiples of f_end. Returns the rate of the warped
/// samples (per unit of u).
fn warp(x: &[f32], fs: f64, r: f64, out: &mut Vec<f32>) -> f64 {
    let n = x.len();
    out.clear();
    if n < 2 {
        out.extend_from_slice(x);
        return fs;
    }
    let t0 = -((n - 1) as f64) / fs;
    // u(t) = t + r t^2 / 2 is increasing on [t0, 0] while 1 + r t > 0
    let u0 = t0 + 0.5 * r * t0 * t0;
    for j in 0..n {
        let u = u0 * (1.0 - j as f64 / (n - 1) as f64);
        let t = if r.abs() < 1e-12 {
            u
        } else {
            let d = 1.0 + 2.0 * r * u;
            if d <= 0.0 {
                t0
            } else {
                (d.sqrt() - 1.0) / r
            }
        };
        let p = ((t - t0) * fs).clamp(0.0, (n - 1) as f64);
        let i = (p.floor() as usize).min(n - 2);
        let a = p - i as f64;
        out.push(((1.0 - a) * x[i] as f64 + a * x[i + 1] as f64) as f32);
    }
    (n - 1) as f64 / -u0
}

/// The speed track of a history of `span` s ending at `t_end` with speed `hz` there and
/// relative trend `r`: constant when the trend changes the speed by less than 0.1 % over it.
fn track_along(hz: f64, r: f64, t_end: f64, span: f64) -> SpeedTrack {
    let constant =
        || SpeedTrack::constant(hz * 60.0, SpeedSourceKind::Estimate).expect("a positive speed");
    if (r * span).abs() < 0.001 {
        return constant();
    }
    // knots over the history and half a second beyond its end (so the end of a window is
    // not the end of the profile, where a monotone cubic holds the last segment's mean)
    const KNOTS: usize = 17;
    let t0 = t_end - span;
    let t1 = t_end + 0.5;
    let ts: Vec<f64> = (0..KNOTS)
        .map(|k| t0 + (t1 - t0) * k as f64 / (KNOTS - 1) as f64)
        .collect();
    let fs: Vec<f64> = ts
        .iter()
        .map(|&t| (hz * (1.0 + r * (t - t_end))).max(1e-3))
        .collect();
    SpeedTrack::from_profile(&ts, &fs, SpeedSourceKind::Estimate).unwrap_or_else(|_| constant())
}

fn fmt_s(s: f64) -> String {
    format!("{s:.2}")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shaft harmonics along a speed law (Hz at t), mains 50 Hz lines, noise.
    fn shaft(fs: f64, seconds: f64, hz: impl Fn(f64) -> f64, seed: u64) -> Vec<f32> {
        let mut s = seed;
        let mut theta = 0.0;
        (0..(fs * seconds) as usize)
            .map(|i| {
                let t = i as f64 / fs;
                theta += hz(t) / fs;
                let mut v = 0.0;
                for k in 1..=6 {
                    let a = if k % 2 == 1 { 0.4 } else { 1.0 } / k as f64;
                    v += a * (std::f64::consts::TAU * k as f64 * theta + k as f64).sin();
                }
                for k in 1..=3 {
                    v += 0.8 * (std::f64::consts::TAU * 50.0 * k as f64 * t).sin();
                }
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                v += ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0;
                v as f32
            })
            .collect()
    }

    fn run(x: &[f32], fs: f64, settings: TrackerSettings, hop: usize) -> Vec<(f64, TrackedSpeed)> {
        let mut tr = SpeedTracker::new(settings, fs).unwrap();
        let mut out = Vec::new();
        for (k, c) in x.chunks(hop).enumerate() {
            tr.push((k * hop) as u64, c);
            if let Ok(e) = tr.estimate() {
                out.push((((k + 1) * hop) as f64 / fs, e));
            }
        }
        out
    }

    fn range(lo: f64, hi: f64) -> TrackerSettings {
        TrackerSettings {
            min_rpm: lo,
            max_rpm: hi,
            hint: None,
            families: None,
        }
    }

    #[test]
    fn steady_speeds_within_half_a_percent_once_the_history_is_full() {
        let fs = 5_000.0;
        for rpm in [300.0, 600.0, 1800.0] {
            let x = shaft(fs, 8.0, |_| rpm / 60.0, 7);
            let est = run(&x, fs, range(250.0, 2000.0), 2_500);
            let full = HISTORY_REVS / (250.0 / 60.0);
            for (t, e) in est.iter().filter(|(t, _)| *t >= full) {
                assert!(
                    (e.rpm / rpm - 1.0).abs() < 0.005 && !e.uncertain(),
                    "{rpm} rpm at {t} s: {e:?}"
                );
            }
        }
    }

    #[test]
    fn a_run_up_is_followed() {
        // 300 -> 1800 rpm in 20 s: 25 % per second at the start
        let fs = 5_000.0;
        let law = |t: f64| (300.0 + 75.0 * t) / 60.0;
        let x = shaft(fs, 20.0, law, 3);
        let est = run(&x, fs, range(250.0, 2000.0), 2_500);
        let mut errs = Vec::new();
        for (t, e) in est.iter().filter(|(t, _)| *t >= 8.0) {
            // the window's mean speed against the truth's (the law is linear: its mid-point)
            let truth = 60.0 * law(t - 0.5);
            let err = e.track.mean_rpm(t - 1.0, *t) / truth - 1.0;
            assert!(
                err.abs() < 0.0075 && !e.uncertain(),
                "at {t} s: {err:+.4} ({e:?})"
            );
            errs.push(err.abs());
        }
        errs.sort_by(f64::total_cmp);
        assert!(
            errs[errs.len() / 2] < 0.003,
            "median error {}",
            errs[errs.len() / 2]
        );
    }

    #[test]
    fn blocks_do_not_change_the_estimate() {
        let fs = 5_000.0;
        let x = shaft(fs, 6.0, |_| 17.0, 11);
        let mut a = SpeedTracker::new(range(300.0, 3000.0), fs).unwrap();
        let mut b = SpeedTracker::new(range(300.0, 3000.0), fs).unwrap();
        a.push(0, &x);
        for (k, c) in x.chunks(97).enumerate() {
            b.push((k * 97) as u64, c);
        }
        assert_eq!(a.estimate().unwrap(), b.estimate().unwrap());
    }

    #[test]
    fn noise_is_not_a_speed() {
        let fs = 5_000.0;
        let mut s = 5u64;
        let x: Vec<f32> = (0..(fs * 8.0) as usize)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32
            })
            .collect();
        let est = run(&x, fs, range(300.0, 3000.0), 2_500);
        assert!(est.iter().all(|(_, e)| e.uncertain()), "{est:?}");
    }

    /// A candidate the octave guard moved from a followed 20 Hz line (score 3) to its half.
    fn moved_to_half() -> Candidate {
        Candidate {
            hz: 10.0,
            score: 2.1,
            followed: false,
            trend: 0.0,
            span: 2.4,
            rival: None,
            unresolved: false,
            by_family: false,
            held: Some((20.0, 3.0)),
            recent: true,
            phase: false,
            off_hint: None,
            train_of: None,
        }
    }

    fn followed_line() -> Candidate {
        Candidate {
            hz: 20.0,
            score: 3.0,
            followed: true,
            rival: Some(10.0),
            held: None,
            ..moved_to_half()
        }
    }

    /// The line of a machine whose half-speed lines hover at the octave guard's threshold
    /// (HIT-SM's OR8_1200 at 1204 rpm: 1.5x and 2.5x lines): the half wins every other
    /// window. Each such window keeps the followed line, ambiguous but not uncertain; the
    /// half is taken when it wins twice in a row.
    #[test]
    fn the_followed_lines_own_half_is_held_off_until_it_wins_twice() {
        let mut tr = SpeedTracker::new(range(500.0, 1500.0), 5_000.0).unwrap();
        tr.lock = Some(Lock {
            hz: 20.0,
            t: 0.0,
            confirmed: true,
            trend: 0.0,
        });
        for (k, c) in [
            moved_to_half(),
            followed_line(),
            moved_to_half(),
            followed_line(),
        ]
        .into_iter()
        .enumerate()
        {
            let e = tr.decide(c, 0.5 * (k + 1) as f64);
            assert!((e.rpm - 1200.0).abs() < 1e-9, "window {k}: {e:?}");
            assert!(!e.uncertain(), "window {k}: {e:?}");
            assert_eq!(e.rival_rpm, Some(600.0), "window {k}");
        }
        let first = tr.decide(moved_to_half(), 2.5);
        assert!((first.rpm - 1200.0).abs() < 1e-9, "{first:?}");
        let second = tr.decide(moved_to_half(), 3.0);
        assert!((second.rpm - 600.0).abs() < 1e-9, "{second:?}");
        assert_eq!(second.status, SpeedStatus::Tracking);
    }

    #[test]
    fn a_hint_is_used_where_the_line_is_unclear() {
        let fs = 5_000.0;
        let mut s = 9u64;
        let x: Vec<f32> = (0..(fs * 8.0) as usize)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32
            })
            .collect();
        let hint = TrackerSettings {
            hint: Some(SpeedHint {
                rpm: 900.0,
                within: 0.1,
            }),
            ..range(300.0, 3000.0)
        };
        let est = run(&x, fs, hint, 2_500);
        let (_, last) = est.last().unwrap();
        assert_eq!((last.status, last.rpm), (SpeedStatus::Hint, 900.0));
        // and a clear line 6 % off the hint replaces it
        let y = shaft(fs, 8.0, |_| 954.0 / 60.0, 4);
        let est = run(&y, fs, hint, 2_500);
        let (_, last) = est.last().unwrap();
        assert!((last.rpm / 954.0 - 1.0).abs() < 0.005, "{last:?}");
        assert_eq!(last.status, SpeedStatus::Tracking);
    }

    #[test]
    fn the_newest_seconds_line_threshold_on_noise() {
        // whitened one-second spectra of Gaussian noise, as `recent_support` takes them: the
        // share of bins at or above RECENT_LINE is what its doc says (6e-5)
        let (fs, n) = (1_000.0, 1_000);
        let mut whitener = Whitener::new();
        let mut w = Whitened::default();
        let (mut seed, mut above, mut bins) = (0x2545_f491_4f6c_dd1du64, 0usize, 0usize);
        let mut gauss = move || {
            let mut u = || {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            ((-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()) as f32
        };
        for _ in 0..1000 {
            let x: Vec<f32> = (0..n).map(|_| gauss()).collect();
            whitener.whiten_into(&x, fs, (2, 1), 400.0, &mut w);
            // away from DC and the top, where the running median is one-sided
            let body = &w.prom[40..w.prom.len() - 40];
            above += body.iter().filter(|&&p| p >= RECENT_LINE).count();
            bins += body.len();
        }
        let rate = above as f64 / bins as f64;
        assert!(
            (3e-5..1.3e-4).contains(&rate),
            "noise at or above {RECENT_LINE}: {above} of {bins} bins ({rate:.1e})"
        );
    }

    #[test]
    fn too_little_signal_is_a_clear_error() {
        let mut tr = SpeedTracker::new(range(300.0, 3000.0), 5_000.0).unwrap();
        tr.push(0, &[0.0; 500]);
        let e = tr.estimate().unwrap_err().to_string();
        assert!(e.contains("0.10 s of signal so far"), "{e}");
    }
}
