//! The source side of the daemon: what the source is ([`SourceInfo`]) and its thread feeding
//! a bounded block queue ([`Intake`]). Live sources drop (and count) blocks when the queue is
//! full; file replays wait. Blocks already waiting are taken first, and how many came back to
//! back tells the pipeline whether it is keeping up.

use crate::acquire::{SampleBlock, Source, SourceStats, StopToken};
use anyhow::Result;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// What the source says about itself before it runs.
#[derive(Debug, Clone)]
pub struct SourceInfo {
    /// One line for logs and the status topic.
    pub describe: String,
    pub sample_rate: f64,
    /// Rig channels the source cannot deliver.
    pub absent: Vec<String>,
    /// The speed the source knows up front (a recording's stored rpm).
    pub nominal_rpm: Option<f64>,
    /// Its blocks carry an analog tacho.
    pub analog_tacho: bool,
    /// Its blocks are a series of periodic captures ([`Source::capture_series`]).
    pub capture_series: bool,
}

impl SourceInfo {
    pub fn of(source: &dyn Source) -> Self {
        SourceInfo {
            describe: source.describe(),
            sample_rate: source.sample_rate(),
            absent: source.absent_channels(),
            nominal_rpm: source.nominal_rpm(),
            analog_tacho: source.analog_tacho(),
            capture_series: source.capture_series(),
        }
    }
}

/// What one receive brought.
pub enum Received {
    Block(SampleBlock),
    /// Nothing within the poll interval.
    Nothing,
    /// The source has ended (or failed) and closed the queue.
    Ended,
}

/// The source's thread and the queue it fills.
pub struct Intake {
    rx: Receiver<SampleBlock>,
    stop: StopToken,
    thread: JoinHandle<Result<()>>,
    /// Blocks received back to back from a non-empty queue.
    backlog: usize,
}

impl Intake {
    /// Start the source on its own thread, `queue_blocks` blocks ahead of the pipeline.
    pub fn spawn(
        source: Box<dyn Source>,
        queue_blocks: usize,
        stats: Arc<SourceStats>,
    ) -> Result<Intake> {
        let (tx, rx) = std::sync::mpsc::sync_channel(queue_blocks);
        let stop = StopToken::new();
        let thread = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("rigmon-source".into())
                .spawn(move || source.run(tx, stats, stop))?
        };
        Ok(Intake {
            rx,
            stop,
            thread,
            backlog: 0,
        })
    }

    /// The next block: one already waiting, else whatever comes within 50 ms.
    pub fn receive(&mut self) -> Received {
        let received = match self.rx.try_recv() {
            Ok(b) => {
                self.backlog += 1;
                Ok(b)
            }
            Err(_) => {
                self.backlog = 0;
                self.rx.recv_timeout(Duration::from_millis(50))
            }
        };
        match received {
            Ok(b) => Received::Block(b),
            Err(RecvTimeoutError::Timeout) => Received::Nothing,
            Err(RecvTimeoutError::Disconnected) => Received::Ended,
        }
    }

    /// Blocks taken back to back from a queue that was not empty (0: keeping up).
    pub fn backlog(&self) -> usize {
        self.backlog
    }

    /// Ask the source to stop; it ends by closing the queue.
    pub fn stop(&self) {
        self.stop.stop();
    }

    /// Wait for the source thread: how the source ended.
    pub fn join(self) -> Result<()> {
        match self.thread.join() {
            Ok(r) => r,
            Err(_) => Err(anyhow::anyhow!("the source thread panicked")),
        }
    }
}
