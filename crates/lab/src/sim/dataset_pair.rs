//! Two datasets of one plan simulated together: adapt's zero-shot dataset (the uncalibrated
//! rig) and its calibrated one. Where a run has the same mechanics in both (the same
//! scenario and the same [`split::mechanics_part`] of its section: calibration accepted only
//! structural or sensor-stage effects such as a resonance, noise or shaft lines), the
//! mechanics run once and each dataset gets its own modes and sensor stage
//! ([`EngineRun::with_resonances`], [`sensor::finish`]); every other run is simulated
//! on its own, as [`dataset::generate`] does. Both datasets come out as `generate` writes
//! them (files and `labels.csv`), up to the rounding `split` documents.
//!
//! The first dataset needs nothing from the calibration, so [`simulate_ahead`] may run its
//! first runs on one thread while the calibration runs (filling the cores the calibration's
//! serial parts leave idle); [`generate_pair`] then does the rest. The runs simulated ahead
//! keep their mechanics (within [`AHEAD_MECHANICS_BYTES`]), so a calibrated run that shares
//! them only adds its own modes and sensor stage instead of running the mechanics again.

use super::dataset::{self, CalibratedDraws, DatasetSummary};
use super::plan::{Plan, PlannedRun};
use super::{output, rig_simulation, sensor, split, EngineRun, Scenario};
use crate::config::simulation::SimulationConfig;
use crate::config::RigConfig;
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Memory the mechanics of the runs simulated ahead may keep for the calibrated dataset,
/// bytes: a 2 s run at 12.8 kHz, 10x oversampled, keeps about 7 MB of housing forces, so
/// about 140 such runs (the 100-115 a 25-30 s calibration lets go ahead on 2 cores); past
/// it a run ahead keeps nothing and its calibrated partner runs its mechanics again. Kept
/// whether or not the calibration then leaves the mechanics alone (on HIT-SM it does not:
/// the memory is spent for nothing there until the pair frees it).
pub const AHEAD_MECHANICS_BYTES: usize = 1_000_000_000;

/// One dataset of the pair: the rig it simulates, its plan and the folder it goes to.
#[derive(Debug, Clone, Copy)]
pub struct DatasetJob<'a> {
    pub rig: &'a RigConfig,
    pub plan: &'a Plan,
    pub dir: &'a Path,
}

/// What one task of the pair simulates: a run of both datasets sharing its mechanics, or a
/// run of one dataset alone (index into that dataset's runs).
#[derive(Debug, Clone, Copy)]
enum Task {
    Shared(usize, usize),
    First(usize),
    Second(usize),
    /// The second dataset's run `.1` on the mechanics kept from the first dataset's run `.0`
    /// simulated ahead.
    SecondOnto(usize, usize),
}

/// The pair's outcome: each dataset's summary and how many runs shared their mechanics.
#[derive(Debug, Clone)]
pub struct PairSummary {
    pub first: DatasetSummary,
    pub second: DatasetSummary,
    pub shared_runs: usize,
}

/// The rig without its simulation section and calibration stamp: what else the mechanics
/// read (bearing, acquisition, channels).
fn rig_without_simulation(rig: &RigConfig) -> RigConfig {
    RigConfig {
        simulation: None,
        calibration: None,
        ..rig.clone()
    }
}

/// Whether two scenarios on two sections run the same mechanics.
fn same_mechanics(
    (a, base_a): (&Scenario, &SimulationConfig),
    (b, base_b): (&Scenario, &SimulationConfig),
) -> bool {
    a.faults == b.faults
        && a.profile == b.profile
        && a.seconds == b.seconds
        && a.seed == b.seed
        && split::mechanics_part(&a.overrides.apply(base_a))
            == split::mechanics_part(&b.overrides.apply(base_b))
}

/// Whether a run of the first dataset was simulated ahead, and kept its mechanics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AheadRun {
    NotYet,
    Written,
    Kept,
}

/// Pair the runs: by stem, sharing where the mechanics agree (also with the mechanics kept
/// from a run simulated ahead).
fn tasks(
    (runs_a, base_a): (&[PlannedRun], &SimulationConfig),
    (runs_b, base_b): (&[PlannedRun], &SimulationConfig),
    rigs_agree: bool,
    done_a: &[AheadRun],
) -> Vec<Task> {
    let by_stem: HashMap<&str, usize> = runs_b
        .iter()
        .enumerate()
        .map(|(i, r)| (r.stem.as_str(), i))
        .collect();
    let mut taken = vec![false; runs_b.len()];
    let mut out = Vec::with_capacity(runs_a.len() + runs_b.len());
    for (i, ra) in runs_a.iter().enumerate() {
        if done_a[i] == AheadRun::Written {
            continue;
        }
        let partner = by_stem.get(ra.stem.as_str()).copied().filter(|&j| {
            rigs_agree && same_mechanics((&ra.scenario, base_a), (&runs_b[j].scenario, base_b))
        });
        match (partner, done_a[i]) {
            (Some(j), AheadRun::Kept) => {
                taken[j] = true;
                out.push(Task::SecondOnto(i, j));
            }
            (None, AheadRun::Kept) => {}
            (Some(j), _) => {
                taken[j] = true;
                out.push(Task::Shared(i, j));
            }
            (None, _) => out.push(Task::First(i)),
        }
    }
    out.extend((0..runs_b.len()).filter(|&j| !taken[j]).map(Task::Second));
    out
}

/// Finish one dataset's recording from a shared mechanics run and write it.
fn finish_and_write(
    job: &DatasetJob,
    base: &SimulationConfig,
    run: &PlannedRun,
    mech: &EngineRun,
    ext: &str,
) -> Result<(String, String)> {
    let sim = run.scenario.overrides.apply(base);
    let engine = mech.with_resonances(&sim.structure.resonances)?;
    let rec = sensor::finish(job.rig, &sim, &run.scenario, &engine)
        .with_context(|| format!("simulating {}", run.stem))?;
    write(job, run, &rec, ext)
}

fn write(
    job: &DatasetJob,
    run: &PlannedRun,
    rec: &crate::recording::Recording,
    ext: &str,
) -> Result<(String, String)> {
    let name = format!("{}.{ext}", run.stem);
    output::write(&job.dir.join(&name), rec, job.rig)?;
    Ok((name, run.scenario.label().to_string()))
}

/// Simulate one run of one dataset alone.
fn alone(job: &DatasetJob, run: &PlannedRun, ext: &str) -> Result<(String, String)> {
    dataset::simulate_run(job.rig, run, job.dir, ext)
}

/// Rows of each dataset a task wrote: (dataset 0 or 1, file name, label).
type Rows = Vec<(usize, String, String)>;

fn run_task(
    task: Task,
    jobs: [&DatasetJob; 2],
    runs: [&[PlannedRun]; 2],
    bases: [&SimulationConfig; 2],
    (ext, kept): (&str, &KeptMechanics),
) -> Result<Rows> {
    Ok(match task {
        Task::First(i) => {
            let (n, l) = alone(jobs[0], &runs[0][i], ext)?;
            vec![(0, n, l)]
        }
        Task::Second(j) => {
            let (n, l) = alone(jobs[1], &runs[1][j], ext)?;
            vec![(1, n, l)]
        }
        Task::Shared(i, j) => {
            let mech = split::run_mechanics(jobs[0].rig, bases[0], &runs[0][i].scenario)
                .with_context(|| format!("simulating {}", runs[0][i].stem))?;
            let (n0, l0) = finish_and_write(jobs[0], bases[0], &runs[0][i], &mech, ext)?;
            let (n1, l1) = finish_and_write(jobs[1], bases[1], &runs[1][j], &mech, ext)?;
            vec![(0, n0, l0), (1, n1, l1)]
        }
        Task::SecondOnto(i, j) => {
            let mech = kept
                .take(i)
                .with_context(|| format!("internal: no mechanics kept for {}", runs[0][i].stem))?;
            let (n, l) = finish_and_write(jobs[1], bases[1], &runs[1][j], &mech, ext)?;
            vec![(1, n, l)]
        }
    })
}

/// The mechanics kept from the runs simulated ahead, by run index; each is taken (and its
/// memory freed) by the one task that finishes it for the second dataset.
struct KeptMechanics(HashMap<usize, Mutex<Option<EngineRun>>>);

impl KeptMechanics {
    fn take(&self, i: usize) -> Option<EngineRun> {
        self.0.get(&i)?.lock().ok()?.take()
    }
}

/// Runs of the first dataset already written by [`simulate_ahead`]: (run index, file
/// name, label), and the mechanics they kept (by run index).
#[derive(Default)]
pub struct Ahead {
    done: Vec<(usize, String, String)>,
    mechanics: HashMap<usize, EngineRun>,
}

impl std::fmt::Debug for Ahead {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ahead")
            .field("done", &self.done.len())
            .field("mechanics_kept", &self.mechanics.len())
            .finish()
    }
}

impl Ahead {
    /// How many runs were simulated ahead.
    pub fn len(&self) -> usize {
        self.done.len()
    }

    /// How many of them kept their mechanics for the second dataset.
    pub fn mechanics_kept(&self) -> usize {
        self.mechanics.len()
    }

    pub fn is_empty(&self) -> bool {
        self.done.is_empty()
    }
}

/// Simulate the first dataset's runs one after another, on the calling thread, until
/// `stop` is set (the run under way is finished) or every run is done. Each run's mechanics
/// run apart from its modes ([`split::run_mechanics`]) and are kept while they fit in
/// `keep_bytes`, for the second dataset's run that shares them ([`generate_pair`]).
pub fn simulate_ahead(
    job: DatasetJob,
    ext: &str,
    calibrated: CalibratedDraws,
    (stop, keep_bytes): (&AtomicBool, usize),
) -> Result<Ahead> {
    let runs = dataset::expand_for(job.rig, job.plan, calibrated)?;
    let base = rig_simulation(job.rig)?;
    std::fs::create_dir_all(job.dir)
        .with_context(|| format!("cannot create output directory {}", job.dir.display()))?;
    let mut ahead = Ahead::default();
    let mut kept_bytes = 0usize;
    for (i, run) in runs.iter().enumerate() {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        let mech = split::run_mechanics(job.rig, base, &run.scenario)
            .with_context(|| format!("simulating {}", run.stem))?;
        let (name, label) = finish_and_write(&job, base, run, &mech, ext)?;
        ahead.done.push((i, name, label));
        if kept_bytes + mech.bytes() <= keep_bytes {
            kept_bytes += mech.bytes();
            ahead.mechanics.insert(i, mech);
        }
    }
    Ok(ahead)
}

/// Generate both datasets (each as [`dataset::generate`] would, with the same
/// `calibrated` draws), sharing the mechanics of every run that allows it; the first
/// dataset's runs in `ahead` are already written (their kept mechanics serve the second
/// dataset's runs that share them, and are freed as they are used). One progress bar counts
/// the recordings of both.
pub fn generate_pair(
    jobs: [DatasetJob; 2],
    ahead: Ahead,
    ext: &str,
    threads: Option<usize>,
    progress: bool,
    calibrated: CalibratedDraws,
) -> Result<PairSummary> {
    let bases = [rig_simulation(jobs[0].rig)?, rig_simulation(jobs[1].rig)?];
    let runs = [
        dataset::expand_for(jobs[0].rig, jobs[0].plan, calibrated)?,
        dataset::expand_for(jobs[1].rig, jobs[1].plan, calibrated)?,
    ];
    for j in &jobs {
        std::fs::create_dir_all(j.dir)
            .with_context(|| format!("cannot create output directory {}", j.dir.display()))?;
    }
    let rigs_agree = rig_without_simulation(jobs[0].rig) == rig_without_simulation(jobs[1].rig);
    let mut done = vec![AheadRun::NotYet; runs[0].len()];
    for &(i, ..) in &ahead.done {
        done[i] = if ahead.mechanics.contains_key(&i) {
            AheadRun::Kept
        } else {
            AheadRun::Written
        };
    }
    let tasks = tasks(
        (&runs[0], bases[0]),
        (&runs[1], bases[1]),
        rigs_agree,
        &done,
    );
    let shared_runs = tasks
        .iter()
        .filter(|t| matches!(t, Task::Shared(..) | Task::SecondOnto(..)))
        .count();
    let Ahead {
        done: ahead_done,
        mechanics,
    } = ahead;
    // the kept mechanics no task finishes are freed now
    let onto: std::collections::HashSet<usize> = tasks
        .iter()
        .filter_map(|t| match t {
            Task::SecondOnto(i, _) => Some(*i),
            _ => None,
        })
        .collect();
    let kept = KeptMechanics(
        mechanics
            .into_iter()
            .filter(|(i, _)| onto.contains(i))
            .map(|(i, m)| (i, Mutex::new(Some(m))))
            .collect(),
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.unwrap_or(0))
        .build()?;
    let total = runs[0].len() + runs[1].len() - ahead_done.len();
    let bar = dataset::recordings_bar(progress, total as u64);
    let t0 = Instant::now();
    let results: Vec<Result<Rows>> = pool.install(|| {
        tasks
            .par_iter()
            .map(|&t| {
                let rows = run_task(
                    t,
                    [&jobs[0], &jobs[1]],
                    [&runs[0], &runs[1]],
                    bases,
                    (ext, &kept),
                )?;
                bar.inc(rows.len() as u64);
                Ok(rows)
            })
            .collect()
    });
    bar.finish_and_clear();
    let mut rows: [Vec<(String, String)>; 2] = [Vec::new(), Vec::new()];
    rows[0].extend(ahead_done.into_iter().map(|(_, n, l)| (n, l)));
    for r in results {
        for (k, name, label) in r? {
            rows[k].push((name, label));
        }
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let mut summaries = Vec::with_capacity(2);
    for (job, mut rows) in jobs.iter().zip(rows) {
        dataset::write_labels(job.dir, &mut rows)?;
        let (recordings, seconds) = job.plan.totals();
        summaries.push(DatasetSummary {
            recordings,
            seconds,
            wall_s,
        });
    }
    let second = summaries.pop().expect("two summaries");
    let first = summaries.pop().expect("two summaries");
    Ok(PairSummary {
        first,
        second,
        shared_runs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> RigConfig {
        RigConfig::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/hit-sm-self.toml"
        )))
        .unwrap()
    }

    fn plan() -> Plan {
        Plan::parse(
            "name = \"pair\"\nseed = 5\nseconds = 0.3\n\
             [[case]]\nfaults = \"healthy\"\nrpm = 900\nrecordings = 1\n\
             [[case]]\nfaults = \"outer_race\"\nrpm = 1200\nrecordings = 1\n",
        )
        .unwrap()
    }

    /// The largest difference between two datasets' recordings (WAV, float samples),
    /// relative to the recording's peak.
    fn worst_difference(a: &Path, b: &Path) -> f64 {
        let read = |p: &Path| -> Vec<f32> {
            hound::WavReader::open(p)
                .unwrap()
                .samples::<f32>()
                .map(|x| x.unwrap())
                .collect()
        };
        let mut worst = 0.0f64;
        let mut n = 0;
        for e in std::fs::read_dir(a).unwrap() {
            let p = e.unwrap().path();
            if p.extension().and_then(|x| x.to_str()) != Some("wav") {
                continue;
            }
            let (sa, sb) = (read(&p), read(&b.join(p.file_name().unwrap())));
            assert_eq!(sa.len(), sb.len());
            let peak = sa.iter().fold(0.0f32, |m, x| m.max(x.abs()));
            assert!(peak > 0.0);
            for (x, y) in sa.iter().zip(&sb) {
                worst = worst.max(f64::from((x - y).abs() / peak));
            }
            n += 1;
        }
        assert_eq!(n, 2, "two recordings per dataset");
        worst
    }

    /// Each rig's dataset of `plan` simulated alone (the reference), into `dirs`.
    fn simulated_alone(rigs: [&RigConfig; 2], plan: &Plan, dirs: [&Path; 2]) {
        for (r, dir) in rigs.into_iter().zip(dirs) {
            dataset::generate(r, plan, dir, "wav", Some(2), false, CalibratedDraws::Spread)
                .unwrap();
        }
    }

    /// With a moved, more damped mode and more noise (structure and sensor only), every
    /// run shares its mechanics and each dataset is the one `generate` writes alone, to
    /// rounding; with a changed contact angle (mechanics) nothing is shared.
    #[test]
    fn a_pair_shares_the_mechanics_and_gives_each_dataset_as_alone() {
        let rig0 = rig();
        let mut rig1 = rig0.clone();
        let sim = rig1.simulation.as_mut().unwrap();
        sim.structure.resonances[0].hz *= 1.3;
        sim.structure.resonances[0].damping *= 2.0;
        sim.structure.noise_rms_m_s2 *= 3.0;
        let plan = plan();
        let tmp = tempfile::tempdir().unwrap();
        let d = |s: &str| tmp.path().join(s);
        let (za, ca, zb, cb) = (d("z-pair"), d("c-pair"), d("z-alone"), d("c-alone"));
        let jobs = |z: &Path, c: &Path, r1: &RigConfig| -> Result<PairSummary> {
            generate_pair(
                [
                    DatasetJob {
                        rig: &rig0,
                        plan: &plan,
                        dir: z,
                    },
                    DatasetJob {
                        rig: r1,
                        plan: &plan,
                        dir: c,
                    },
                ],
                Ahead::default(),
                "wav",
                Some(2),
                false,
                CalibratedDraws::Spread,
            )
        };
        let pair = jobs(&za, &ca, &rig1).unwrap();
        assert_eq!(pair.shared_runs, 2);
        simulated_alone([&rig0, &rig1], &plan, [&zb, &cb]);
        assert!(worst_difference(&za, &zb) < 1e-5);
        assert!(worst_difference(&ca, &cb) < 1e-5);
        // the two datasets do differ (the calibration matters)
        assert!(worst_difference(&za, &ca) > 1e-3);
        let labels = std::fs::read_to_string(ca.join("labels.csv")).unwrap();
        assert_eq!(
            labels,
            std::fs::read_to_string(cb.join("labels.csv")).unwrap()
        );
    }

    /// Runs simulated ahead, the first kept with its mechanics: the calibrated partner of
    /// the kept one is finished onto them and the other run shares in the pair (2 runs
    /// share; 1 when nothing may be kept), both datasets still as alone; a stopped ahead
    /// simulates nothing.
    #[test]
    fn runs_simulated_ahead_keep_their_mechanics_for_the_second_dataset() {
        let rig0 = rig();
        let mut rig1 = rig0.clone();
        let sim = rig1.simulation.as_mut().unwrap();
        sim.structure.resonances[0].hz *= 1.3;
        sim.structure.noise_rms_m_s2 *= 3.0;
        let plan = plan();
        let tmp = tempfile::tempdir().unwrap();
        let d = |s: &str| tmp.path().join(s);
        let (zb, cb) = (d("z-alone"), d("c-alone"));
        simulated_alone([&rig0, &rig1], &plan, [&zb, &cb]);
        let stop = AtomicBool::new(false);
        for (keep, shared) in [(usize::MAX, 2), (0, 1)] {
            let (z, c) = (d(&format!("z-ahead-{keep}")), d(&format!("c-ahead-{keep}")));
            let job0 = DatasetJob {
                rig: &rig0,
                plan: &plan,
                dir: &z,
            };
            let mut ahead =
                simulate_ahead(job0, "wav", CalibratedDraws::Spread, (&stop, keep)).unwrap();
            assert_eq!(ahead.len(), 2);
            assert_eq!(ahead.mechanics_kept(), if keep == 0 { 0 } else { 2 });
            ahead.done.truncate(1);
            ahead.mechanics.remove(&1);
            let job1 = DatasetJob {
                rig: &rig1,
                plan: &plan,
                dir: &c,
            };
            let pair = generate_pair(
                [job0, job1],
                ahead,
                "wav",
                Some(2),
                false,
                CalibratedDraws::Spread,
            )
            .unwrap();
            assert_eq!(pair.shared_runs, shared, "keeping {keep} bytes");
            assert!(worst_difference(&z, &zb) < 1e-5);
            assert!(worst_difference(&c, &cb) < 1e-5);
            for (a, b) in [(&z, &zb), (&c, &cb)] {
                assert_eq!(
                    std::fs::read_to_string(a.join("labels.csv")).unwrap(),
                    std::fs::read_to_string(b.join("labels.csv")).unwrap()
                );
            }
        }
        stop.store(true, Ordering::Relaxed);
        let job0 = DatasetJob {
            rig: &rig0,
            plan: &plan,
            dir: &d("z-stopped"),
        };
        let none = simulate_ahead(job0, "wav", CalibratedDraws::Spread, (&stop, 0)).unwrap();
        assert!(none.is_empty());
    }
}
