//! The contract's clock: `CLOCK_MONOTONIC` in nanoseconds.
//!
//! `CLOCK_MONOTONIC` is system-wide on Linux, so a timestamp written by one process can be
//! subtracted from one read in another. Reading it is a vDSO call: no syscall, no allocation,
//! safe on the real-time thread.

/// Nanoseconds on `CLOCK_MONOTONIC`.
#[inline]
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}
