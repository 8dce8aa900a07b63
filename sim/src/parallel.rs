//! A persistent pool of worker threads for the touched body's step, and the rule that keeps
//! the physics deterministic on it.
//!
//! The rest of this crate is single-threaded and pure; this module is where it stops being so,
//! and it keeps the promise the rest makes: **the result of a step does not depend on the
//! number of threads, bit for bit.** The kernels that use the pool (`fem/batch.rs`) only ever
//! split work whose pieces write disjoint outputs computed by the same arithmetic whatever the
//! split (an element's rotation and forces, a node's sum of its elements' contributions taken in
//! element order): no shared accumulator, no reduction whose order depends on who finished
//! first. So a chunk may run on any thread, the caller may run every chunk itself (when the
//! workers are slow to wake, or another caller holds the pool), and the numbers are the same.
//!
//! Why not rayon: the pool is used a handful of times per step (the forces, then one
//! matrix-free product per CG iteration), each region tens to hundreds of microseconds, on a
//! 2-core machine shared with the haptic loop. What matters is the cost of a fork/join and that
//! steady-state steps allocate nothing; a fixed set of threads that spin briefly, then sleep on
//! a condition variable, with the caller taking chunks too, gives both in ~150 lines without a
//! new dependency. faer's own parallelism (`Par::rayon`) is not used either: the step's solves
//! are the crate's own packed triangular solves of one right-hand side (`fem/packed.rs`),
//! memory-bound and sequential along the elimination tree.
//!
//! Threads are spawned once, by [`WorkerPool::new`]; [`WorkerPool::run`] allocates nothing.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

/// Spins (`pause`, ~10–40 ns each) of an idle worker checking for a new job before it sleeps,
/// and of the caller waiting for the last chunks before it yields: some tens of µs — about the
/// gap between two regions of one CG iteration on an organ (a preconditioner solve), far
/// shorter than the gap between two steps, so a worker does not burn a shared core between
/// steps.
const SPINS: u32 = 2_000;

/// The job in flight: a chunk function with its lifetime erased (see `run` for why that is
/// sound), and the number of chunks.
type JobFn = dyn Fn(usize) + Sync;

/// State shared by the caller and the workers.
struct Shared {
    /// Epoch in the high 32 bits, next unclaimed chunk in the low 32: a worker claims a chunk
    /// with a compare-and-swap that also checks the epoch, so a late worker can never take a
    /// chunk of the next job with the last job's function.
    state: AtomicU64,
    /// Chunks of the current job, and how many are done.
    chunks: AtomicUsize,
    done: AtomicUsize,
    /// The current job's function: written by the caller before it publishes a new epoch,
    /// read by a worker only after it has claimed a chunk of that epoch.
    job: UnsafeCell<Option<*const JobFn>>,
    /// Workers asleep on `wake` (incremented under `sleep`), and the condition they sleep on.
    sleepers: AtomicUsize,
    /// Workers that have started (see `WorkerPool::new`).
    started: AtomicUsize,
    sleep: Mutex<()>,
    wake: Condvar,
    shutdown: AtomicBool,
}

// SAFETY: `job` is written only by the one caller holding `caller` while no chunk of the
// previous epoch is unfinished, and read by workers only between a successful claim and the
// completion of that chunk (module docs of `run`). The pointee is `Sync`.
unsafe impl Sync for Shared {}
unsafe impl Send for Shared {}

/// A fixed set of worker threads; the thread calling [`WorkerPool::run`] works too.
pub struct WorkerPool {
    threads: usize,
    shared: Arc<Shared>,
    /// One caller at a time; a second concurrent caller runs its chunks alone.
    caller: Mutex<()>,
    handles: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for WorkerPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WorkerPool")
            .field("threads", &self.threads)
            .finish()
    }
}

impl WorkerPool {
    /// A pool of `threads` threads in all: the caller and `threads − 1` workers (none for 0 or
    /// 1). Spawns them now.
    pub fn new(threads: usize) -> WorkerPool {
        let threads = threads.max(1);
        let shared = Arc::new(Shared {
            state: AtomicU64::new(0),
            chunks: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            job: UnsafeCell::new(None),
            sleepers: AtomicUsize::new(0),
            started: AtomicUsize::new(0),
            sleep: Mutex::new(()),
            wake: Condvar::new(),
            shutdown: AtomicBool::new(false),
        });
        let handles = (1..threads)
            .map(|k| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("lop-sim-worker-{k}"))
                    .spawn(move || worker(&shared))
                    .expect("spawn a solver worker thread")
            })
            .collect();
        // A thread's start-up allocates (the runtime's per-thread state): wait for it here, so
        // that no allocation of the pool happens after `new` returns.
        while shared.started.load(Ordering::Acquire) < threads - 1 {
            std::thread::yield_now();
        }
        WorkerPool {
            threads,
            shared,
            caller: Mutex::new(()),
            handles,
        }
    }

    /// Threads in all, the caller included.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Calls `f(c)` once for every chunk `c` in `0..chunks`, on the workers and the calling
    /// thread, and returns when all are done. The chunks must write disjoint data.
    ///
    /// Sound although `f` borrows from the caller's stack: `run` returns only after every
    /// chunk has finished, and a worker dereferences the function only for a chunk it claimed
    /// (of the current epoch) and not yet finished.
    pub fn run(&self, chunks: usize, f: &(dyn Fn(usize) + Sync)) {
        let guard = if self.threads > 1 && chunks > 1 {
            self.caller.try_lock().ok()
        } else {
            None
        };
        let Some(_guard) = guard else {
            (0..chunks).for_each(f);
            return;
        };
        assert!(chunks < u32::MAX as usize, "too many chunks");
        let s = &*self.shared;
        // SAFETY: erases the borrow's lifetime; see the doc comment.
        let ptr: *const JobFn = unsafe { std::mem::transmute::<_, *const JobFn>(f) };
        // No chunk of the previous epoch is in flight (the last `run` waited for them all), so
        // no worker reads `job` now.
        unsafe { *s.job.get() = Some(ptr) };
        s.chunks.store(chunks, Ordering::Relaxed);
        s.done.store(0, Ordering::Relaxed);
        let epoch = (s.state.load(Ordering::Relaxed) >> 32) + 1;
        s.state.store(epoch << 32, Ordering::SeqCst);
        if s.sleepers.load(Ordering::SeqCst) > 0 {
            let _g = s.sleep.lock().unwrap_or_else(|e| e.into_inner());
            s.wake.notify_all();
        }
        work(s, epoch);
        // The last chunks are on workers: spin, then yield (a worker preempted mid-chunk on a
        // busy machine must get the core back).
        let mut spins = 0u32;
        while s.done.load(Ordering::Acquire) < chunks {
            if spins < SPINS {
                spins += 1;
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
    }
}

impl Drop for WorkerPool {
    fn drop(&mut self) {
        let s = &*self.shared;
        s.shutdown.store(true, Ordering::SeqCst);
        {
            let _g = s.sleep.lock().unwrap_or_else(|e| e.into_inner());
            s.wake.notify_all();
        }
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

/// Claims and runs chunks of epoch `epoch` until none is left (or the epoch has moved on).
fn work(s: &Shared, epoch: u64) {
    loop {
        let state = s.state.load(Ordering::Acquire);
        if state >> 32 != epoch {
            return;
        }
        let chunk = (state & 0xffff_ffff) as usize;
        if chunk >= s.chunks.load(Ordering::Relaxed) {
            return;
        }
        if s.state
            .compare_exchange_weak(state, state + 1, Ordering::AcqRel, Ordering::Relaxed)
            .is_err()
        {
            continue;
        }
        // SAFETY: a chunk of this epoch is claimed and unfinished, so the caller is inside
        // `run` and `job` holds its live function.
        let f = unsafe { (*s.job.get()).expect("a job is set") };
        unsafe { (*f)(chunk) };
        s.done.fetch_add(1, Ordering::Release);
    }
}

/// A worker's life: wait for a new epoch (spinning, then asleep), work on it, repeat.
fn worker(s: &Shared) {
    s.started.fetch_add(1, Ordering::Release);
    let mut seen = 0u64;
    loop {
        let mut spins = 0;
        let epoch = loop {
            if s.shutdown.load(Ordering::Acquire) {
                return;
            }
            let e = s.state.load(Ordering::Acquire) >> 32;
            if e != seen {
                break e;
            }
            if spins < SPINS {
                spins += 1;
                std::hint::spin_loop();
                continue;
            }
            let mut g = s.sleep.lock().unwrap_or_else(|e| e.into_inner());
            s.sleepers.fetch_add(1, Ordering::SeqCst);
            while s.state.load(Ordering::SeqCst) >> 32 == seen && !s.shutdown.load(Ordering::SeqCst)
            {
                g = s.wake.wait(g).unwrap_or_else(|e| e.into_inner());
            }
            s.sleepers.fetch_sub(1, Ordering::SeqCst);
            spins = 0;
        };
        seen = epoch;
        work(s, epoch);
    }
}

/// Splits `0..len` into `chunks` contiguous ranges of near-equal size; range `c`.
pub(crate) fn chunk_range(len: usize, chunks: usize, c: usize) -> std::ops::Range<usize> {
    let (q, r) = (len / chunks, len % chunks);
    let start = c * q + c.min(r);
    start..start + q + usize::from(c < r)
}

/// A raw pointer to a slice that chunks write in disjoint ranges (see [`WorkerPool::run`]).
#[derive(Clone, Copy)]
pub(crate) struct SharedMut<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: used only to hand disjoint ranges of one slice to the chunks of one `run`.
unsafe impl<T: Send> Send for SharedMut<T> {}
unsafe impl<T: Send> Sync for SharedMut<T> {}

impl<T> SharedMut<T> {
    pub(crate) fn new(s: &mut [T]) -> SharedMut<T> {
        SharedMut {
            ptr: s.as_mut_ptr(),
            len: s.len(),
        }
    }

    /// The sub-slice `range`.
    ///
    /// # Safety
    /// No two live sub-slices may overlap, and the slice must outlive them.
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.end - range.start)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chunk_runs_once() {
        let pool = WorkerPool::new(2);
        for n in [0usize, 1, 2, 7, 64] {
            let hits: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
            for _ in 0..200 {
                pool.run(n, &|c| {
                    hits[c].fetch_add(1, Ordering::Relaxed);
                });
            }
            assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 200));
        }
        let ranges: Vec<_> = (0..3).map(|c| chunk_range(10, 3, c)).collect();
        assert_eq!(ranges, vec![0..4, 4..7, 7..10]);
    }
}
