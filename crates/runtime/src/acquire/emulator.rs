//! The serial DAQ emulator behind `rigmon emulate serial`: streams a recording in the rigmon
//! serial protocol to a pseudo-terminal it creates (or to a real serial port), at real time
//! or as fast as the reader takes it, with optional corrupt frames and a simulated unplug.

use super::file_replay::{FileReplay, ReplaySpeed};
use super::layout::RigLayout;
use super::serial_protocol::{FrameEncoder, SampleFormat, MAX_SAMPLE_BYTES};
use super::{sleep_unless_stopped, StopToken};
use crate::config::RigConfig;
use anyhow::{bail, Context, Result};
use serialport::SerialPort;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How the emulator streams.
#[derive(Debug, Clone)]
pub struct EmulatorOptions {
    pub speed: ReplaySpeed,
    pub format: SampleFormat,
    /// Samples per channel in one frame.
    pub frame_samples: usize,
    /// Corrupt every N-th frame (one flipped bit in its samples).
    pub corrupt_every: Option<u64>,
    /// Unplug once the sample clock passes this many seconds...
    pub unplug_after_s: Option<f64>,
    /// ...for this many wall-clock seconds (the DAQ's clock runs on: those samples are lost).
    pub unplug_for_s: f64,
    /// Start the recording again at its end.
    pub looping: bool,
}

impl Default for EmulatorOptions {
    fn default() -> Self {
        EmulatorOptions {
            speed: ReplaySpeed::Factor(1.0),
            format: SampleFormat::I16,
            frame_samples: 100,
            corrupt_every: None,
            unplug_after_s: None,
            unplug_for_s: 1.0,
            looping: false,
        }
    }
}

/// Where the frames go.
#[derive(Debug, Clone)]
pub enum EmulatorPort {
    /// A new pseudo-terminal; its other end's path is announced, and kept as a symlink at
    /// `link` when given (a stable name across unplugs, like socat's `link=`).
    Pty { link: Option<PathBuf> },
    /// An existing serial device.
    Device { path: String, baud: u32 },
}

/// What the emulator did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct EmulatorReport {
    /// Frames written (corrupted ones included).
    pub frames: u64,
    pub corrupted: u64,
    /// Frames not written (or cut short) because nobody was reading in real-time mode.
    pub dropped: u64,
    /// Samples per channel in frames written intact.
    pub samples: u64,
    /// Samples per channel the DAQ clock ran through while unplugged.
    pub unplugged_samples: u64,
    pub unplugs: u64,
}

/// A recording ready to be streamed as serial frames.
pub struct SerialEmulator {
    replay: FileReplay,
    layout: RigLayout,
    encoder: FrameEncoder,
    opts: EmulatorOptions,
}

impl SerialEmulator {
    pub fn new(replay: FileReplay, rig: &RigConfig, opts: EmulatorOptions) -> Result<Self> {
        let layout = RigLayout::new(&rig.channels, &rig.speed);
        let rec = replay.recording();
        let fs = rec.sample_rate;
        if opts.frame_samples == 0 || opts.frame_samples > super::serial_protocol::MAX_SAMPLES {
            bail!(
                "frame size {} samples: must be 1 to 4096",
                opts.frame_samples
            );
        }
        if opts.frame_samples * layout.device_channels() * opts.format.bytes() > MAX_SAMPLE_BYTES {
            bail!("{} samples x {} channels of {} do not fit in one frame; use fewer samples per frame", opts.frame_samples, layout.device_channels(), opts.format);
        }
        if layout.analog_tacho && !matches!(rec.tacho, Some(crate::recording::Tacho::Analog { .. }))
        {
            tracing::warn!("rig {} has an analog tacho channel but the recording has none; the emulator sends 0 there (and any recorded edges as edges)", rig.machine.id);
        }
        // One scale per device channel, chosen so the recording's peak fits the integer range.
        let all = replay.block_at(0, rec.len());
        let dev = layout.join(&all.channels, all.tacho_analog.as_deref(), rec.len());
        let scales = dev
            .iter()
            .map(|ch| match opts.format.full_scale() {
                None => 1.0,
                Some(full) => {
                    let peak = ch
                        .iter()
                        .filter(|v| v.is_finite())
                        .fold(0.0f32, |m, v| m.max(v.abs())) as f64;
                    if peak > 0.0 {
                        (peak * 1.0001 / full) as f32
                    } else {
                        1.0
                    }
                }
            })
            .collect();
        let encoder = FrameEncoder {
            sample_rate: fs as f32,
            format: opts.format,
            scales,
            flags: 0,
        };
        Ok(SerialEmulator {
            replay,
            layout,
            encoder,
            opts,
        })
    }

    /// Stream until the recording ends (unless looping) or `stop` is set. `announce` is
    /// called with the path readers should open, each time the port (re)appears.
    pub fn run(
        &self,
        port: &EmulatorPort,
        stop: &StopToken,
        announce: &mut dyn FnMut(&str),
    ) -> Result<EmulatorReport> {
        let rec = self.replay.recording();
        let n = rec.len() as u64;
        let fs = rec.sample_rate;
        let fsz = self.opts.frame_samples as u64;
        let mut report = EmulatorReport::default();
        let mut out = open_port(port, announce)?;
        let unplug_at = self.opts.unplug_after_s.map(|s| (s * fs).round() as u64);
        let mut clock = 0u64; // DAQ sample clock
        let mut seq = 0u32;
        let mut frame_no = 0u64;
        let mut bytes = Vec::new();
        let t0 = Instant::now();
        // Wall-clock time added by the unplug pause that real-time pacing must not catch up.
        while !stop.is_stopped() {
            let pass = clock / n;
            if pass > 0 && !self.opts.looping {
                break;
            }
            if unplug_at.is_some_and(|u| clock >= u) && report.unplugs == 0 {
                report.unplugs += 1;
                // Remove the name first: once the pty is closed its number can be reused by
                // another pty, which a reader must not find under our name.
                if let EmulatorPort::Pty { link: Some(l) } = port {
                    let _ = std::fs::remove_file(l);
                }
                drop(out);
                let pause = Duration::from_secs_f64(self.opts.unplug_for_s.max(0.0));
                if !sleep_unless_stopped(pause, stop) {
                    return Ok(report);
                }
                let factor = match self.opts.speed {
                    ReplaySpeed::Factor(x) => x,
                    ReplaySpeed::Max => 1.0,
                };
                let skipped = (self.opts.unplug_for_s * fs * factor).round() as u64;
                let frames_skipped = skipped.div_ceil(fsz);
                report.unplugged_samples += frames_skipped * fsz;
                clock += frames_skipped * fsz;
                seq = seq.wrapping_add(frames_skipped as u32);
                out = open_port(port, announce)?;
                continue;
            }
            let start = clock % n;
            let end = (start + fsz).min(n);
            let len = end - start;
            if let ReplaySpeed::Factor(x) = self.opts.speed {
                let due = t0 + Duration::from_secs_f64((clock + len) as f64 / fs / x);
                let now = Instant::now();
                if due > now && !sleep_unless_stopped(due - now, stop) {
                    break;
                }
            }
            let block = self.replay.block_at(start as usize, end as usize);
            let dev =
                self.layout
                    .join(&block.channels, block.tacho_analog.as_deref(), len as usize);
            let refs: Vec<&[f32]> = dev.iter().map(Vec::as_slice).collect();
            let edges: Vec<f64> = block
                .tacho_edges
                .iter()
                .map(|t| (t * fs - start as f64) + clock as f64)
                .collect();
            bytes.clear();
            self.encoder
                .encode(&mut bytes, seq, clock, &refs, &edges)
                .context("encoding a frame")?;
            frame_no += 1;
            let corrupt = self
                .opts
                .corrupt_every
                .is_some_and(|k| k > 0 && frame_no % k == 0);
            if corrupt {
                // Flip one bit in the middle of the samples: the header stays sound, the CRC fails.
                let at =
                    32 + 4 * dev.len() + (len as usize * dev.len() * self.opts.format.bytes()) / 2;
                bytes[at] ^= 0x40;
            }
            let blocking = self.opts.speed == ReplaySpeed::Max;
            match out.write_frame(&bytes, blocking, stop)? {
                true => {
                    report.frames += 1;
                    if corrupt {
                        report.corrupted += 1;
                    } else {
                        report.samples += len;
                    }
                }
                false if stop.is_stopped() => break,
                false => report.dropped += 1,
            }
            seq = seq.wrapping_add(1);
            clock += len;
        }
        out.finish(stop);
        Ok(report)
    }
}

/// An open output: a pty pair (both ends held so the reader's settings persist) or a device.
enum Output {
    Pty {
        master: serialport::TTYPort,
        _slave: serialport::TTYPort,
    },
    Device(Box<dyn SerialPort>),
}

fn open_port(port: &EmulatorPort, announce: &mut dyn FnMut(&str)) -> Result<Output> {
    match port {
        EmulatorPort::Pty { link } => {
            let (mut master, slave) =
                serialport::TTYPort::pair().context("cannot create a pseudo-terminal pair")?;
            // Children started later (a daemon spawned by the same process, as in the tests)
            // must not inherit either end: a copy held elsewhere keeps the pty alive, so
            // closing it here would not hang up the reader and an unplug would go unseen.
            close_on_exec(&master).context("cannot mark the pty master close-on-exec")?;
            close_on_exec(&slave).context("cannot mark the pty slave close-on-exec")?;
            master.set_timeout(Duration::from_millis(50))?;
            let name = slave.name().context("the pseudo-terminal has no name")?;
            match link {
                Some(l) => {
                    replace_symlink(Path::new(&name), l)?;
                    announce(&l.to_string_lossy());
                }
                None => announce(&name),
            }
            Ok(Output::Pty {
                master,
                _slave: slave,
            })
        }
        EmulatorPort::Device { path, baud } => {
            let p = serialport::new(path, *baud)
                .timeout(Duration::from_millis(50))
                .open()
                .with_context(|| format!("cannot open serial port {path}"))?;
            announce(path);
            Ok(Output::Device(p))
        }
    }
}

/// Set FD_CLOEXEC on a descriptor (serialport opens its pty pair without it).
fn close_on_exec(fd: &impl std::os::fd::AsRawFd) -> std::io::Result<()> {
    let fd = fd.as_raw_fd();
    // SAFETY: fcntl on a descriptor we own; F_GETFD/F_SETFD take no pointers.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFD) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

fn replace_symlink(target: &Path, link: &Path) -> Result<()> {
    let tmp = link.with_extension("rigmon-tmp");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(target, &tmp)
        .with_context(|| format!("cannot create the symlink {}", tmp.display()))?;
    std::fs::rename(&tmp, link)
        .with_context(|| format!("cannot move the symlink to {}", link.display()))?;
    Ok(())
}

impl Output {
    fn writer(&mut self) -> &mut dyn Write {
        match self {
            Output::Pty { master, .. } => master,
            Output::Device(d) => d,
        }
    }

    /// Write a whole frame. Blocking: wait for the reader (unless stopped). Otherwise a
    /// frame the reader has no room for is dropped, possibly cut short, as a UART would.
    /// Returns whether the whole frame was written.
    fn write_frame(&mut self, bytes: &[u8], blocking: bool, stop: &StopToken) -> Result<bool> {
        let mut off = 0;
        while off < bytes.len() {
            match self.writer().write(&bytes[off..]) {
                Ok(0) => return Ok(false),
                Ok(k) => off += k,
                Err(e)
                    if e.kind() == std::io::ErrorKind::TimedOut
                        || e.kind() == std::io::ErrorKind::WouldBlock =>
                {
                    if !blocking || stop.is_stopped() {
                        return Ok(false);
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e).context("writing to the serial port"),
            }
        }
        Ok(true)
    }

    /// End of stream: let the reader take what is still buffered in the pseudo-terminal
    /// (closing the master would throw it away), for up to 5 s. The slave's input queue
    /// must stay empty for 60 ms: bytes still in the kernel's flip buffers do not show in it.
    fn finish(mut self, stop: &StopToken) {
        let _ = self.writer().flush();
        if let Output::Pty { _slave: slave, .. } = &self {
            let end = Instant::now() + Duration::from_secs(5);
            let mut empty_polls = 0;
            while empty_polls < 3 && Instant::now() < end && !stop.is_stopped() {
                std::thread::sleep(Duration::from_millis(20));
                match slave.bytes_to_read() {
                    Ok(0) => empty_polls += 1,
                    Ok(_) => empty_polls = 0,
                    Err(_) => break,
                }
            }
        }
    }
}
