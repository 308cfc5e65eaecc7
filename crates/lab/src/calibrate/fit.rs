//! Greedy forward selection: simulate every measured operating point, then repeatedly try
//! each catalog effect not yet added (bounded search on the fit part, on the effect's own
//! components; accepted effects whose view it moves are re-fitted with it), and add the one
//! that cuts its own components most, if the held-out part confirms it ([`accepts`]). Stops
//! when nothing passes. The trials of a round run in parallel. Views are cached by
//! (simulation section, operating point), engine runs by the section's engine part in a
//! least-recently-used cache as large as [`ENGINE_CACHE_BYTES`] allows, so effects of the
//! sensor stage (noise, lines, shaft and half-order lines) do not re-run the mechanics, and
//! the mechanics are kept apart from the structural modes ([`crate::sim::split`]), so the
//! `resonance` effect re-runs only the modes. A measured recording is analysed whole,
//! its views averaged over [`views::SEGMENT_S`] segments; its simulated twin is one segment
//! long, and the twin's `speed` view comes from its speed profile over the whole measured
//! length ([`views::compute`]).

use super::catalog::{self, Effect, ALL};
use super::error::{self, least_cut, min_cut, ErrorComponent, ErrorParts};
use super::locate::{locate, Unexplained};
use super::measured::{several_speeds, Measured};
use super::modes::Mode;
use super::search;
use super::speed_line;
use super::timing::{RecordingTime, RoundTime, Stage, StageTime, Timings};
use super::views::{self, Parts, Views};
use crate::config::simulation::SimulationConfig;
use crate::config::{RigConfig, SpeedConfig};
use crate::dsp::speed::SpeedTrack;
use crate::sim::{
    dominant_resonance_hz, rig_simulation, run_engine, sensor, split, unit_scale, EngineRun,
    Scenario, SpeedProfile,
};
use crate::vocabulary::SpeedSourceKind;
use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, Mutex};

/// Relative cut an effect must make in its own components on the fit part, and the
/// multiple of their smallest meaningful cut ([`least_cut`]) it must reach...
pub const FIT_CUT: (f64, f64) = (0.20, 1.0);
/// ... and on the held-out part.
pub const HELD_CUT: (f64, f64) = (0.10, 0.6);

/// Acceptance rule. On the effect's own error components `own` (before, after): the fit
/// part drops by >= 20 % and by at least their smallest meaningful cut ([`least_cut`]), AND
/// the held-out part by >= 10 % and 0.6 times that. And the whole error (all components, before,
/// after) drops on both parts: an effect that mends its own view but breaks others is not
/// taken.
pub fn accepts(
    own: &[ErrorComponent],
    fit: (f64, f64),
    held: (f64, f64),
    fit_total: (f64, f64),
    held_total: (f64, f64),
) -> bool {
    let floor = least_cut(own);
    let cut = |(b, a): (f64, f64), (rel, abs): (f64, f64)| b - a >= rel * b && b - a >= abs * floor;
    cut(fit, FIT_CUT)
        && cut(held, HELD_CUT)
        && fit_total.1 < fit_total.0
        && held_total.1 < held_total.0
}

/// One candidate effect as tried in one round.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    pub name: String,
    /// The fitted parameters; for an accepted effect, its final ones (after any re-fit,
    /// while the error fields stay those of the round it was added in).
    pub params: BTreeMap<String, f64>,
    pub fit_before: f64,
    pub fit_after: f64,
    pub held_before: f64,
    pub held_after: f64,
    /// The effect's own components (search and acceptance), fit and held-out part.
    pub own: Vec<String>,
    pub own_fit_before: f64,
    pub own_fit_after: f64,
    pub own_held_before: f64,
    pub own_held_after: f64,
    /// Error over all recordings before / after.
    pub error_before: f64,
    pub error_after: f64,
    /// All components over all recordings after the effect.
    pub components_after: ErrorParts,
    pub accepted: bool,
    pub evaluations: usize,
    /// Wall seconds of this trial (search, re-fits and final errors; with the trials of a
    /// round in parallel, including time spent waiting for a core).
    pub seconds: f64,
    /// Accepted effects re-fitted together with this one.
    pub refits: Vec<Refit>,
    /// The free effect this shaft-locked one was preferred over, and why ([`choose`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preferred_over: Option<String>,
    /// Parameters that ended within 1 % of a search bound (the bound, not the data, may
    /// have set them).
    pub at_bound: Vec<String>,
    #[serde(skip)]
    pub effect: Option<Effect>,
    #[serde(skip)]
    pub values: Vec<f64>,
    /// The simulation section with this effect (and its re-fits).
    #[serde(skip)]
    pub candidate: Option<SimulationConfig>,
}

/// An accepted effect re-fitted when a later one moved its view.
#[derive(Debug, Clone, Serialize)]
pub struct Refit {
    pub name: String,
    pub params: BTreeMap<String, f64>,
    /// Parameters the re-fit left at a search bound.
    pub at_bound: Vec<String>,
    /// Position in the accepted list.
    #[serde(skip)]
    pub index: usize,
    #[serde(skip)]
    pub values: Vec<f64>,
}

/// The outcome of a calibration.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub fit_part: Vec<bool>,
    pub before: ErrorParts,
    pub after: ErrorParts,
    pub accepted: Vec<Trial>,
    pub rounds: Vec<Vec<Trial>>,
    pub unexplained: Vec<Unexplained>,
    pub calibrated: SimulationConfig,
    pub measured_views: Vec<Views>,
    pub views_before: Vec<Views>,
    pub views_after: Vec<Views>,
    /// Where the calibration spent its time ([`Timings`]).
    pub timings: Vec<StageTime>,
    /// The same per measured recording.
    pub recording_times: Vec<RecordingTime>,
    /// Wall time of each round and its trials.
    pub round_times: Vec<RoundTime>,
    /// Wall seconds of the measured recordings' views, and of the whole calibration.
    pub measured_views_wall_s: f64,
    pub wall_s: f64,
    /// The mode the fit part's healthy recordings ring, with the damping its half-power width
    /// gives `looseness_impacts` ([`catalog::Context::ring`]), if it could be read.
    pub ring: Option<super::ring_width::RingWidth>,
}

/// How the calibration runs. [`Options::default`] is the normal way; [`Options::baseline`]
/// is the way it ran before recordings were analysed whole (each measured recording as one
/// piece with a twin as long as it, trials one after the other, the engine cache emptied
/// when full): `rigmon bench calibrate` times both on the same data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// Measured views averaged over [`views::SEGMENT_S`] segments and twins one segment long
    /// (else one piece, the twin as long as the recording).
    pub segmented: bool,
    /// The trials of a round in parallel.
    pub parallel_trials: bool,
    /// Least-recently-used engine cache (else emptied whenever it is full).
    pub engine_lru: bool,
    /// While an effect's parameters are searched, simulate and compare only what its own
    /// components read ([`Twin::error_of`]; else every view of every recording).
    pub own_views: bool,
    /// Do not try again an effect the last round ruled out ([`ruled_out`]).
    pub skip_ruled_out: bool,
    /// Run the mechanics apart from the structural modes ([`crate::sim::split`]), so a
    /// twin that differs only in its resonances (the `resonance` effect) re-runs the modes
    /// alone; else every new section runs the whole engine.
    pub structure_apart: bool,
    /// Keep as many engine runs per recording as [`ENGINE_CACHE_BYTES`] holds (at least
    /// [`ENGINE_CACHE_PER_OP`]; else that many), so a later round's search that revisits a
    /// section does not simulate it again.
    pub engine_cache_by_memory: bool,
    /// Search `looseness_impacts` whatever the recordings show
    /// ([`catalog::WITH_LOOSENESS_IMPACTS`]); without it, only where they show a loose
    /// housing's landings ([`shows_landings`]), else the catalog is [`ALL`].
    pub looseness_impacts: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            segmented: true,
            parallel_trials: true,
            engine_lru: true,
            own_views: true,
            skip_ruled_out: true,
            structure_apart: true,
            engine_cache_by_memory: true,
            looseness_impacts: false,
        }
    }
}

impl Options {
    /// The calibration as it ran before issue 37: every open effect tried in every round.
    pub fn before_issue_37() -> Self {
        Options {
            skip_ruled_out: false,
            ..Options::first_issue_37_pass()
        }
    }

    /// The calibration as the first pass at issue 37 left it (effects ruled out are not
    /// tried again, but every section the search visits re-runs the whole engine, and 8
    /// engine runs are kept per recording): what `rigmon bench calibrate` compares with.
    pub fn first_issue_37_pass() -> Self {
        Options {
            structure_apart: false,
            engine_cache_by_memory: false,
            ..Options::default()
        }
    }

    /// The calibration as it ran before whole-recording analysis (see [`Options`]).
    pub fn baseline() -> Self {
        Options {
            segmented: false,
            parallel_trials: false,
            engine_lru: false,
            own_views: false,
            skip_ruled_out: false,
            structure_apart: false,
            engine_cache_by_memory: false,
            looseness_impacts: false,
        }
    }
}

/// Engine runs by key, least recently used evicted first.
struct EngineCache {
    runs: HashMap<(String, usize), (Arc<EngineRun>, u64)>,
    clock: u64,
    capacity: usize,
    lru: bool,
}

impl EngineCache {
    fn get(&mut self, key: &(String, usize)) -> Option<Arc<EngineRun>> {
        self.clock += 1;
        let now = self.clock;
        self.runs.get_mut(key).map(|(r, used)| {
            *used = now;
            r.clone()
        })
    }

    fn insert(&mut self, key: (String, usize), run: Arc<EngineRun>) {
        self.clock += 1;
        if self.runs.len() >= self.capacity {
            if self.lru {
                if let Some(oldest) = self
                    .runs
                    .iter()
                    .min_by_key(|(_, (_, used))| *used)
                    .map(|(k, _)| k.clone())
                {
                    self.runs.remove(&oldest);
                }
            } else {
                self.runs.clear();
            }
        }
        self.runs.insert(key, (run, self.clock));
    }
}

/// Measured recordings and their simulated twins.
pub struct Twin<'a> {
    pub rig: &'a RigConfig,
    pub ops: &'a [Measured],
    pub measured: Vec<Views>,
    /// Views by (simulation section, operating point).
    views: Mutex<HashMap<(String, usize), Arc<Views>>>,
    /// Views with only some groups computed, by (section, operating point, groups).
    partial: Mutex<HashMap<(String, usize, Parts), Arc<Views>>>,
    /// Engine runs by (engine part of the section, operating point): effects that change
    /// only the sensor stage reuse them. Bounded (see [`ENGINE_CACHE_PER_OP`]).
    engines: Mutex<EngineCache>,
    /// Runs of the mechanics alone with their housing forces ([`Options::structure_apart`]),
    /// by (the section's [`split::mechanics_part`], operating point): a twin that differs
    /// only in its structural modes adds them to one of these. Bounded (see
    /// [`MECHANICS_CACHE_BYTES`]).
    mechanics: Mutex<EngineCache>,
    /// Factor from the classifier channel's unit to m/s^2.
    pub unit_to_m_s2: f64,
    pub options: Options,
    /// Time per stage.
    pub timings: Timings,
}

/// Engine runs kept per operating point: every trial of a round keeps its own base run and
/// the run it is varying, so with the trials in parallel the recent runs are a few per
/// effect that changes the mechanics.
pub const ENGINE_CACHE_PER_OP: usize = 8;
/// The same, in the baseline (emptied when full).
pub const ENGINE_CACHE_PER_OP_BASELINE: usize = 4;
/// Memory the engine runs kept may take ([`Options::engine_cache_by_memory`]), bytes: a run
/// of a 2 s twin at 12.8 kHz takes about 0.4 MB, so about 200 runs per recording of three.
pub const ENGINE_CACHE_BYTES: f64 = 256e6;
/// Memory the runs of the mechanics with their housing forces may take, bytes (a 2.56 s
/// twin at 12.8 kHz, 10x oversampled, keeps about 9 MB of forces; at least 4 runs per
/// recording are kept whatever their size).
pub const MECHANICS_CACHE_BYTES: f64 = 160e6;

/// How many engine runs per measured recording fit in `bytes`: a twin's signals and
/// shaft angles at the recording's rate (and with `forces`, its housing forces at the
/// internal rate from the warm-up on).
fn runs_within(bytes: f64, rig: &RigConfig, ops: &[Measured], forces: bool) -> usize {
    let channels = rig.acceleration_channels().count().max(1) as f64;
    let oversampling = rig
        .simulation
        .as_ref()
        .map_or(10.0, |s| f64::from(s.oversampling));
    let warmup = rig.simulation.as_ref().map_or(0.3, |s| s.warmup_s);
    let largest = ops
        .iter()
        .map(|m| {
            let twin = views::twin_seconds(&m.recording);
            let fs = m.recording.sample_rate;
            let mut b = twin * fs * (channels + 1.0) * 8.0;
            if forces {
                b += (twin + warmup) * fs * oversampling * 24.0;
            }
            b
        })
        .fold(1.0, f64::max);
    (bytes / (largest * ops.len().max(1) as f64)) as usize
}

/// The speed track of a simulated twin over `seconds` as the rig's speed source would
/// read it: a tacho or an estimate follow the twin's speed profile (the sine of
/// `[simulation.speed_fluctuation]`, else constant); a fixed speed stays fixed and the
/// `recording` source takes the stored mean speed, as for any simulated recording.
pub fn twin_speed_track(
    rig: &RigConfig,
    sim: &SimulationConfig,
    rpm: f64,
    seconds: f64,
) -> Result<SpeedTrack> {
    let profile = match &sim.speed_fluctuation {
        Some(f) => SpeedProfile::Sine {
            rpm,
            amplitude_rpm: f.fraction * rpm,
            period_s: f.period_s,
        },
        None => SpeedProfile::Constant { rpm },
    };
    match &rig.speed {
        SpeedConfig::Fixed { rpm, .. } => SpeedTrack::fixed(*rpm),
        SpeedConfig::Recording { .. } => {
            SpeedTrack::constant(profile.mean_rpm(seconds), SpeedSourceKind::Recording)
        }
        _ => {
            let n = (seconds * 100.0).ceil() as usize + 2;
            let t: Vec<f64> = (0..n).map(|i| i as f64 / 100.0).collect();
            let hz: Vec<f64> = t.iter().map(|&ti| profile.rpm_at(ti) / 60.0).collect();
            SpeedTrack::from_profile(&t, &hz, SpeedSourceKind::Simulator)
        }
    }
}

impl<'a> Twin<'a> {
    pub fn new(rig: &'a RigConfig, ops: &'a [Measured]) -> Result<Self> {
        Self::with_options(rig, ops, Options::default())
    }

    pub fn with_options(rig: &'a RigConfig, ops: &'a [Measured], options: Options) -> Result<Self> {
        let timings = Timings::for_recordings(ops.len());
        let measured = ops
            .par_iter()
            .enumerate()
            .map(|(i, m)| {
                let v = timings.time_op(Stage::MeasuredViews, Some(i), || {
                    if options.segmented {
                        views::compute(&m.recording, rig, &m.faults)
                    } else {
                        whole_piece(&m.recording, rig, &m.faults)
                    }
                });
                v.with_context(|| format!("views of {}", m.name))
            })
            .collect::<Result<Vec<_>>>()?;
        let ch = rig
            .classifier_channel()
            .or_else(|| rig.acceleration_channels().next())
            .context("the rig has no acceleration channel")?;
        let unit_to_m_s2 = ch.sensitivity / unit_scale(&ch.unit, &ch.name)?;
        let per_op = if options.engine_cache_by_memory {
            runs_within(ENGINE_CACHE_BYTES, rig, ops, false).max(ENGINE_CACHE_PER_OP)
        } else if options.engine_lru {
            ENGINE_CACHE_PER_OP
        } else {
            ENGINE_CACHE_PER_OP_BASELINE
        };
        let mech_per_op = runs_within(MECHANICS_CACHE_BYTES, rig, ops, true).max(4);
        Ok(Twin {
            rig,
            ops,
            measured,
            unit_to_m_s2,
            views: Mutex::new(HashMap::new()),
            partial: Mutex::new(HashMap::new()),
            engines: Mutex::new(EngineCache {
                runs: HashMap::new(),
                clock: 0,
                capacity: per_op * ops.len(),
                lru: options.engine_lru,
            }),
            mechanics: Mutex::new(EngineCache {
                runs: HashMap::new(),
                clock: 0,
                capacity: mech_per_op * ops.len(),
                lru: true,
            }),
            options,
            timings,
        })
    }

    /// Views of the simulated twin of operating point `i`.
    pub fn simulated(&self, sim: &SimulationConfig, i: usize) -> Result<Arc<Views>> {
        self.simulated_parts(sim, i, Parts::ALL)
    }

    /// The groups `parts` of the views of the simulated twin of operating point `i` (all of
    /// them when the full views are cached already, or in the baseline); with none, the
    /// twin is not simulated at all (its `speed` and `mode` come from the section).
    pub fn simulated_parts(
        &self,
        sim: &SimulationConfig,
        i: usize,
        parts: Parts,
    ) -> Result<Arc<Views>> {
        let key = (serde_json::to_string(sim)?, i);
        if let Some(v) = self.views.lock().expect("cache").get(&key) {
            return Ok(v.clone());
        }
        let parts = if self.options.segmented {
            parts
        } else {
            Parts::ALL
        };
        let partial_key = (key.0.clone(), i, parts);
        if parts != Parts::ALL {
            if let Some(v) = self.partial.lock().expect("cache").get(&partial_key) {
                return Ok(v.clone());
            }
        }
        let m = &self.ops[i];
        let mut s = sim.clone();
        s.sample_rate_hz = Some(m.recording.sample_rate);
        let dur = m.recording.duration_s();
        let twin_s = if self.options.segmented {
            views::twin_seconds(&m.recording)
        } else {
            dur
        };
        let sc = Scenario::constant(&m.faults, m.rpm, twin_s, 1000 + i as u64);
        let rec = if parts.is_empty() {
            None
        } else {
            let run = self
                .engine_run(&s, &sc, i)
                .with_context(|| format!("simulating the twin of {}", m.name))?;
            Some(self.timings.time_op(Stage::Sensor, Some(i), || {
                sensor::finish(self.rig, &sc.overrides.apply(&s), &sc, &run)
            })?)
        };
        let mut v = self
            .timings
            .time_op(Stage::SimViews, Some(i), || -> Result<Views> {
                if !self.options.segmented {
                    let rec = rec.as_ref().expect("the baseline computes every view");
                    return whole_piece(rec, self.rig, &m.faults);
                }
                let mut v = match &rec {
                    Some(rec) => views::compute_parts(rec, self.rig, &m.faults, parts)?,
                    None => Views {
                        rpm: m.rpm,
                        healthy: m.faults.is_empty(),
                        seconds: twin_s,
                        segments: 1,
                        ..Views::default()
                    },
                };
                let track = twin_speed_track(self.rig, &s, m.rpm, dur)?;
                v.speed = views::speed_view(&track, dur, track.mean_rpm(0.0, dur));
                v.seconds = dur;
                Ok(v)
            })?;
        // the simulated side of `modes` is the model's dominant mode (see `error`)
        if let Some(hz) = model_mode_hz(self.rig, &s) {
            v.mode = Mode {
                hz,
                prominent: true,
            };
        }
        let v = Arc::new(v);
        if parts == Parts::ALL {
            self.views.lock().expect("cache").insert(key, v.clone());
        } else {
            let mut partial = self.partial.lock().expect("cache");
            partial.insert(partial_key, v.clone());
        }
        Ok(v)
    }

    /// The engine run of section `s` for operating point `i` (scenario `sc`): from the
    /// cache, else (with [`Options::structure_apart`]) its mechanics from their own cache or
    /// run once, plus its structural modes.
    fn engine_run(&self, s: &SimulationConfig, sc: &Scenario, i: usize) -> Result<Arc<EngineRun>> {
        let engine_key = (serde_json::to_string(&s.engine_part())?, i);
        if let Some(r) = self.engines.lock().expect("cache").get(&engine_key) {
            return Ok(r);
        }
        let r = if self.options.structure_apart {
            let mech_key = (serde_json::to_string(&split::mechanics_part(s))?, i);
            let cached = self.mechanics.lock().expect("cache").get(&mech_key);
            let mech = match cached {
                Some(m) => m,
                None => {
                    let m = Arc::new(self.timings.time_op(Stage::Engine, Some(i), || {
                        split::run_mechanics(self.rig, s, sc)
                    })?);
                    let mut cache = self.mechanics.lock().expect("cache");
                    cache.insert(mech_key, m.clone());
                    m
                }
            };
            self.timings.time_op(Stage::Engine, Some(i), || {
                mech.with_resonances(&s.structure.resonances)
            })?
        } else {
            self.timings
                .time_op(Stage::Engine, Some(i), || run_engine(self.rig, s, sc))?
        };
        let r = Arc::new(r);
        let mut cache = self.engines.lock().expect("cache");
        cache.insert(engine_key, r.clone());
        Ok(r)
    }

    /// The sum of the named components of the mean error over the operating points `idx`
    /// (`error(sim, idx)?.of(own)`), computing only what they read: the view groups they
    /// need ([`Parts::for_components`]), on the recordings they apply to. The same number
    /// as the full [`Twin::error`] gives; in the baseline, that is what it runs.
    pub fn error_of(
        &self,
        sim: &SimulationConfig,
        idx: &[usize],
        own: &[ErrorComponent],
    ) -> Result<f64> {
        if !self.options.own_views {
            return Ok(self.error(sim, idx)?.of(own));
        }
        let mode_from_spectrum = model_mode_hz(self.rig, sim).is_none();
        let parts = Parts::for_components(own, mode_from_spectrum);
        let applying: Vec<usize> = idx
            .iter()
            .copied()
            .filter(|&i| own.iter().any(|&c| error::applies(c, &self.measured[i])))
            .collect();
        let pairs = applying
            .par_iter()
            .map(|&i| {
                let s = self.simulated_parts(sim, i, parts)?;
                Ok(self.timings.time_op(Stage::Error, Some(i), || {
                    error::pair_only(&self.measured[i], &s, own)
                }))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(error::mean(&pairs).of(own))
    }

    /// Mean error over the operating points `idx`.
    pub fn error(&self, sim: &SimulationConfig, idx: &[usize]) -> Result<ErrorParts> {
        let parts = idx
            .par_iter()
            .map(|&i| {
                let s = self.simulated(sim, i)?;
                Ok(self
                    .timings
                    .time_op(Stage::Error, Some(i), || error::pair(&self.measured[i], &s)))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(error::mean(&parts))
    }
}

/// The views of a recording as one piece (the baseline, [`Options::baseline`]).
fn whole_piece(
    rec: &crate::recording::Recording,
    rig: &RigConfig,
    faults: &[crate::vocabulary::Condition],
) -> Result<Views> {
    let mut v = views::compute_segment(rec, rig, faults)?;
    let track = crate::analysis::whole_recording(rec, rig)?;
    let dur = rec.duration_s();
    v.speed = views::speed_view(&track, dur, v.rpm);
    Ok(v)
}

/// Say what the measured recordings' length leaves out: a speed fluctuation slower than half
/// the shortest one, or (a series of short captures) any speed fluctuation at all.
fn warn_short(ops: &[Measured]) {
    let shortest = ops
        .iter()
        .map(|m| m.recording.duration_s())
        .fold(f64::INFINITY, f64::min);
    let captures = ops
        .iter()
        .any(|m| crate::recording::captures::is_capture_series(&m.recording.metadata));
    if captures {
        tracing::info!(
            "a series of short captures holds no speed fluctuation view: `speed_fluctuation` \
             cannot be fitted from it"
        );
    } else if shortest < 2.0 * LONGEST_PERIOD_S {
        tracing::warn!(
            "the shortest analysed recording is {shortest:.1} s: a speed fluctuation slower \
             than {:.1} s per period (half of it) cannot be resolved (the catalog searches up to \
             {LONGEST_PERIOD_S} s); analyse {:.0} s or more (--seconds, or longer recordings)",
            shortest / 2.0,
            2.0 * LONGEST_PERIOD_S
        );
    }
}

/// Extra, reportable parameters derived from the simulation: for `unbalance` the total 1x
/// and 2x amplitudes (rotor model plus the added lines) at the highest measured speed, m/s^2
/// (what a measurement of the rig would read); for `subharmonics` the speed its 0.5x
/// amplitude holds at; for `looseness_impacts` that speed and the peak of one landing's
/// ring-down there (`peak_m_s2`, what a measurement of one landing would read).
fn derived(twin: &Twin, effect: Effect, sim: &SimulationConfig) -> Result<BTreeMap<String, f64>> {
    let mut out = BTreeMap::new();
    if effect == Effect::Subharmonics {
        if let Some(h) = &sim.subharmonics {
            out.insert("at_rpm".into(), h.ref_rpm.round());
        }
    }
    if effect == Effect::LoosenessImpacts {
        if let Some(l) = &sim.loose_impacts {
            out.insert("at_rpm".into(), l.ref_rpm.round());
            out.insert("peak_m_s2".into(), round_sig(crate::sim::landing_peak(l)));
            // searched, or read from the ring's half-power width (`Context::ring`)
            out.insert("damping".into(), round_sig(l.damping));
        }
    }
    if effect == Effect::Unbalance {
        let (i, m) = twin
            .ops
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.rpm.total_cmp(&b.1.rpm))
            .context("no operating points")?;
        let v = twin.simulated(sim, i)?;
        for (k, a) in v.shaft.amplitude.iter().take(2).enumerate() {
            out.insert(
                format!("order{}_m_s2", k + 1),
                round_sig(a * twin.unit_to_m_s2),
            );
        }
        out.insert("at_rpm".into(), m.rpm.round());
    }
    Ok(out)
}

/// Bounded search of one effect's parameters on the fit part, on its own components, on top
/// of `base`, starting from `start` (default: [`Effect::start`]): (values, objective,
/// evaluations).
fn search_effect(
    twin: &Twin,
    effect: Effect,
    base: &SimulationConfig,
    start: Option<&[f64]>,
    fit: &[usize],
    cx: &catalog::Context,
) -> Result<(Vec<f64>, f64, usize)> {
    let own = effect.components();
    let mut failure = None;
    let mut found = (
        start.map_or_else(|| effect.start(base, cx), <[f64]>::to_vec),
        f64::INFINITY,
        0,
    );
    for _ in 0..effect.search_passes() {
        let (x, e, n) = search::minimize(
            &effect.params(cx),
            &found.0,
            &mut |x| match twin.error_of(&effect.apply(base, x, cx), fit, own) {
                Ok(e) => e,
                Err(e) => {
                    failure.get_or_insert(e);
                    f64::INFINITY
                }
            },
        );
        found = (x, e, found.2 + n);
    }
    match failure {
        Some(e) => Err(e.context(format!("trying effect {}", effect.name()))),
        None => Ok(found),
    }
}

/// Names of the parameters within 1 % of their search range's ends (log ranges in log).
fn at_bound(effect: Effect, values: &[f64], cx: &catalog::Context) -> Vec<String> {
    effect
        .params(cx)
        .iter()
        .zip(values)
        .filter(|(p, v)| {
            let near = |u: f64| u <= 0.01 || u >= 0.99;
            match p.range {
                catalog::Range::Linear(a, b) => near((*v - a) / (b - a)),
                catalog::Range::Log(a, b) => near((v.ln() - a.ln()) / (b.ln() - a.ln())),
                catalog::Range::Choice(_) => false,
            }
        })
        .map(|(p, _)| p.name.to_string())
        .collect()
}

/// Reportable parameters: the searched ones (4 significant digits) and derived ones.
fn named_params(
    twin: &Twin,
    effect: Effect,
    values: &[f64],
    sim: &SimulationConfig,
    cx: &catalog::Context,
) -> Result<BTreeMap<String, f64>> {
    let mut p: BTreeMap<String, f64> = effect
        .params(cx)
        .iter()
        .zip(values)
        .map(|(p, v)| (p.name.to_string(), round_sig(*v)))
        .collect();
    p.extend(derived(twin, effect, sim)?);
    Ok(p)
}

/// Whether the last round's evidence rules `effect` out of this round: its trial there did
/// not cut its own components on the fit part as [`accepts`] requires (the fit part alone,
/// before the held-out part is asked), and the effect accepted since moved none of those
/// components on the fit part by more than its [`min_cut`] (`before`: the fit part's error
/// at the start of the last round; `now`: at the start of this one). Its search would start
/// from the same values on the same error landscape of its own components.
pub fn ruled_out(effect: Effect, last: &[Trial], before: &ErrorParts, now: &ErrorParts) -> bool {
    last.iter()
        .find(|t| t.effect == Some(effect))
        .is_some_and(|t| {
            ruled_out_by(effect, (t.own_fit_before, t.own_fit_after), &|c| {
                now.get(c) - before.get(c)
            })
        })
}

/// [`ruled_out`] from the last trial's own components on the fit part (before, after) and
/// how far each component has moved on the fit part since the last round began.
pub fn ruled_out_by(
    effect: Effect,
    (b, a): (f64, f64),
    moved_by: &dyn Fn(ErrorComponent) -> f64,
) -> bool {
    let own = effect.components();
    let floor = least_cut(own);
    let fit_passed = b - a >= FIT_CUT.0 * b && b - a >= FIT_CUT.1 * floor;
    let moved = own.iter().any(|&c| moved_by(c).abs() > min_cut(c));
    !fit_passed && !moved
}

/// One round of trials: the calibration so far, and its errors.
struct Round<'r, 'a> {
    twin: &'r Twin<'a>,
    current: &'r SimulationConfig,
    accepted: &'r [Trial],
    cur_fit_parts: ErrorParts,
    cur_held_parts: ErrorParts,
    cur_all: f64,
    /// The fit, held-out and all operating points.
    parts: (&'r [usize], &'r [usize], &'r [usize]),
    cx: &'r catalog::Context,
}

impl Round<'_, '_> {
    /// Search `effect` on top of the calibration so far, re-fit the accepted effects whose
    /// views it moves, and judge it ([`accepts`]).
    fn try_effect(&self, effect: Effect) -> Result<Trial> {
        let trial_start = std::time::Instant::now();
        let (twin, cx) = (self.twin, self.cx);
        let (fit, held, all) = self.parts;
        let own = effect.components();
        let (values, _, evals) = search_effect(twin, effect, self.current, None, fit, cx)?;
        let cand = effect.apply(self.current, &values, cx);
        let (cand, refits, evals) = self.refit_moved(cand, evals)?;
        let fit_parts = twin.error(&cand, fit)?;
        let (fit_after, own_fit_after) = (fit_parts.total, fit_parts.of(own));
        let held_parts = twin.error(&cand, held)?;
        let held_after = held_parts.total;
        let (cur_fit, cur_held) = (self.cur_fit_parts.total, self.cur_held_parts.total);
        let (own_fit_before, own_held_before) =
            (self.cur_fit_parts.of(own), self.cur_held_parts.of(own));
        let own_held_after = held_parts.of(own);
        let all_parts = twin.error(&cand, all)?;
        Ok(Trial {
            name: effect.name().into(),
            params: named_params(twin, effect, &values, &cand, cx)?,
            fit_before: cur_fit,
            fit_after,
            held_before: cur_held,
            held_after,
            error_before: self.cur_all,
            error_after: all_parts.total,
            components_after: all_parts,
            own: own.iter().map(|s| s.to_string()).collect(),
            own_fit_before,
            own_fit_after,
            own_held_before,
            own_held_after,
            accepted: accepts(
                own,
                (own_fit_before, own_fit_after),
                (own_held_before, own_held_after),
                (cur_fit, fit_after),
                (cur_held, held_after),
            ),
            evaluations: evals,
            seconds: trial_start.elapsed().as_secs_f64(),
            refits,
            preferred_over: None,
            at_bound: at_bound(effect, &values, cx),
            effect: Some(effect),
            values,
            candidate: Some(cand),
        })
    }

    /// An effect that moves a view an accepted effect was fitted on gets that effect
    /// re-fitted with it before it is judged (e.g. at 1796 rpm a 60 Hz line falls on the 2x
    /// line an accepted unbalance was fitted to): (candidate, re-fits, evaluations).
    fn refit_moved(
        &self,
        mut cand: SimulationConfig,
        mut evals: usize,
    ) -> Result<(SimulationConfig, Vec<Refit>, usize)> {
        let (twin, cx, fit) = (self.twin, self.cx, self.parts.0);
        let mut refits = Vec::new();
        let mut cand_fit_parts = twin.error(&cand, fit)?;
        for (k, a) in self.accepted.iter().enumerate() {
            let ae = a.effect.expect("accepted effects carry their effect");
            let moved = ae
                .components()
                .iter()
                .any(|&c| cand_fit_parts.get(c) > self.cur_fit_parts.get(c) + min_cut(c));
            if moved {
                // from its accepted values, so the re-fit only moves what it must
                let (v, _, n) = search_effect(twin, ae, &cand, Some(&a.values), fit, cx)?;
                evals += n;
                cand = ae.apply(&cand, &v, cx);
                cand_fit_parts = twin.error(&cand, fit)?;
                refits.push(Refit {
                    name: a.name.clone(),
                    params: named_params(twin, ae, &v, &cand, cx)?,
                    at_bound: at_bound(ae, &v, cx),
                    index: k,
                    values: v,
                });
            }
        }
        Ok((cand, refits, evals))
    }
}

/// Run the greedy calibration on measured operating points (from [`super::measured::load`],
/// split by [`super::measured::checkerboard`]): the library entry point of `rigmon
/// calibrate`.
pub fn calibrate(rig: &RigConfig, ops: &[Measured], fit_part: Vec<bool>) -> Result<Outcome> {
    calibrate_with(rig, ops, fit_part, Options::default())
}

/// Longest `speed_fluctuation` period the catalog searches, s.
pub const LONGEST_PERIOD_S: f64 = catalog::PERIOD_S.1;

/// [`calibrate`] with explicit [`Options`].
pub fn calibrate_with(
    rig: &RigConfig,
    ops: &[Measured],
    fit_part: Vec<bool>,
    options: Options,
) -> Result<Outcome> {
    let base = rig_simulation(rig)?.clone();
    warn_short(ops);
    let started = std::time::Instant::now();
    let twin = Twin::with_options(rig, ops, options)?;
    let measured_views_wall_s = started.elapsed().as_secs_f64();
    let all: Vec<usize> = (0..ops.len()).collect();
    let fit: Vec<usize> = all.iter().copied().filter(|&i| fit_part[i]).collect();
    let held: Vec<usize> = all.iter().copied().filter(|&i| !fit_part[i]).collect();
    let fit_views: Vec<&Views> = fit.iter().map(|&i| &twin.measured[i]).collect();
    let base_views = fit
        .iter()
        .map(|&i| twin.simulated(&base, i))
        .collect::<Result<Vec<_>>>()?;
    let ringing = ringing_hz(&fit_views, &base_views);
    let cx = catalog::Context {
        speed_line: speed_line::find(&fit_views),
        ringing_hz: ringing,
        healthy_fit_rpm: fit
            .iter()
            .filter(|&&i| twin.measured[i].healthy)
            .map(|&i| ops[i].rpm)
            .reduce(f64::max),
        ring: ringing.and_then(|hz| ring_width(rig, ops, &fit, &twin.measured, hz)),
        ..context(ops)
    };
    if let Some(l) = cx.speed_line {
        tracing::info!(
            "the measured speed spectra show a line at {:.4} Hz ({:.3} s), {:.2} % deep: \
             speed_fluctuation is searched around it",
            l.hz,
            1.0 / l.hz,
            100.0 * l.fraction
        );
    }
    if let Some(i) = crate::sim::dominant_resonance(rig, &base).filter(|&i| i > 0) {
        tracing::warn!(
            "the classifier channel sees most of resonances[{i}] ({:.0} Hz), but the `resonance` \
             effect fits resonances[0] and `modes` compares the dominant one: list the mode the \
             sensor sees first in [[simulation.structure.resonances]]",
            base.structure.resonances[i].hz
        );
    }
    let before = twin.error(&base, &all)?;
    let catalog: &[Effect] = if options.looseness_impacts || shows_landings(&twin, &base, &all)? {
        &catalog::WITH_LOOSENESS_IMPACTS
    } else {
        &ALL
    };
    log_ring(&cx, catalog);
    let mut current = base.clone();
    let mut accepted: Vec<Trial> = Vec::new();
    let mut rounds = Vec::new();
    let mut round_times = Vec::new();
    let mut last: Option<(ErrorParts, Vec<Trial>)> = None;
    loop {
        let cur_fit_parts = twin.error(&current, &fit)?;
        let cur_held_parts = twin.error(&current, &held)?;
        let cur_all = twin.error(&current, &all)?.total;
        let (open, skipped): (Vec<Effect>, Vec<Effect>) = catalog
            .iter()
            .copied()
            .filter(|e| !accepted.iter().any(|t| t.effect == Some(*e)))
            .partition(|e| {
                !(options.skip_ruled_out
                    && last.as_ref().is_some_and(|(parts, trials)| {
                        ruled_out(*e, trials, parts, &cur_fit_parts)
                    }))
            });
        let round_start = std::time::Instant::now();
        let round = Round {
            twin: &twin,
            current: &current,
            accepted: &accepted,
            cur_fit_parts,
            cur_held_parts,
            cur_all,
            parts: (&fit, &held, &all),
            cx: &cx,
        };
        let try_effect = |effect: Effect| round.try_effect(effect);
        let mut trials: Vec<Trial> = if twin.options.parallel_trials {
            open.par_iter()
                .map(|e| try_effect(*e))
                .collect::<Result<_>>()?
        } else {
            open.iter().map(|e| try_effect(*e)).collect::<Result<_>>()?
        };
        let best = choose(&mut trials);
        for (i, t) in trials.iter_mut().enumerate() {
            t.accepted = Some(i) == best;
        }
        round_times.push(RoundTime {
            round: rounds.len() + 1,
            wall_s: round_start.elapsed().as_secs_f64(),
            trials: trials.iter().map(|t| (t.name.clone(), t.seconds)).collect(),
            skipped: skipped.iter().map(|e| e.name().to_string()).collect(),
        });
        rounds.push(trials.clone());
        last = Some((cur_fit_parts, trials.clone()));
        match best {
            Some(i) => {
                let mut t = trials.swap_remove(i);
                current = t.candidate.take().expect("every trial keeps its candidate");
                for r in &t.refits {
                    let a = &mut accepted[r.index];
                    a.values = r.values.clone();
                    a.params = r.params.clone();
                    a.at_bound = r.at_bound.clone();
                }
                accepted.push(t);
            }
            None => break,
        }
        if accepted.len() == catalog.len() {
            break;
        }
    }
    let after = twin.error(&current, &all)?;
    let views_before: Vec<Views> = all
        .iter()
        .map(|&i| twin.simulated(&base, i).map(|v| (*v).clone()))
        .collect::<Result<_>>()?;
    let views_after: Vec<Views> = all
        .iter()
        .map(|&i| twin.simulated(&current, i).map(|v| (*v).clone()))
        .collect::<Result<_>>()?;
    let pairs: Vec<(&Views, &Views)> = twin.measured.iter().zip(views_after.iter()).collect();
    let mut unexplained = locate(&pairs);
    super::trace::annotate(&mut unexplained, &rig.bearing.fault_orders());
    Ok(Outcome {
        fit_part,
        before,
        after,
        accepted,
        rounds,
        unexplained,
        calibrated: current,
        measured_views: twin.measured.clone(),
        views_before,
        views_after,
        timings: twin.timings.totals(),
        recording_times: twin
            .timings
            .per_recording(&ops.iter().map(|m| m.name.clone()).collect::<Vec<_>>()),
        round_times,
        measured_views_wall_s,
        wall_s: started.elapsed().as_secs_f64(),
        ring: cx.ring,
    })
}

/// The search context the measured operating points fix, without a speed line (the
/// calibration adds the one its fit part's speed views show, [`speed_line::find`]).
pub fn context(ops: &[Measured]) -> catalog::Context {
    let fs = ops
        .iter()
        .map(|m| m.recording.sample_rate)
        .fold(f64::INFINITY, f64::min);
    let rpm: Vec<f64> = ops.iter().map(|m| m.rpm).collect();
    catalog::Context {
        fs,
        max_rpm: rpm.iter().copied().fold(0.0, f64::max),
        several_speeds: several_speeds(&rpm),
        speed_line: None,
        ringing_hz: None,
        healthy_fit_rpm: None,
        ring: None,
    }
}

/// The measured recordings `all` show a loose housing's landings against the model `base`
/// ([`super::trace::shows_landings`]: a half-order comb of the envelope): only then is
/// `looseness_impacts` searched without being asked for, so a calibration of a machine
/// without them pays nothing for the effect.
fn shows_landings(twin: &Twin, base: &SimulationConfig, all: &[usize]) -> Result<bool> {
    // the twins' views are shared with the cache (the report's `before` reads them again)
    let views: Vec<Arc<Views>> = all
        .iter()
        .map(|&i| twin.simulated(base, i))
        .collect::<Result<_>>()?;
    let pairs: Vec<(&Views, &Views)> = twin
        .measured
        .iter()
        .zip(views.iter().map(|v| &**v))
        .collect();
    Ok(locate(&pairs).iter().any(super::trace::shows_landings))
}

/// The trial a round adds, among those that pass [`accepts`]: the one that cuts its own
/// components most, unless that is a free effect ([`Effect::free`]: broadband noise, a
/// resonance at any frequency) and an effect locked to the shaft ([`Effect::locked_to_shaft`])
/// cuts the whole fit error more: a periodic signature is explained, not absorbed. The
/// preferred trial says why in its `preferred_over` (the error each would leave).
fn choose(trials: &mut [Trial]) -> Option<usize> {
    let passed = || trials.iter().enumerate().filter(|(_, t)| t.accepted);
    let whole = |t: &Trial| t.fit_before - t.fit_after;
    let own = |t: &Trial| t.own_fit_before - t.own_fit_after;
    let by_own = passed().max_by(|a, b| own(a.1).total_cmp(&own(b.1)))?.0;
    let free = trials[by_own].effect.is_some_and(|e| e.free());
    let locked = passed()
        .filter(|(_, t)| t.effect.is_some_and(|e| e.locked_to_shaft()))
        .max_by(|a, b| whole(a.1).total_cmp(&whole(b.1)))
        .map(|(i, _)| i);
    match locked {
        Some(i) if free && whole(&trials[i]) > whole(&trials[by_own]) => {
            let note = format!(
                "`{}` (free of the shaft): it would leave a fit error of {:.3} (cut {:.3}), \
                 `{}` leaves {:.3} (cut {:.3}) with a signature locked to the shaft",
                trials[by_own].name,
                trials[by_own].fit_after,
                whole(&trials[by_own]),
                trials[i].name,
                trials[i].fit_after,
                whole(&trials[i]),
            );
            trials[i].preferred_over = Some(note);
            Some(i)
        }
        _ => Some(by_own),
    }
}

/// The simulated side of `modes`: the model's dominant structural mode, or none (the twin's
/// own dominant band) when a loose housing's landings ring a mode of their own, which may
/// outweigh the structure's.
fn model_mode_hz(rig: &RigConfig, sim: &SimulationConfig) -> Option<f64> {
    dominant_resonance_hz(rig, sim).filter(|_| sim.loose_impacts.is_none())
}

/// Where the healthy recordings among `measured` ring that the uncalibrated model (`base`,
/// the same recordings simulated) does not: the centre of the band where their landings
/// ring ([`super::landing_comb`]) when they show landings the model lacks (the median over
/// those recordings); else the band whose measured level exceeds the simulated one most
/// (the median over the recordings; all recordings when none is healthy), Hz. A mode the
/// landings of a loose part ring shows there; the model's own modes, present on both
/// sides, do not.
fn ringing_hz(measured: &[&Views], base: &[Arc<Views>]) -> Option<f64> {
    let mut landing_hz: Vec<f64> = measured
        .iter()
        .zip(base)
        .filter(|(m, _)| m.healthy && m.landings.detected())
        .filter_map(|(m, s)| {
            let k = m.landings.strongest()?;
            let (lo, hi) = m.landings.best_band_hz()?;
            (s.landings.ratio_in(k) < super::landing_comb::DETECT_RATIO).then(|| (lo * hi).sqrt())
        })
        .collect();
    if !landing_hz.is_empty() {
        landing_hz.sort_by(f64::total_cmp);
        return Some(landing_hz[landing_hz.len() / 2]);
    }
    let any_healthy = measured.iter().any(|v| v.healthy);
    let mut hz: Vec<f64> = measured
        .iter()
        .zip(base)
        .filter(|(m, _)| !any_healthy || m.healthy)
        .filter_map(|(m, s)| {
            let excess = m.bands.iter().zip(&s.bands).map(|(a, b)| a - b);
            let (k, _) = excess.enumerate().max_by(|a, b| a.1.total_cmp(&b.1))?;
            m.band_lo_hz.get(k).map(|lo| lo + views::BAND_HZ / 2.0)
        })
        .collect();
    hz.sort_by(f64::total_cmp);
    (!hz.is_empty()).then(|| hz[hz.len() / 2])
}

/// The damping of the mode ringing near `hz` on the fit part's (`fit`) healthy recordings,
/// read from its half-power width ([`super::ring_width`]): the median over the recordings
/// where it can be read, with their median frequency and stand above the floor; `None` where
/// none shows it.
fn ring_width(
    rig: &RigConfig,
    ops: &[Measured],
    fit: &[usize],
    measured: &[Views],
    hz: f64,
) -> Option<super::ring_width::RingWidth> {
    let read: Vec<_> = fit
        .iter()
        .filter(|&&i| measured[i].healthy)
        .filter_map(|&i| {
            let rec = &ops[i].recording;
            let ch = views::classifier_channel(rec, rig)?;
            super::ring_width::measure(&ch.samples, rec.sample_rate, ops[i].rpm / 60.0, hz)
        })
        .collect();
    let med = |f: fn(&super::ring_width::RingWidth) -> f64| {
        let v: Vec<f64> = read.iter().map(f).collect();
        super::stats::median(&v)
    };
    (!read.is_empty()).then(|| super::ring_width::RingWidth {
        hz: med(|r| r.hz),
        damping: med(|r| r.damping),
        snr_db: med(|r| r.snr_db),
    })
}

/// Say where `looseness_impacts`, if the `catalog` searches it, takes its damping from.
fn log_ring(cx: &catalog::Context, catalog: &[Effect]) {
    if let Some(r) = cx
        .ring
        .filter(|_| catalog.contains(&Effect::LoosenessImpacts))
    {
        tracing::info!(
            "the fit part's healthy recordings ring a mode at {:.0} Hz, {:.1} dB above the \
             floor, half-power width {:.1} Hz: `looseness_impacts` takes its damping, {:.4}, \
             from it",
            r.hz,
            r.snr_db,
            2.0 * r.damping * r.hz,
            r.damping
        );
    }
}

/// Round to 4 significant digits (reports).
pub fn round_sig(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let d = 3 - v.abs().log10().floor() as i32;
    let p = 10f64.powi(d);
    (v * p).round() / p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_effect_is_ruled_out_only_when_it_failed_and_its_view_stood_still() {
        use ErrorComponent as C;
        let e = Effect::Noise; // own component: floor
                               // the accepted effect moved another view (bands), not the floor
        let other = |c: ErrorComponent| if c == C::Bands { -6.0 } else { 0.0 };
        assert!(ruled_out_by(e, (4.0, 3.9), &other));
        // a cut that passed the fit part's rule (the held-out part refused it): try again
        assert!(!ruled_out_by(e, (4.0, 1.0), &other));
        // the floor moved by more than its smallest meaningful cut: try again
        let floor = |c: ErrorComponent| {
            if c == C::Floor {
                2.0 * min_cut(C::Floor)
            } else {
                0.0
            }
        };
        assert!(!ruled_out_by(e, (4.0, 3.9), &floor));
        // no trial in the last round: nothing rules it out
        let p = ErrorParts::default();
        assert!(!ruled_out(e, &[], &p, &p));
    }

    fn trial(effect: Effect, own_cut: f64, whole_cut: f64) -> Trial {
        Trial {
            name: effect.name().into(),
            params: BTreeMap::new(),
            fit_before: 10.0,
            fit_after: 10.0 - whole_cut,
            held_before: 10.0,
            held_after: 10.0 - whole_cut,
            own: Vec::new(),
            own_fit_before: 5.0,
            own_fit_after: 5.0 - own_cut,
            own_held_before: 5.0,
            own_held_after: 5.0 - own_cut,
            error_before: 10.0,
            error_after: 10.0 - whole_cut,
            components_after: ErrorParts::default(),
            accepted: true,
            evaluations: 0,
            seconds: 0.0,
            refits: Vec::new(),
            preferred_over: None,
            at_bound: Vec::new(),
            effect: Some(effect),
            values: Vec::new(),
            candidate: None,
        }
    }

    /// A free effect that cuts its own component most is still passed over for a shaft-locked
    /// one that cuts the whole error more, and the report says why; against a locked effect
    /// (unbalance) or when the locked one explains less, the own cut decides.
    #[test]
    fn a_periodic_signature_is_explained_not_absorbed() {
        let mut t = vec![
            trial(Effect::Noise, 3.0, 1.0),
            trial(Effect::LoosenessImpacts, 2.0, 2.5),
        ];
        assert_eq!(choose(&mut t), Some(1));
        let why = t[1].preferred_over.as_deref().unwrap();
        assert!(
            why.contains("`noise`") && why.contains("locked to the shaft"),
            "{why}"
        );
        let mut t = vec![
            trial(Effect::Noise, 3.0, 3.0),
            trial(Effect::LoosenessImpacts, 2.0, 2.5),
        ];
        assert_eq!(choose(&mut t), Some(0));
        let mut t = vec![
            trial(Effect::Unbalance, 3.0, 1.0),
            trial(Effect::LoosenessImpacts, 2.0, 2.5),
        ];
        assert_eq!(choose(&mut t), Some(0));
        let mut t = vec![
            trial(Effect::Noise, 3.0, 1.0),
            trial(Effect::Slip, 2.0, 2.5),
        ];
        assert_eq!(choose(&mut t), Some(0));
        t.iter_mut().for_each(|x| x.accepted = false);
        assert_eq!(choose(&mut t), None);
    }
}
