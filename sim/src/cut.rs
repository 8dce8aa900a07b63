//! Cutting a body while the world runs: tetrahedra removed, the models, the contact structures
//! and the heat model rebuilt for the new mesh, the state carried over.
//!
//! A cut is two halves, so that the dear one can run off the critical path:
//!
//! 1. [`World::cut_source`] copies what a cut of body `i` is made from (its rest mesh, its
//!    precise model's parameters, its heat parameters, its topology epoch): cheap, on the
//!    stepping thread. [`CutSource::prepare`] then removes the tetrahedra from the mesh
//!    ([`TetMesh::without_tets`]: the pieces a cut leaves loose or too small go with it) and
//!    builds the precise model and the heat model on the new mesh, at rest: the assembly, the
//!    orderings and the factorisations, milliseconds to a second. It reads nothing of the
//!    world, so it may run on any thread while the body goes on stepping on the old mesh.
//! 2. [`World::apply_cut`] swaps the prepared body in between two steps: the new model takes
//!    the old one's positions and velocities node by node (nodes keep their numbers; the ones
//!    the cut left unused are held where they are), its period, refactor policy and worker
//!    pool; the surface, the tools' contact scratch, organ collision and the heat model follow;
//!    the body's [`epoch`](crate::world::Body::epoch) counts one more topology. Cheap: no
//!    factorisation. A prepared cut whose epoch is no longer the body's (another cut landed
//!    first) is refused, never applied to a mesh it was not made for.
//!
//! The step in flight finishes on the old mesh; the caller decides when a prepared cut lands.
//! Applied at a fixed step count after its request, a run is the same whatever the thread's
//! speed. [`World::cut_body`] does both halves at once (tests, offline tools).
//!
//! **Electrosurgical cutting in the rounds** ([`World::set_cutting`]). A tool whose cut button
//! is held ([`RoundTool::cut`]) heats its anchor as the heat button does (at the cut mode's
//! power, [`RoundTool::heat_power`]), and after the round's heat steps every tetrahedron of
//! the touched body with a node under the tip (a node of the anchor's triangle, or within two
//! tool radii of the anchor) at the vaporisation temperature ([`CutParams::vaporization`]) is
//! asked to be cut away. A node, not the tetrahedron's mean: a real electrode vaporises a layer
//! a fraction of a millimetre thick where it touches, far thinner than an organ mesh's
//! tetrahedra (the shipped liver's are about a centimetre across), whose lumped heat capacity
//! holds the node temperature back: the shipped liver's node under the tip warms by about
//! 14 K a second at the default 80 W, so its first cut comes about 4.5 s into a cut. Intracellular water
//! boils at 100 °C and the cells burst into steam: that is how an electrosurgical cut
//! separates tissue (Massarweh, Cosgriff and Slakey, *Electrosurgery: history, principles,
//! and current and future uses*, J. Am. Coll. Surg. 202 (2006) 520–530), hence the default.
//! The cut is prepared on a thread of its own and lands [`CutParams::delay_steps`] steps of
//! the body later, before that step; a step that finds it not ready waits for it
//! ([`CutEvent::Landed::waited`]), so the cut lands at the same step whatever the thread's
//! speed and a run is deterministic. One cut per body is in flight at a time; the body's
//! tissue that vaporises meanwhile goes with the next. A refused cut (it would leave no piece)
//! is not asked again for [`RETRY_STEPS`] of the body's steps. Selecting costs one pass over
//! the body's tetrahedra per round while the button is held on it.
//!
//! **A cut body keeps its precise model.** Its levels-of-precision controller is dropped: the
//! Green-coordinates cage was fitted to the uncut shape, and its harmonic deformation of the
//! interior cannot open a wound, so a cut body never returns to it. A body that only has a cage
//! (`model = "gc"`) cannot be cut ([`CutError::NoPreciseModel`]).
//!
//! **The tools start a new contact.** Each tool's contact patch, local model and free-motion
//! history refer to surface triangles of the old mesh and are dropped: the next step gathers a
//! patch on the new surface.

use std::fmt;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

use crate::contact::closest_on_surface;
use crate::fem::{Fem, FemError, FemParameters};
use crate::heat::{HeatBody, HeatError, HeatParameters};
use crate::interaction::ToolAnchor;
use crate::mesh::{CutRefused, MeshCut, TetMesh};
use crate::model::Model;
use crate::msd::{MassSpring, MsdParameters, SubstepPolicy};
use crate::world::{Coupling, RoundTool, World};

/// Why a cut was not made. Nothing changed in the world.
#[derive(Debug, Clone, PartialEq)]
pub enum CutError {
    /// No body of that index.
    NoBody {
        /// The index asked.
        body: usize,
        /// Bodies in the world.
        bodies: usize,
    },
    /// The body runs only a Green-coordinates cage, which cannot represent a cut.
    NoPreciseModel {
        /// The body's name.
        body: String,
    },
    /// The mesh refused the cut ([`CutRefused`]).
    Refused {
        /// The body's name.
        body: String,
        /// Why.
        why: CutRefused,
    },
    /// The model could not be built on the cut mesh.
    Model {
        /// The body's name.
        body: String,
        /// The model's error.
        why: String,
    },
    /// The cut was prepared for topology `prepared` of the body, which is at `current` now.
    Stale {
        /// The body's name.
        body: String,
        /// Epoch the cut was made from.
        prepared: u64,
        /// The body's epoch now.
        current: u64,
    },
}

impl fmt::Display for CutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CutError::NoBody { body, bodies } => {
                write!(f, "no body {body} to cut (the world has {bodies})")
            }
            CutError::NoPreciseModel { body } => write!(
                f,
                "body {body:?} runs only a Green-coordinates cage, which cannot be cut: give it \
                 model = \"auto\", \"fem\" or \"msd\""
            ),
            CutError::Refused { body, why } => write!(f, "body {body:?}: {why}"),
            CutError::Model { body, why } => {
                write!(f, "body {body:?}: the model on the cut mesh: {why}")
            }
            CutError::Stale {
                body,
                prepared,
                current,
            } => write!(
                f,
                "body {body:?}: a cut prepared on topology {prepared} cannot land on topology \
                 {current}"
            ),
        }
    }
}

impl std::error::Error for CutError {}

/// The precise model a cut rebuilds, by its parameters.
#[derive(Debug, Clone)]
enum Recipe {
    Fem(FemParameters),
    Msd(MsdParameters, SubstepPolicy),
}

/// What a cut of one body is made from ([`World::cut_source`]); [`CutSource::prepare`] runs on
/// any thread.
#[derive(Debug, Clone)]
pub struct CutSource {
    body: usize,
    name: String,
    epoch: u64,
    mesh: TetMesh,
    recipe: Recipe,
    heat: Option<HeatParameters>,
}

/// A cut ready to land ([`World::apply_cut`]).
#[derive(Debug, Clone)]
pub struct PreparedCut {
    body: usize,
    name: String,
    epoch: u64,
    cut: MeshCut,
    model: Model,
    heat: Option<HeatBody>,
}

/// What a cut that landed did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutReport {
    /// The body cut.
    pub body: usize,
    /// Its topology epoch from now on.
    pub epoch: u64,
    /// Tetrahedra removed (asked, and those of the pieces taken out), and left.
    pub removed_tets: usize,
    /// Of `removed_tets`, those of pieces taken out (cut loose, or too small).
    pub piece_tets: usize,
    /// Pieces taken out, and left.
    pub pieces_removed: usize,
    /// Pieces left.
    pub pieces_kept: usize,
    /// Tetrahedra left.
    pub tets_left: usize,
    /// Nodes the cut left unused.
    pub nodes_freed: usize,
    /// Rest volume removed, m³.
    pub volume_removed: f64,
}

impl fmt::Display for CutReport {
    /// What a log line says of a cut: `8 tetrahedra removed (0 of them cut loose or too
    /// small), 1698 left, topology 1`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} tetrahedra removed ({} of them cut loose or too small), {} left, topology {}",
            self.removed_tets, self.piece_tets, self.tets_left, self.epoch
        )
    }
}

impl CutSource {
    /// The body this cut is for.
    pub fn body(&self) -> usize {
        self.body
    }

    /// The body's rest mesh at the epoch the cut starts from (to choose what to remove).
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// Removes the tetrahedra `remove` marks (one entry per tetrahedron of
    /// [`CutSource::mesh`]) and builds the body's precise model, and its heat model if the
    /// world has one, on the cut mesh, at rest. Allocates and factorises.
    ///
    /// # Errors
    /// [`CutError::Refused`], [`CutError::Model`].
    pub fn prepare(self, remove: &[bool]) -> Result<PreparedCut, CutError> {
        let cut = self
            .mesh
            .without_tets(remove)
            .map_err(|why| CutError::Refused {
                body: self.name.clone(),
                why,
            })?;
        let failed = |why: String| CutError::Model {
            body: self.name.clone(),
            why,
        };
        let model = match &self.recipe {
            Recipe::Fem(p) => {
                Model::Fem(Fem::new(&cut.mesh, *p).map_err(|e: FemError| failed(e.to_string()))?)
            }
            Recipe::Msd(p, policy) => {
                Model::MassSpring(MassSpring::new(&cut.mesh, *p).with_substep_policy(*policy))
            }
        };
        let heat = match self.heat {
            Some(p) => {
                Some(HeatBody::new(&cut.mesh, p).map_err(|e: HeatError| failed(e.to_string()))?)
            }
            None => None,
        };
        Ok(PreparedCut {
            body: self.body,
            name: self.name,
            epoch: self.epoch,
            cut,
            model,
            heat,
        })
    }
}

impl PreparedCut {
    /// The mesh the body will have once the cut lands.
    pub fn mesh(&self) -> &TetMesh {
        &self.cut.mesh
    }
}

impl World {
    /// What a cut of body `i` is made from (module docs): a copy of its rest mesh and of its
    /// precise model's and heat model's parameters.
    ///
    /// # Errors
    /// [`CutError::NoBody`], [`CutError::NoPreciseModel`].
    pub fn cut_source(&self, i: usize) -> Result<CutSource, CutError> {
        let b = self.bodies.get(i).ok_or(CutError::NoBody {
            body: i,
            bodies: self.bodies.len(),
        })?;
        let recipe = match precise_model(b) {
            Model::Fem(f) => Recipe::Fem(*f.parameters()),
            Model::MassSpring(m) => Recipe::Msd(*m.params(), m.substep_policy()),
            Model::Gc(_) => {
                return Err(CutError::NoPreciseModel {
                    body: b.name.clone(),
                })
            }
        };
        Ok(CutSource {
            body: i,
            name: b.name.clone(),
            epoch: b.epoch,
            mesh: b.mesh.clone(),
            recipe,
            heat: self
                .heat()
                .and_then(|h| h.bodies().get(i))
                .map(|h| *h.params()),
        })
    }

    /// Lands a prepared cut (module docs) between two steps.
    ///
    /// # Errors
    /// [`CutError::NoBody`], [`CutError::Stale`]; nothing changes.
    pub fn apply_cut(&mut self, prepared: PreparedCut) -> Result<CutReport, CutError> {
        let PreparedCut {
            body: i,
            name,
            epoch,
            cut,
            mut model,
            heat,
        } = prepared;
        let bodies = self.bodies.len();
        let b = self
            .bodies
            .get(i)
            .ok_or(CutError::NoBody { body: i, bodies })?;
        if b.epoch != epoch || b.name != name {
            return Err(CutError::Stale {
                body: name,
                prepared: epoch,
                current: b.epoch,
            });
        }
        if let (Model::Fem(new), Model::Fem(old)) = (&mut model, precise_model(b)) {
            // Both valid: the period and policy the old model runs at now.
            let _ = new.set_dt(old.dt());
            new.set_refactor_policy(old.refactor_policy());
        }
        model.set_state(b.model.positions(), b.model.velocities());
        let heat_state = self.heat().and_then(|h| h.bodies().get(i)).cloned();
        let report = CutReport {
            body: i,
            epoch: epoch + 1,
            removed_tets: cut.removed_tets,
            piece_tets: cut.piece_tets,
            pieces_removed: cut.pieces_removed,
            pieces_kept: cut.pieces_kept,
            tets_left: cut.mesh.tets.len(),
            nodes_freed: cut.nodes_freed,
            volume_removed: cut.volume_removed,
        };
        self.replace_body_topology(i, cut.mesh, model);
        if let (Some(mut new), Some(old)) = (heat, heat_state) {
            // Same node count by construction; a heat model that refuses the swap stops, as a
            // failed heat step does, and the bodies go on.
            let ok = new.take_state(&old).is_ok() && self.replace_heat_body(i, new);
            if !ok {
                self.disable_heat();
            }
        }
        Ok(report)
    }

    /// [`World::cut_source`], [`CutSource::prepare`] and [`World::apply_cut`] at once.
    ///
    /// # Errors
    /// As those three.
    pub fn cut_body(&mut self, i: usize, remove: &[bool]) -> Result<CutReport, CutError> {
        let prepared = self.cut_source(i)?.prepare(remove)?;
        self.apply_cut(prepared)
    }
}

/// The precise model body `b` runs, or has parked under its cage.
fn precise_model(b: &crate::world::Body) -> &Model {
    match (&b.model, &b.lop) {
        (Model::Gc(_), Some(lop)) => lop.parked(),
        (m, _) => m,
    }
}

/// The tetrahedra of `mesh` that vaporise at `temperatures` (°C, one per node): those with a
/// node `under_tip` at `threshold` or hotter (module docs); `None` when there is none, without
/// allocating (what the rounds ask every round while a cut button is held).
pub fn vaporised(
    mesh: &TetMesh,
    temperatures: &[f64],
    threshold: f64,
    under_tip: impl Fn(u32) -> bool,
) -> Option<Vec<bool>> {
    let boiling = |n: u32| {
        temperatures
            .get(n as usize)
            .is_some_and(|&v| v >= threshold)
            && under_tip(n)
    };
    let goes = |t: &[u32; 4]| t.iter().any(|&n| boiling(n));
    // A node no tetrahedron uses any more (an earlier cut's) boils on its own: it takes nothing.
    mesh.tets
        .iter()
        .any(goes)
        .then(|| mesh.tets.iter().map(goes).collect())
}

/// Steps of a body before a cut of it that was refused is asked for again.
pub const RETRY_STEPS: u64 = 100;

/// How a world cuts ([`World::set_cutting`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CutParams {
    /// Node temperature at which the tetrahedra around it under a cutting tip vaporise, °C.
    pub vaporization: f64,
    /// Steps of the body from a cut's request to the step it lands before (at least 1).
    pub delay_steps: u32,
    /// Per body, in body order: whether it may be cut (missing: not).
    pub bodies: Vec<bool>,
}

impl Default for CutParams {
    fn default() -> CutParams {
        CutParams {
            vaporization: 100.0,
            delay_steps: 50,
            bodies: Vec::new(),
        }
    }
}

/// A cut asked for, landed or refused in a round ([`crate::world::RoundReport::cuts`]).
#[derive(Debug, Clone, PartialEq)]
pub enum CutEvent {
    /// Tool `tool` asked for `tets` tetrahedra of body `body` to go; the cut lands before the
    /// body's step `due` (counted from the world's start of cutting).
    Asked {
        /// The body.
        body: usize,
        /// The tool.
        tool: usize,
        /// Tetrahedra asked for.
        tets: usize,
        /// The body's step it lands before.
        due: u64,
    },
    /// A cut landed.
    Landed {
        /// What it did.
        report: CutReport,
        /// The step waited for its preparation.
        waited: bool,
    },
    /// A cut was refused (nothing changed).
    Refused(CutError),
}

type Slot = Arc<(Mutex<Option<Result<PreparedCut, CutError>>>, Condvar)>;

/// A cut being prepared on its thread.
#[derive(Debug)]
struct Pending {
    slot: Slot,
    /// The body's step it lands before.
    due: u64,
}

impl Pending {
    fn wait(&self) -> (MutexGuard<'_, Option<Result<PreparedCut, CutError>>>, bool) {
        let (lock, ready) = &*self.slot;
        let mut g = lock.lock().unwrap_or_else(|e| e.into_inner());
        let waited = g.is_none();
        while g.is_none() {
            g = ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
        (g, waited)
    }
}

impl Clone for Pending {
    /// A copy of the prepared cut (waiting for it if need be): a world's clone lands the same
    /// cut at the same step.
    fn clone(&self) -> Pending {
        let done = self.wait().0.clone();
        Pending {
            slot: Arc::new((Mutex::new(done), Condvar::new())),
            due: self.due,
        }
    }
}

/// Run by a cut's preparation thread before it works: how the caller schedules it (`lopd
/// deform` drops it from its loop's `SCHED_FIFO` to the normal scheduler, so it runs only in
/// the time the steps leave).
pub type ThreadSetup = Arc<dyn Fn() + Send + Sync>;

/// A world's cutting state ([`World::set_cutting`]).
#[derive(Clone)]
pub(crate) struct Cutting {
    params: CutParams,
    setup: Option<ThreadSetup>,
    /// Per body: steps taken since cutting started, the cut in flight, the step from which a
    /// refused cut may be asked again.
    steps: Vec<u64>,
    pending: Vec<Option<Pending>>,
    retry_at: Vec<u64>,
}

impl fmt::Debug for Cutting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Cutting")
            .field("params", &self.params)
            .field("steps", &self.steps)
            .field("pending", &self.pending)
            .field("retry_at", &self.retry_at)
            .finish_non_exhaustive()
    }
}

impl World {
    /// Has every cut's preparation thread run `setup` first (module docs; by default the
    /// thread keeps the scheduling of the thread that asked for the cut). No effect while
    /// cutting is off.
    pub fn set_cut_thread_setup(&mut self, setup: ThreadSetup) {
        if let Some(c) = self.cutting.as_mut() {
            c.setup = Some(setup);
        }
    }

    /// Turns electrosurgical cutting on with `params` (module docs), or off with `None` (a cut
    /// in flight is dropped).
    pub fn set_cutting(&mut self, params: Option<CutParams>) {
        let n = self.bodies.len();
        self.cutting = params.map(|mut params| {
            params.delay_steps = params.delay_steps.max(1);
            Box::new(Cutting {
                params,
                setup: None,
                steps: vec![0; n],
                pending: (0..n).map(|_| None).collect(),
                retry_at: vec![0; n],
            })
        });
    }

    /// How the world cuts, if it does.
    pub fn cutting(&self) -> Option<&CutParams> {
        self.cutting.as_ref().map(|c| &c.params)
    }

    /// Whether body `i` may be cut.
    pub fn cuttable(&self, i: usize) -> bool {
        self.cutting
            .as_ref()
            .is_some_and(|c| c.params.bodies.get(i).copied().unwrap_or(false))
    }

    /// Counts a step of body `i` (the round, after each step).
    pub(crate) fn count_cut_step(&mut self, i: usize) {
        if let Some(s) = self.cutting.as_mut().and_then(|c| c.steps.get_mut(i)) {
            *s += 1;
        }
    }

    /// Lands body `i`'s cut if it is due before the step about to be taken, and moves the
    /// tools' `couplings` on it to the new surface: each anchor to the closest point of the new
    /// surface to where it was on the old one (its offset and grab kept), so the tissue goes
    /// on receiving the tool's force in the steps that follow.
    pub(crate) fn land_due_cut(
        &mut self,
        i: usize,
        couplings: &mut [Coupling],
    ) -> Option<CutEvent> {
        let c = self.cutting.as_mut()?;
        let due = c.pending.get(i)?.as_ref()?.due;
        if c.steps[i] < due {
            return None;
        }
        let pending = c.pending[i].take()?;
        let (result, waited) = {
            let (mut g, waited) = pending.wait();
            (g.take(), waited)
        };
        let result = result?;
        let retry = c.steps[i] + RETRY_STEPS;
        // Where each tool's anchor on body i is, on the surface about to go.
        let mut points = [None; crate::world::MAX_TOOLS];
        for (p, c) in points.iter_mut().zip(couplings.iter()) {
            if let Coupling::GodObject(Some((b, a))) = *c {
                if b == i {
                    *p = self.anchor_point(i, &a).map(|x| (x, a));
                }
            }
        }
        let event = match result.and_then(|p| self.apply_cut(p)) {
            Ok(report) => {
                for (c, p) in couplings.iter_mut().zip(points) {
                    if let Some((x, a)) = p {
                        *c = Coupling::GodObject(self.anchor_near(i, x, a).map(|a| (i, a)));
                    }
                }
                CutEvent::Landed { report, waited }
            }
            Err(e) => {
                if let Some(c) = self.cutting.as_mut() {
                    c.retry_at[i] = retry;
                }
                CutEvent::Refused(e)
            }
        };
        Some(event)
    }

    /// The point of body `i`'s surface `a` anchors to, at its current positions.
    fn anchor_point(&self, i: usize, a: &ToolAnchor) -> Option<[f64; 3]> {
        let b = self.bodies.get(i)?;
        a.point(&b.mesh.surface, b.model.positions())
    }

    /// `a` moved to the point of body `i`'s surface closest to `x` (its offset and grab kept).
    fn anchor_near(&self, i: usize, x: [f64; 3], a: ToolAnchor) -> Option<ToolAnchor> {
        let b = self.bodies.get(i)?;
        let hit = closest_on_surface(b.model.positions(), &b.mesh.surface, x)?;
        Some(ToolAnchor {
            triangle: hit.triangle as u32,
            bary: hit.barycentric,
            ..a
        })
    }

    /// After a round's heat: asks for the cuts the tools holding the cut button make (module
    /// docs), pushing an event for each.
    pub(crate) fn request_cuts(
        &mut self,
        tools: &[RoundTool<'_>],
        couplings: &[Coupling],
        events: &mut Vec<CutEvent>,
    ) {
        let Some(c) = self.cutting.as_ref() else {
            return;
        };
        let (vaporization, delay) = (c.params.vaporization, u64::from(c.params.delay_steps));
        for (k, (t, coupling)) in tools.iter().zip(couplings).enumerate() {
            let Coupling::GodObject(Some((b, a))) = *coupling else {
                continue;
            };
            if !t.cut || t.heat_power <= 0.0 || a.grab || !self.cuttable(b) {
                continue;
            }
            let c = self.cutting.as_ref().expect("cutting is on");
            match (c.pending.get(b), c.steps.get(b), c.retry_at.get(b)) {
                (Some(None), Some(steps), Some(retry)) if steps >= retry => {}
                _ => continue,
            }
            let Some(temps) = self.heat().and_then(|h| h.bodies().get(b)) else {
                continue;
            };
            let Some(at) = self.anchor_point(b, &a) else {
                continue;
            };
            let body = &self.bodies[b];
            let x = body.model.positions();
            let reach = 2.0 * t.laws.get(b).map_or(0.0, |l| l.radius);
            // The nodes under the tip: the anchor triangle's, and any within reach of it.
            let tri = body.mesh.surface.get(a.triangle as usize).copied();
            let near = |n: u32| {
                tri.is_some_and(|t| t.contains(&n))
                    || (0..3)
                        .map(|j| (x[n as usize][j] - at[j]).powi(2))
                        .sum::<f64>()
                        <= reach * reach
            };
            let Some(remove) = vaporised(&body.mesh, temps.temperatures(), vaporization, near)
            else {
                continue;
            };
            let tets = remove.iter().filter(|&&r| r).count();
            let Ok(source) = self.cut_source(b) else {
                continue;
            };
            let slot: Slot = Arc::new((Mutex::new(None), Condvar::new()));
            let fill = Arc::clone(&slot);
            let setup = self.cutting.as_ref().and_then(|c| c.setup.clone());
            let spawned = std::thread::Builder::new()
                .name("lop-sim-cut".into())
                .spawn(move || {
                    if let Some(setup) = setup {
                        setup();
                    }
                    let result = source.prepare(&remove);
                    let (lock, ready) = &*fill;
                    *lock.lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
                    ready.notify_all();
                });
            if spawned.is_err() {
                continue;
            }
            let c = self.cutting.as_mut().expect("cutting is on");
            let due = c.steps[b] + delay;
            c.pending[b] = Some(Pending { slot, due });
            events.push(CutEvent::Asked {
                body: b,
                tool: k,
                tets,
                due,
            });
        }
    }
}
