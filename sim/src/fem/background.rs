//! Factors off the critical path ([`RefactorPolicy::Background`]): a new factorisation of `K̃`
//! — the lagged preconditioner refreshed because CG stalled or its extra iterations add up to
//! a factorisation's price, or a new step period, which changes `K̃ = M/Δt² + D/(2Δt) + K` —
//! is assembled and factorised on a thread of the body's own, and swapped in at a fixed step
//! count: requested during (or before) step `s`, it is used from step `s + D`, `D` the
//! policy's `delay_steps`. Until then the steps go on with the factor (and the period) they
//! had. The job carries a snapshot of everything the factorisation reads (the rotated
//! gradients, the per-node rotations, the period), so the factor that lands is the same
//! whatever the thread's speed, and a run is deterministic: two runs give the same positions
//! bit for bit.
//!
//! If the factor is not ready when step `s + D` begins, that step **waits** for it (counted:
//! [`super::SolverCounters::factor_waits`]); it never computes one itself and never uses the
//! old one instead, which would make the trajectory depend on timing. Pick `D` from the
//! measured factorisation time over the step period (with headroom for a loaded machine).
//!
//! One job is in flight at a time. A stall while one is in flight asks for nothing more (the
//! new factor is on its way); a period change asked while one is in flight is queued and
//! requested when that one lands.
//!
//! Steady state allocates nothing: the job's buffers (a spare `System` with its factor, the
//! snapshot) go back and forth between the body and its thread; the two `System`s are swapped,
//! not copied.

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

use super::batch::WarpedBatch;
use super::element::Element;
use super::system::{Precision, System};

/// What the factor thread assembles from: the body's elements and masses (never change).
#[derive(Debug)]
pub(super) struct AssemblyData {
    pub elements: Vec<Element>,
    pub mass: Vec<f64>,
    pub lambda: f64,
    pub mu: f64,
    pub damping: f64,
}

/// One factorisation: its inputs (a snapshot) and its output (the spare system, factorised).
#[derive(Debug, Clone)]
pub(super) struct Job {
    /// The spare system: same pattern and numbering as the body's; the factor lands here.
    pub system: Box<System>,
    /// The rotated gradients per batch at the request (corotational), as `Batches` keeps them.
    pub warped: Vec<WarpedBatch>,
    /// The per-node rotations at the request: the new factor's `node_rot_lag`.
    pub node_rot: Vec<[f64; 4]>,
    /// The period the factor is for, s.
    pub dt: f64,
    /// Warped stiffness (from `warped`) or the rest stiffness.
    pub warped_stiffness: bool,
    /// Single precision (the corotational preconditioner, double on failure) or double.
    pub single: bool,
    /// Whether the factorisation succeeded.
    pub ok: bool,
}

#[derive(Debug, Default)]
struct Slot {
    /// The job, while it is with the thread (to do, or done).
    job: Option<Box<Job>>,
    done: bool,
    shutdown: bool,
    /// Set by the thread once it runs (its start-up allocates: `spawn` waits for it).
    started: bool,
}

#[derive(Debug, Default)]
struct Shared {
    slot: Mutex<Slot>,
    changed: Condvar,
    /// Tests only: the thread sleeps this long (µs) before each factorisation, to show that
    /// the results do not depend on its speed.
    slowdown_us: std::sync::atomic::AtomicU64,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Slot> {
        self.slot.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A body's factor thread and the bookkeeping of the job in flight.
#[derive(Debug)]
pub(super) struct FactorThread {
    shared: Arc<Shared>,
    data: Arc<AssemblyData>,
    handle: Option<JoinHandle<()>>,
    /// The job's buffers while no job is in flight.
    home: Option<Box<Job>>,
    /// The step from which the job in flight is used, and its period.
    pub due: Option<(u64, f64)>,
    /// A period change asked while a job was in flight.
    pub queued_dt: Option<f64>,
    /// `D`.
    pub delay: u32,
    /// Steps that waited for their factor, and factors swapped in.
    pub waits: u64,
    pub landed: u64,
}

impl FactorThread {
    /// Spawns the thread, with `system` (a clone of the body's) as the spare, and has it
    /// factorise the rest matrix at period `warm_dt` once (in single precision if
    /// `warm_single`), as a warm-up.
    pub fn new(
        data: Arc<AssemblyData>,
        system: Box<System>,
        n_batches: usize,
        delay: u32,
        (warm_dt, warm_single): (f64, bool),
    ) -> Self {
        let n_nodes = data.mass.len();
        let home = Box::new(Job {
            system,
            warped: vec![[[[0.0; super::batch::LANES]; 3]; 4]; n_batches],
            node_rot: vec![[1.0, 0.0, 0.0, 0.0]; n_nodes],
            dt: 0.0,
            warped_stiffness: false,
            single: false,
            ok: false,
        });
        let mut t = FactorThread::spawn(data, None);
        t.home = Some(home);
        t.delay = delay;
        // One factorisation now, thrown away: the first one on a thread allocates its
        // per-thread scratch (faer's matrix kernels keep some in thread-locals), and the steps
        // after `new` must not see that.
        if let Some(job) = t.idle_job() {
            job.dt = warm_dt;
            job.single = warm_single;
        }
        t.send(0);
        t.collect();
        (t.due, t.landed, t.waits) = (None, 0, 0);
        t
    }

    fn spawn(data: Arc<AssemblyData>, done: Option<Box<Job>>) -> FactorThread {
        let shared = Arc::new(Shared::default());
        if let Some(job) = done {
            let mut slot = shared.lock();
            slot.job = Some(job);
            slot.done = true;
        }
        let (s, d) = (Arc::clone(&shared), Arc::clone(&data));
        let handle = std::thread::Builder::new()
            .name("lop-sim-factor".into())
            .spawn(move || run(&s, &d))
            .expect("spawn the factor thread");
        {
            let mut slot = shared.lock();
            while !slot.started {
                slot = shared.changed.wait(slot).unwrap_or_else(|e| e.into_inner());
            }
        }
        FactorThread {
            shared,
            data,
            handle: Some(handle),
            home: None,
            due: None,
            queued_dt: None,
            delay: 0,
            waits: 0,
            landed: 0,
        }
    }

    /// Tests only: sleep `us` µs before each factorisation.
    pub fn slow_down(&self, us: u64) {
        self.shared
            .slowdown_us
            .store(us, std::sync::atomic::Ordering::Relaxed);
    }

    /// The job's buffers to fill, if no job is in flight.
    pub fn idle_job(&mut self) -> Option<&mut Job> {
        self.home.as_deref_mut()
    }

    /// Sends the job filled through [`FactorThread::idle_job`], to be used from step `due`.
    pub fn send(&mut self, due: u64) {
        let Some(job) = self.home.take() else {
            return;
        };
        self.due = Some((due, job.dt));
        let mut slot = self.shared.lock();
        slot.job = Some(job);
        slot.done = false;
        self.shared.changed.notify_all();
    }

    /// The job in flight, done: waits for it if it is not (counted in `waits`).
    pub fn collect(&mut self) -> &mut Job {
        if self.home.is_none() {
            let mut slot = self.shared.lock();
            if !slot.done {
                self.waits += 1;
                while !slot.done {
                    slot = self
                        .shared
                        .changed
                        .wait(slot)
                        .unwrap_or_else(|e| e.into_inner());
                }
            }
            slot.done = false;
            self.home = slot.job.take();
            self.due = None;
            self.landed += 1;
        }
        self.home.as_deref_mut().expect("the job is home")
    }
}

impl Clone for FactorThread {
    /// A new thread with a copy of the job: a job in flight is waited for and its result
    /// copied (a clone is taken outside the step's hot path).
    fn clone(&self) -> FactorThread {
        let (home, done) = match &self.home {
            Some(job) => (Some(job.clone()), None),
            None => {
                let mut slot = self.shared.lock();
                while !slot.done {
                    slot = self
                        .shared
                        .changed
                        .wait(slot)
                        .unwrap_or_else(|e| e.into_inner());
                }
                (None, slot.job.clone())
            }
        };
        let mut t = FactorThread::spawn(Arc::clone(&self.data), done);
        t.home = home;
        t.due = self.due;
        t.queued_dt = self.queued_dt;
        t.delay = self.delay;
        t.waits = self.waits;
        t.landed = self.landed;
        t
    }
}

impl Drop for FactorThread {
    fn drop(&mut self) {
        self.shared.lock().shutdown = true;
        self.shared.changed.notify_all();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// The thread: wait for a job, assemble and factorise it, hand it back.
fn run(shared: &Shared, data: &AssemblyData) {
    shared.lock().started = true;
    shared.changed.notify_all();
    loop {
        let mut job = {
            let mut slot = shared.lock();
            loop {
                if slot.shutdown {
                    return;
                }
                if !slot.done {
                    if let Some(job) = slot.job.take() {
                        break job;
                    }
                }
                slot = shared.changed.wait(slot).unwrap_or_else(|e| e.into_inner());
            }
        };
        let slow = shared
            .slowdown_us
            .load(std::sync::atomic::Ordering::Relaxed);
        if slow > 0 {
            std::thread::sleep(std::time::Duration::from_micros(slow));
        }
        factorize(&mut job, data);
        let mut slot = shared.lock();
        slot.job = Some(job);
        slot.done = true;
        shared.changed.notify_all();
    }
}

/// Assembles `K̃` for the job's period and stiffness and factorises it, as
/// `Fem::factor_dynamic` does within a step.
fn factorize(job: &mut Job, data: &AssemblyData) {
    let dt = job.dt;
    let system = &mut job.system;
    system.clear_with_mass(&data.mass, 1.0 / (dt * dt) + data.damping / (2.0 * dt));
    for (e, el) in data.elements.iter().enumerate() {
        let (vl, vm) = (el.volume * data.lambda, el.volume * data.mu);
        let g = if job.warped_stiffness {
            super::batch::warped_of(&job.warped, e)
        } else {
            el.grad
        };
        system.add_element(e, &g, vl, vm);
    }
    job.ok = (job.single && system.factorize(Precision::Single).is_ok())
        || system.factorize(Precision::Double).is_ok();
}

impl super::Fem {
    /// Starts the factor thread (once), with a copy of the system as its spare, and sets `D`.
    pub(super) fn start_factor_thread(&mut self, delay: u32) {
        if let Some(t) = &mut self.background {
            t.delay = delay;
            return;
        }
        let data = Arc::new(AssemblyData {
            elements: self.elements.clone(),
            mass: self.mass.clone(),
            lambda: self.lambda,
            mu: self.mu,
            damping: self.params.damping,
        });
        let spare = Box::new((*self.system).clone());
        let batches = self.s.batch.warped_batches().len();
        let single = self.params.mode == super::FemMode::Corotational
            && self.solver == super::CorotationalSolver::LaggedFactorPcg;
        self.background = Some(Box::new(FactorThread::new(
            data,
            spare,
            batches,
            delay,
            (self.params.dt, single),
        )));
    }

    /// Asks the factor thread for the factor of `K̃` at the new `period` (`None`: the current
    /// one) with the current rotations
    /// (corotational) or at rest (linear), to be used from step `steps + D`. Does nothing if a
    /// job is in flight (a period change is queued instead). Copies the snapshot; allocation-
    /// free.
    pub(super) fn request_factor(&mut self, period: Option<f64>) {
        let dt = period.unwrap_or(self.params.dt);
        let corotational = self.params.mode == super::FemMode::Corotational;
        let single = corotational && self.solver == super::CorotationalSolver::LaggedFactorPcg;
        if corotational && self.background.as_ref().is_some_and(|t| t.home.is_some()) {
            // The snapshot's rotations are the element rotations it copies.
            self.ensure_node_rotations();
        }
        let due = self.counters.steps + u64::from(self.background.as_ref().map_or(0, |t| t.delay));
        let Some(t) = self.background.as_deref_mut() else {
            return;
        };
        let Some(job) = t.idle_job() else {
            // A period change waits for the job in flight (the latest asked wins; none if it
            // is the period on its way); a refresh is moot, one is on its way.
            if let Some(dt) = period {
                let coming = t.due.map_or(self.params.dt, |d| d.1);
                t.queued_dt = (dt != coming).then_some(dt);
            }
            return;
        };
        job.dt = dt;
        job.single = single;
        job.warped_stiffness = corotational;
        if corotational {
            job.warped.copy_from_slice(self.s.batch.warped_batches());
            job.node_rot.copy_from_slice(&self.s.node_rot);
        }
        t.send(due);
    }

    /// At the start of a step: if a factor is due now, takes it (waiting for it if need be)
    /// and swaps it in, with its period; then sends a queued period change.
    pub(super) fn land_due_factor(&mut self) -> Result<(), super::Failed> {
        let steps = self.counters.steps;
        let Some(t) = self.background.as_deref_mut() else {
            return Ok(());
        };
        if t.due.map(|d| d.0) != Some(steps) {
            return Ok(());
        }
        let job = t.collect();
        // Steps' factorisations stay counted with the body's system.
        let in_step = self.system.factorizations();
        std::mem::swap(&mut self.system, &mut job.system);
        self.system.set_factorizations(in_step);
        self.params.dt = job.dt;
        let (ok, warped) = (job.ok, job.warped_stiffness);
        if warped {
            self.s.node_rot_lag.copy_from_slice(&job.node_rot);
        } else {
            self.s
                .node_rot_lag
                .iter_mut()
                .for_each(|q| *q = super::rotation::QUAT_IDENTITY);
        }
        let queued = t.queued_dt.take();
        self.extra_iterations = 0;
        self.baseline_iterations = None;
        self.s
            .inv_key
            .iter_mut()
            .for_each(|k| *k = super::system::NONE);
        self.clear_patch_cache();
        self.s
            .node_turn
            .iter_mut()
            .for_each(|t| *t = super::rotation::IDENTITY);
        // The turn is from the landed factor's rotations now: made again before it is used.
        self.s.node_rot_stale = true;
        if !ok {
            self.factor = super::Factor::Stale;
            return Err(super::Failed);
        }
        self.factor = if warped {
            super::Factor::WarpedDynamic
        } else {
            super::Factor::RestDynamic
        };
        if let Some(dt) = queued {
            if dt != self.params.dt {
                self.request_factor(Some(dt));
            }
        }
        Ok(())
    }
}
