//! Unix signals as flags the pipeline polls: SIGTERM/SIGINT ask for a clean stop (close the
//! recording, STOPPING=1), SIGHUP asks for a config reload and model swap. The handlers only
//! store to atomics (async-signal-safe).

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);
static RELOAD: AtomicBool = AtomicBool::new(false);

extern "C" fn on_stop(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

extern "C" fn on_hup(_: libc::c_int) {
    RELOAD.store(true, Ordering::SeqCst);
}

/// Install the handlers (idempotent).
pub fn install() {
    // SAFETY: the handlers only touch atomics; `signal` with a plain handler is fine on Linux
    // (BSD semantics: the handler stays installed and syscalls restart).
    unsafe {
        libc::signal(libc::SIGTERM, on_stop as *const () as libc::sighandler_t);
        libc::signal(libc::SIGINT, on_stop as *const () as libc::sighandler_t);
        libc::signal(libc::SIGHUP, on_hup as *const () as libc::sighandler_t);
    }
}

/// True once SIGTERM or SIGINT arrived.
pub fn stop_requested() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// Ask for a stop from inside the process (tests, end of a source).
pub fn request_stop() {
    STOP.store(true, Ordering::SeqCst);
}

/// True once per SIGHUP (the flag is cleared when read).
pub fn take_reload() -> bool {
    RELOAD.swap(false, Ordering::SeqCst)
}
