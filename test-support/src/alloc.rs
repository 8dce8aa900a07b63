//! A counting global allocator for the "allocates nothing" tests. Every allocation is forwarded
//! to the system allocator unchanged; what is counted depends on the mode the test binary
//! installs:
//!
//! ```
//! #[global_allocator]
//! static A: lop_test_support::alloc::Counting = lop_test_support::alloc::Counting::armed_threads();
//! # fn main() {
//! #     let c = lop_test_support::alloc::this_thread(|| drop(vec![0u8; 8]));
//! #     assert_eq!(c.allocations, 1);
//! # }
//! ```
//!
//! - [`Counting::armed_threads`]: only allocations made by a thread while it is armed
//!   ([`arm`], [`counted`], [`this_thread`]) count, so the harness's and other tests' threads
//!   cannot disturb the count;
//! - [`Counting::every_thread`]: every allocation of every thread counts in the process-wide
//!   totals (for a test binary with a single test that must see allocations made on any thread).
//!
//! Two sets of counters: process-wide totals ([`allocations`], [`bytes`], zeroed by [`reset`]),
//! for a test that arms one thread (a servo thread, say) and reads the count from another; and
//! per-thread counts ([`this_thread`]), for a test that measures work done on its own thread
//! while other tests run in parallel. [`largest_on_this_thread`] gives the largest single
//! allocation instead, for the readers' bounded-memory tests.
//!
//! An allocation is one call of `alloc`, `alloc_zeroed` or `realloc`; its bytes are the size
//! asked for (the new size for `realloc`). Calls of `dealloc` are counted apart
//! ([`deallocations`]): freeing can take the allocator's locks too, so a real-time path must
//! not free either.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

/// The counting allocator; install it with `#[global_allocator]` (see the module docs).
pub struct Counting {
    every_thread: bool,
}

impl Counting {
    /// Counts only the allocations of armed threads.
    pub const fn armed_threads() -> Counting {
        Counting {
            every_thread: false,
        }
    }

    /// Counts every allocation of every thread in the process-wide totals (armed threads also
    /// in their own per-thread counts).
    pub const fn every_thread() -> Counting {
        Counting { every_thread: true }
    }

    fn note(&self, bytes: usize) {
        // `try_with`: the thread's locals may already be gone while it exits.
        let armed = ARMED.try_with(Cell::get).unwrap_or(false);
        if armed {
            let _ = THREAD_ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
            let _ = THREAD_BYTES.try_with(|c| c.set(c.get() + bytes as u64));
            let _ = THREAD_LARGEST.try_with(|c| c.set(c.get().max(bytes as u64)));
        }
        if armed || self.every_thread {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            BYTES.fetch_add(bytes as u64, Ordering::Relaxed);
        }
    }
}

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
static BYTES: AtomicU64 = AtomicU64::new(0);
static DEALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
    static THREAD_ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    static THREAD_BYTES: Cell<u64> = const { Cell::new(0) };
    static THREAD_LARGEST: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards every call to the system allocator unchanged; counting touches only atomics
// and const-initialised thread locals, which never allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.note(layout.size());
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.note(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        self.note(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        let armed = ARMED.try_with(Cell::get).unwrap_or(false);
        if armed || self.every_thread {
            DEALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Allocations and their bytes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Calls of `alloc`, `alloc_zeroed` and `realloc`.
    pub allocations: u64,
    /// Bytes asked for by those calls.
    pub bytes: u64,
}

/// Arms this thread: its allocations count from now on.
pub fn arm() {
    ARMED.with(|a| a.set(true));
}

/// Disarms this thread.
pub fn disarm() {
    ARMED.with(|a| a.set(false));
}

/// Runs `f` with this thread armed, then restores its previous state.
pub fn counted<R>(f: impl FnOnce() -> R) -> R {
    let was = ARMED.with(|a| a.replace(true));
    let r = f();
    ARMED.with(|a| a.set(was));
    r
}

/// The allocations `f` makes on this thread (other threads cannot disturb the count). They
/// also count in the process-wide totals.
pub fn this_thread(f: impl FnOnce()) -> Counts {
    let before = thread_counts();
    counted(f);
    let after = thread_counts();
    Counts {
        allocations: after.allocations - before.allocations,
        bytes: after.bytes - before.bytes,
    }
}

/// Runs `f` with this thread armed and returns its result and the largest single allocation
/// (in bytes) it made on this thread: what the bounded-memory tests of the readers compare
/// with the size of their input.
pub fn largest_on_this_thread<R>(f: impl FnOnce() -> R) -> (R, u64) {
    let outer = THREAD_LARGEST.with(|c| c.replace(0));
    let r = counted(f);
    let largest = THREAD_LARGEST.with(|c| c.replace(c.get().max(outer)));
    (r, largest)
}

fn thread_counts() -> Counts {
    Counts {
        allocations: THREAD_ALLOCATIONS.with(Cell::get),
        bytes: THREAD_BYTES.with(Cell::get),
    }
}

/// Zeroes the process-wide totals.
pub fn reset() {
    ALLOCATIONS.store(0, Ordering::Relaxed);
    BYTES.store(0, Ordering::Relaxed);
    DEALLOCATIONS.store(0, Ordering::Relaxed);
}

/// Process-wide calls of `dealloc` counted since the last [`reset`] (armed threads, or every
/// thread with [`Counting::every_thread`]).
pub fn deallocations() -> u64 {
    DEALLOCATIONS.load(Ordering::Relaxed)
}

/// Process-wide allocations counted since the last [`reset`].
pub fn allocations() -> u64 {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Process-wide bytes counted since the last [`reset`].
pub fn bytes() -> u64 {
    BYTES.load(Ordering::Relaxed)
}
