//! Ctrl-C handling: SIGINT and SIGTERM only raise a flag, which the writer
//! checks between batches; it then stops, and the temporary file is removed,
//! so an interrupted run leaves nothing behind.

use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

#[cfg(unix)]
extern "C" fn on_signal(_signal: libc::c_int) {
    // Only an atomic store: async-signal-safe.
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Routes SIGINT and SIGTERM to the flag read by [`interrupted`]. Call it
/// before the output file is created.
pub fn install() {
    #[cfg(unix)]
    // SAFETY: `sigaction` is given a zero-initialised, then fully set up
    // struct; the handler only performs an atomic store, which is
    // async-signal-safe. SA_RESTART keeps interrupted write(2) calls going.
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        action.sa_flags = libc::SA_RESTART;
        libc::sigemptyset(&mut action.sa_mask);
        for signal in [libc::SIGINT, libc::SIGTERM] {
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// True once SIGINT or SIGTERM has arrived.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}
