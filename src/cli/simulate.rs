//! `rigmon simulate`: run the rig simulator for one scenario and write MCAP or WAV.

use crate::config::RigConfig;
use crate::sim::{self, Overrides, Scenario, SpeedProfile};
use crate::vocabulary::Condition;
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `rigmon simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Rig file with a [simulation] section (e.g. config/lut-rig.toml).
    #[arg(long)]
    pub rig: PathBuf,
    /// healthy | outer_race | inner_race | ball, comma-separated for compound faults.
    #[arg(long, default_value = crate::vocabulary::Condition::Healthy.as_str())]
    pub fault: String,
    /// Shaft speed, rpm (start speed of a ramp).
    #[arg(long)]
    pub rpm: f64,
    /// Length of the recording, s.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Random seed (same seed -> identical output).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file: .mcap or .wav (rig channel order, float32).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Ramp linearly from --rpm to this speed over the recording.
    #[arg(long)]
    pub ramp_to: Option<f64>,
    /// Sinusoidal speed fluctuation, fraction of the speed (0.01 = 1 %).
    #[arg(long)]
    pub fluctuation: Option<f64>,
    /// Period of the speed fluctuation, s.
    #[arg(long, default_value_t = 2.0)]
    pub fluctuation_period: f64,
    /// Defect width along the rolling direction, mm.
    #[arg(long)]
    pub defect_size: Option<f64>,
    /// Defect depth, mm.
    #[arg(long)]
    pub defect_depth: Option<f64>,
    /// Mean cage slip, fraction.
    #[arg(long)]
    pub slip: Option<f64>,
    /// Random ball jitter, fraction of the ball spacing.
    #[arg(long)]
    pub slip_jitter: Option<f64>,
    /// Contact angle used by the model, degrees.
    #[arg(long)]
    pub contact_angle: Option<f64>,
    /// Extra static radial load on the test bearing, N.
    #[arg(long)]
    pub load: Option<f64>,
    /// Sensor noise RMS, m/s^2.
    #[arg(long)]
    pub noise: Option<f64>,
    /// First structural resonance, Hz.
    #[arg(long)]
    pub resonance_hz: Option<f64>,
    /// Print the first bending modes (eigen-analysis) before simulating.
    #[arg(long)]
    pub modes: bool,
}

/// Refuse an output path that names one of the inputs (the same file, hard links included),
/// before anything is read or written; `main` calls this before [`run`].
pub fn refuse_overwrite(args: &Args) -> Result<()> {
    super::same_file::refuse_output_naming_input(&[("-o", &args.output)], &[("--rig", &args.rig)])?;
    Ok(())
}

pub fn run(args: Args) -> Result<()> {
    let rig = RigConfig::load(&args.rig)?;
    let faults = Condition::parse_faults(&args.fault)?;
    if !(args.rpm > 0.0) {
        bail!("--rpm {}: must be positive", args.rpm);
    }
    let profile = match (args.ramp_to, args.fluctuation) {
        (Some(_), Some(_)) => bail!("use either --ramp-to or --fluctuation, not both"),
        (Some(to), None) => SpeedProfile::Ramp {
            from_rpm: args.rpm,
            to_rpm: to,
            seconds: args.seconds,
        },
        (None, Some(f)) => SpeedProfile::Sine {
            rpm: args.rpm,
            amplitude_rpm: f * args.rpm,
            period_s: args.fluctuation_period,
        },
        (None, None) => SpeedProfile::Constant { rpm: args.rpm },
    };
    let overrides = Overrides {
        defect_width_mm: args.defect_size,
        defect_depth_mm: args.defect_depth,
        slip: args.slip,
        slip_jitter: args.slip_jitter,
        contact_angle_deg: args.contact_angle,
        radial_load_n: args.load,
        noise_rms_m_s2: args.noise,
        resonance_hz: args.resonance_hz,
        ..Default::default()
    };
    let scenario = Scenario {
        faults,
        profile,
        seconds: args.seconds,
        seed: args.seed,
        overrides,
        metadata: BTreeMap::new(),
    };
    if args.modes {
        let sim_cfg = scenario.overrides.apply(sim::rig_simulation(&rig)?);
        let ([v, h], _) = sim::bending_modes(&rig, &sim_cfg)?;
        eprintln!("first bending modes: vertical {v:.2} Hz, horizontal {h:.2} Hz");
    }
    let t0 = std::time::Instant::now();
    let rec = sim::simulate(&rig, &scenario)?;
    let wall = t0.elapsed().as_secs_f64();
    sim::output::write(&args.output, &rec, &rig)?;
    eprintln!(
        "wrote {} ({} s of {} at {} rpm, {} channels at {} Hz) in {:.2} s wall ({:.0}x real time)",
        args.output.display(),
        args.seconds,
        scenario.label(),
        rec.metadata.get("rpm").map(String::as_str).unwrap_or("?"),
        rec.channels.len() + usize::from(rec.tacho.is_some()),
        rec.sample_rate,
        wall,
        args.seconds / wall.max(1e-9)
    );
    Ok(())
}
