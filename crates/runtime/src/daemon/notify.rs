//! systemd notification (sd_notify): READY=1 once the source and the model are up, STATUS=
//! lines, WATCHDOG=1 driven by pipeline progress (a stalled pipeline stops petting and
//! systemd restarts the service), RELOADING=1 around SIGHUP and STOPPING=1 on shutdown.
//! Without `NOTIFY_SOCKET` (not under systemd) every call is a cheap no-op.

use sd_notify::NotifyState;
use std::time::{Duration, Instant};

/// Sends sd_notify messages and paces the watchdog.
#[derive(Debug)]
pub struct Notifier {
    enabled: bool,
    /// Pet at most this often (half the watchdog period); None when no watchdog is set.
    watchdog_every: Option<Duration>,
    last_pet: Option<Instant>,
    /// Progress seen since the last pet.
    progressed: bool,
    last_status: String,
}

impl Notifier {
    /// Read `NOTIFY_SOCKET` and `WATCHDOG_USEC` from the environment.
    pub fn from_env() -> Self {
        let enabled = std::env::var_os("NOTIFY_SOCKET").is_some();
        let watchdog_every = if enabled {
            sd_notify::watchdog_enabled().map(|d| d / 2)
        } else {
            None
        };
        Notifier {
            enabled,
            watchdog_every,
            last_pet: None,
            progressed: false,
            last_status: String::new(),
        }
    }

    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// The watchdog pet interval, if systemd asked for a watchdog.
    pub fn watchdog_interval(&self) -> Option<Duration> {
        self.watchdog_every
    }

    fn send(&self, states: &[NotifyState]) {
        if self.enabled {
            if let Err(e) = sd_notify::notify(states) {
                tracing::debug!("sd_notify failed: {e}");
            }
        }
    }

    /// READY=1 with a status line.
    pub fn ready(&mut self, status: &str) {
        self.last_status = status.to_string();
        self.send(&[NotifyState::Ready, NotifyState::Status(status)]);
    }

    /// STATUS=... (only sent when it changed).
    pub fn status(&mut self, status: &str) {
        if status != self.last_status {
            self.last_status = status.to_string();
            self.send(&[NotifyState::Status(status)]);
        }
    }

    pub fn reloading(&self) {
        self.send(&[
            NotifyState::Reloading,
            NotifyState::monotonic_usec_now().unwrap_or(NotifyState::Status("reloading")),
        ]);
    }

    /// READY=1 again after a reload.
    pub fn reloaded(&mut self, status: &str) {
        self.ready(status);
    }

    pub fn stopping(&self, status: &str) {
        self.send(&[NotifyState::Stopping, NotifyState::Status(status)]);
    }

    /// The pipeline made progress (a block was consumed or a window computed).
    pub fn progress(&mut self) {
        self.progressed = true;
    }

    /// Call often from the pipeline loop: pets the watchdog when progress was made since the
    /// last pet (or `idle_ok` says waiting is legitimate, e.g. the device is reconnecting) and
    /// half the watchdog period has passed.
    pub fn tick(&mut self, idle_ok: bool) {
        let Some(every) = self.watchdog_every else {
            return;
        };
        let due = self.last_pet.is_none_or(|t| t.elapsed() >= every);
        if due && (self.progressed || idle_ok) {
            self.send(&[NotifyState::Watchdog]);
            self.last_pet = Some(Instant::now());
            self.progressed = false;
        }
    }
}
