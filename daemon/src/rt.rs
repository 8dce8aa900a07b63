//! Real-time plumbing for the haptic thread: memory locking, core pinning, `SCHED_FIFO`,
//! absolute-deadline sleeping and stack pre-faulting.
//!
//! Every privilege is optional: when one is missing (an unprivileged container, a laptop) the
//! function says why once, returns `false`, and the loop runs anyway with worse jitter.

use std::time::Duration;

/// Nanoseconds per second.
pub const NS_PER_S: u64 = 1_000_000_000;

/// Locks current and future pages in RAM so the RT thread never takes a page fault.
pub fn lock_memory() -> Result<(), String> {
    // SAFETY: plain syscall with constant flags.
    let r = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if r == 0 {
        Ok(())
    } else {
        Err(format!(
            "mlockall failed ({}); raise RLIMIT_MEMLOCK (ulimit -l unlimited, or LimitMEMLOCK=infinity in the systemd unit)",
            std::io::Error::last_os_error()
        ))
    }
}

/// Pins the calling thread to `core`.
pub fn pin_to_core(core: usize) -> Result<(), String> {
    let ids = core_affinity::get_core_ids().unwrap_or_default();
    match ids.into_iter().find(|c| c.id == core) {
        Some(id) if core_affinity::set_for_current(id) => Ok(()),
        Some(_) => Err(format!("could not pin to core {core}")),
        None => Err(format!("core {core} is not available to this process")),
    }
}

/// Keeps the calling thread (and the threads it starts later) off `core`: its affinity becomes
/// every core it may run on but that one. Refused when that would leave none.
pub fn avoid_core(core: usize) -> Result<(), String> {
    // SAFETY: `cpu_set_t` is plain data, zeroed is the empty set; the calls get its true size.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        let size = std::mem::size_of::<libc::cpu_set_t>();
        if libc::sched_getaffinity(0, size, &mut set) != 0 {
            return Err(format!(
                "sched_getaffinity: {}",
                std::io::Error::last_os_error()
            ));
        }
        if core >= libc::CPU_SETSIZE as usize || !libc::CPU_ISSET(core, &set) {
            return Ok(());
        }
        libc::CPU_CLR(core, &mut set);
        if libc::CPU_COUNT(&set) == 0 {
            return Err(format!(
                "core {core} is the only core this process may run on"
            ));
        }
        if libc::sched_setaffinity(0, size, &set) != 0 {
            return Err(format!(
                "sched_setaffinity: {}",
                std::io::Error::last_os_error()
            ));
        }
    }
    Ok(())
}

/// The haptic loop's core: `[haptic] core`, else [`last_core`]. The loop, its frame thread and
/// the deformation thread (which keeps off it) all place themselves by this one rule.
pub fn haptic_core(haptic: &lop_config::HapticConfig) -> Option<usize> {
    haptic.core.or_else(last_core)
}

/// Index of the last core this process may run on: the default for the RT thread, so core 0
/// keeps interrupts and housekeeping.
pub fn last_core() -> Option<usize> {
    core_affinity::get_core_ids().and_then(|ids| ids.iter().map(|c| c.id).max())
}

/// Gives the calling thread `SCHED_FIFO` at `priority` (1..=99).
pub fn set_fifo(priority: u8) -> Result<(), String> {
    use thread_priority::*;
    let prio = ThreadPriority::Crossplatform(
        ThreadPriorityValue::try_from(priority.min(99)).map_err(|e| format!("{e:?}"))?,
    );
    set_thread_priority_and_policy(
        thread_native_id(),
        prio,
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| {
        format!(
            "SCHED_FIFO refused ({e:?}); grant CAP_SYS_NICE or an rtprio limit (LimitRTPRIO=99)"
        )
    })
}

/// Gives the calling thread the normal scheduler (`SCHED_OTHER`; lowering itself needs no
/// privilege). A helper thread started by a `SCHED_FIFO` thread inherits its policy and would
/// hold that thread's core until it blocks; at the normal policy it runs only in the time the
/// real-time thread leaves.
pub fn set_normal() -> Result<(), String> {
    use thread_priority::*;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(
            ThreadPriorityValue::try_from(0).map_err(|e| format!("{e:?}"))?,
        ),
        ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
    )
    .map_err(|e| format!("{e:?}"))
}

/// Touches `bytes` of stack so later deep calls never fault a new stack page in.
#[inline(never)]
pub fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 16 * 1024;
    fn touch(remaining: usize) {
        let mut buf = [0u8; CHUNK];
        // black_box keeps the buffer and the writes.
        std::hint::black_box(&mut buf);
        if remaining > CHUNK {
            touch(remaining - CHUNK);
        }
    }
    touch(bytes);
}

/// Now on `CLOCK_MONOTONIC`, ns.
#[inline]
pub fn now_ns() -> u64 {
    lop_ipc::clock::monotonic_ns()
}

/// Sleeps until the absolute `CLOCK_MONOTONIC` time `deadline_ns` minus `spin_ns`, then spins
/// until the deadline. Returns the wake-up time. No allocation; the only syscall is the sleep.
#[inline]
pub fn sleep_until(deadline_ns: u64, spin_ns: u64) -> u64 {
    let sleep_to = deadline_ns.saturating_sub(spin_ns);
    if now_ns() < sleep_to {
        let ts = libc::timespec {
            tv_sec: (sleep_to / NS_PER_S) as libc::time_t,
            tv_nsec: (sleep_to % NS_PER_S) as libc::c_long,
        };
        // SAFETY: valid timespec; TIMER_ABSTIME sleep on CLOCK_MONOTONIC. EINTR just returns
        // early and the spin below finishes the wait.
        unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
    }
    loop {
        let now = now_ns();
        if now >= deadline_ns {
            return now;
        }
        std::hint::spin_loop();
    }
}

/// A `Duration` as ns, saturating.
pub fn ns(d: Duration) -> u64 {
    d.as_nanos().min(u64::MAX as u128) as u64
}

/// How the calling thread gets its real-time priority.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Priority {
    /// Ask for `SCHED_FIFO` at this priority (the timed loop's own thread).
    Fifo(u8),
    /// The thread's owner set it (the device's servo thread): only check and report it.
    Inherited,
}

/// What [`set_up_thread`] obtained, as `RT_FLAG_*` bits and the pinned core (-1: none), for
/// the loop's telemetry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtState {
    /// `RT_FLAG_*` bits.
    pub flags: u32,
    /// The core the thread is pinned to, or -1.
    pub pinned_core: i32,
}

/// The real-time set-up of the calling thread, shared by the timed haptic loop and the
/// device-clocked servo path: pin to `core`, the priority as `priority` says, note whether
/// memory is locked, and pre-fault `prefault_stack` bytes of stack. Each privilege is optional:
/// a missing one is reported once (`who` names the thread) and the thread runs anyway.
pub fn set_up_thread(
    who: &str,
    core: Option<usize>,
    priority: Priority,
    prefault_stack_bytes: usize,
) -> RtState {
    use lop_ipc::{RT_FLAG_FIFO, RT_FLAG_MLOCKED, RT_FLAG_PINNED};
    let mut state = RtState {
        flags: 0,
        pinned_core: -1,
    };
    if let Some(core) = core {
        match pin_to_core(core) {
            Ok(()) => {
                state.flags |= RT_FLAG_PINNED;
                state.pinned_core = core as i32;
            }
            Err(e) => tracing::warn!("{who} not pinned: {e}"),
        }
    }
    match priority {
        Priority::Fifo(p) => match set_fifo(p) {
            Ok(()) => state.flags |= RT_FLAG_FIFO,
            Err(e) => tracing::warn!("{who} runs without real-time priority: {e}"),
        },
        // SAFETY: plain query of the calling thread's policy.
        Priority::Inherited => {
            if unsafe { libc::sched_getscheduler(0) } == libc::SCHED_FIFO {
                state.flags |= RT_FLAG_FIFO;
            } else {
                tracing::warn!(
                    "{who} does not run SCHED_FIFO: grant the service real-time limits \
                     (LimitRTPRIO, see docs/deploy.md)"
                );
            }
        }
    }
    if crate::MEMORY_LOCKED.load(std::sync::atomic::Ordering::Relaxed) {
        state.flags |= RT_FLAG_MLOCKED;
    }
    if prefault_stack_bytes > 0 {
        prefault_stack(prefault_stack_bytes);
    }
    state
}
