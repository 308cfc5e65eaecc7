//! The stdout sink, built from the command line's [`Output`]: one line per health message
//! (text or JSON), written and flushed on the pipeline thread.

use super::sink::{Sink, SinkConfig, SinkContext, WindowEvent};
use anyhow::Result;
use std::io::{StdoutLock, Write};

/// What to print on stdout, one line per health message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    None,
    Lines,
    Json,
}

/// Health messages on stdout (locked for the whole run).
pub struct StdoutSink {
    output: Output,
    out: StdoutLock<'static>,
}

impl SinkConfig for Output {
    fn build(&self, _cx: &SinkContext) -> Result<Option<Box<dyn Sink>>> {
        Ok(match self {
            Output::None => None,
            Output::Lines | Output::Json => Some(Box::new(StdoutSink {
                output: *self,
                out: std::io::stdout().lock(),
            })),
        })
    }
}

impl Sink for StdoutSink {
    fn on_window(&mut self, w: &WindowEvent) {
        match self.output {
            Output::None => {}
            Output::Lines => {
                let _ = writeln!(self.out, "{}", w.health.line());
            }
            Output::Json => {
                let _ = self.out.write_all(w.health_json);
                let _ = self.out.write_all(b"\n");
            }
        }
        let _ = self.out.flush();
    }

    fn close(mut self: Box<Self>) {
        let _ = self.out.flush();
    }
}
