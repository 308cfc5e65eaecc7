//! `rigmon emulate serial`: stream a recording in the rigmon serial protocol through a
//! pseudo-terminal (or to a serial port), to test the serial adapter and the daemon without
//! hardware. Prints the path to open on stdout (again after every replug) and a JSON
//! summary on stderr at the end.

use crate::acquire::emulator::{EmulatorOptions, EmulatorPort, SerialEmulator};
use crate::acquire::serial_protocol::SampleFormat;
use crate::acquire::{FileReplay, ReplaySpeed, StopToken};
use crate::config::RigConfig;
use crate::importers::{self, ImportOptions};
use anyhow::{bail, Context, Result};
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `rigmon emulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub device: Device,
}

/// What to emulate.
#[derive(clap::Subcommand, Debug)]
pub enum Device {
    /// A serial DAQ adapter speaking the rigmon serial protocol.
    Serial(SerialArgs),
}

/// Arguments of `rigmon emulate serial`.
#[derive(clap::Args, Debug)]
pub struct SerialArgs {
    /// Rig file (channel order, sensitivities).
    #[arg(long)]
    pub rig: PathBuf,
    /// Recording to stream (MCAP, any-layout .mat, WAV, CSV).
    pub recording: PathBuf,
    /// Create a pseudo-terminal and print the path of the end to open.
    #[arg(long)]
    pub pty: bool,
    /// With --pty: keep a symlink to the pseudo-terminal here (stable across unplugs).
    /// Without --pty: the serial device to write to.
    #[arg(long)]
    pub port: Option<PathBuf>,
    /// Baud rate of --port (without --pty).
    #[arg(long, default_value_t = 921_600)]
    pub baud: u32,
    /// Real-time factor (1 = real time) or "max" (as fast as the reader takes it).
    #[arg(long, default_value = "1")]
    pub speed: ReplaySpeed,
    /// Sample format on the wire: i16, i24 or f32.
    #[arg(long, default_value = "i16")]
    pub format: SampleFormat,
    /// Frame length, ms of samples.
    #[arg(long, default_value_t = 10.0)]
    pub frame_ms: f64,
    /// Corrupt every N-th frame (one flipped bit; its CRC fails).
    #[arg(long)]
    pub corrupt_every: Option<u64>,
    /// Unplug once this many seconds of the recording have been sent...
    #[arg(long, requires = "unplug_for")]
    pub unplug_after: Option<f64>,
    /// ...for this many seconds (the DAQ's clock runs on; those samples are lost).
    #[arg(long, requires = "unplug_after")]
    pub unplug_for: Option<f64>,
    /// Start the recording again at its end.
    #[arg(long = "loop")]
    pub looping: bool,
    /// Sample-rate override for recordings that do not carry one, Hz.
    #[arg(long)]
    pub sample_rate: Option<f64>,
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

pub fn run(args: Args) -> Result<()> {
    match args.device {
        Device::Serial(a) => serial(a),
    }
}

fn serial(a: SerialArgs) -> Result<()> {
    let port = match (a.pty, &a.port) {
        (true, link) => EmulatorPort::Pty { link: link.clone() },
        (false, Some(p)) => EmulatorPort::Device { path: p.to_string_lossy().into_owned(), baud: a.baud },
        (false, None) => bail!("say where to send frames: --pty creates a pseudo-terminal, --port PATH writes to a serial device"),
    };
    if !(a.frame_ms.is_finite() && a.frame_ms > 0.0) {
        bail!(
            "--frame-ms {}: must be a positive number of milliseconds",
            a.frame_ms
        );
    }
    let rig = RigConfig::load(&a.rig)?;
    let rec = importers::load(
        &a.recording,
        &rig,
        &ImportOptions {
            sample_rate: a.sample_rate,
            rpm: None,
            ..Default::default()
        },
    )?;
    let frame_samples = ((rec.sample_rate * a.frame_ms / 1000.0).round() as usize).max(1);
    let replay = FileReplay::from_recording(rec, &rig, a.speed, a.looping, 100.0)
        .with_context(|| format!("recording {}", a.recording.display()))?;
    let opts = EmulatorOptions {
        speed: a.speed,
        format: a.format,
        frame_samples,
        corrupt_every: a.corrupt_every,
        unplug_after_s: a.unplug_after,
        unplug_for_s: a.unplug_for.unwrap_or(0.0),
        looping: a.looping,
    };
    let emu = SerialEmulator::new(replay, &rig, opts)?;

    // SIGINT/SIGTERM end the stream cleanly (the symlink is removed).
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
    let stop = StopToken::new();
    let watcher = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.is_stopped() {
                if STOP.load(Ordering::SeqCst) {
                    stop.stop();
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        })
    };
    let mut announce = |path: &str| {
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{path}");
        let _ = out.flush();
    };
    let result = emu.run(&port, &stop, &mut announce);
    stop.stop();
    let _ = watcher.join();
    if let (EmulatorPort::Pty { link: Some(l) }, true) = (&port, a.pty) {
        let _ = std::fs::remove_file(l);
    }
    let report = result?;
    eprintln!("{}", serde_json::to_string(&report)?);
    Ok(())
}
