//! Signal handling for every lop process that holds shared memory (`lopd`'s processes, the
//! benchmarks that spawn them): SIGINT, SIGTERM and SIGHUP set one flag that every loop polls,
//! so each takes its normal exit path (the haptic loop writes zero force first; services are
//! released). The handler only stores to an atomic, which is async-signal-safe.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

/// Set when the process was asked to stop.
pub static STOP: AtomicBool = AtomicBool::new(false);
/// The signal that asked, or 0.
pub static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    STOP_SIGNAL.store(sig, Ordering::Relaxed);
    STOP.store(true, Ordering::Release);
}

/// Installs the handlers. Call once, early in `main`.
pub fn install() {
    for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
        // SAFETY: a zeroed sigaction with a plain handler is valid; the handler only touches
        // atomics.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
            libc::sigemptyset(&mut sa.sa_mask);
            sa.sa_flags = libc::SA_RESTART;
            libc::sigaction(sig, &sa, std::ptr::null_mut());
        }
    }
}

/// Whether a stop was requested.
pub fn stop_requested() -> bool {
    STOP.load(Ordering::Acquire)
}

/// Makes the calling process get SIGTERM when its parent dies, so a killed supervisor never
/// leaves a haptic loop rendering forces on its own. Called in children right after fork.
pub fn die_with_parent() {
    // SAFETY: prctl with constant arguments.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
    }
}
