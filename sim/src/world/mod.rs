//! The simulated scene: bodies, each with its mesh and its current model, stepped on its own
//! time step; organ-to-organ collision; the heat model.
//!
//! One round of the world ([`World::round`], in `round.rs`) is the only way the deformation
//! process, `lopd simulate` and the benchmarks advance a scene: tool input → organ collision
//! detection → the bodies that are due, each on its own `dt`, with the catch-up policy → heat →
//! a report of timed stages. `World` owns no clock: the caller says how far to advance and
//! passes the clock that times the stages, so the deformation process keeps simulated time on
//! the wall clock while benchmarks and tests step as fast as they like, deterministically.
//! [`World::step_body`] steps one body alone, for tests of a single model.

pub mod pace;
mod rehearse;
mod round;

pub use rehearse::Rehearsal;
pub use round::{BodyRound, Round, RoundReport, RoundTool, MAX_HEAT_CATCH_UP};

use crate::collide::{CollisionBody, CollisionParams, CollisionStats, Collisions};
use crate::contact::{closest_on_surface, scale, ForceLaw, ToolSphere};
pub use crate::grasp::Grip;
use crate::grasp::{jaw_hold, MAX_HOLDS};
use crate::haptic::{FreeMotion, LocalModel};
use crate::heat::HeatWorld;
use crate::lop::PrecisionController;
use crate::mesh::TetMesh;
use crate::model::{BlowUp, ContactReport, ContactSpring, Model, ToolAnchor, ToolContact};
use crate::msd::{MassSpring, MsdParameters};
use crate::parallel::WorkerPool;
use crate::patch::{
    gather, GatherScratch, GatherSphere, PatchHold, PatchPoint, PatchSolve, PatchTool, ToolPatch,
    MAX_PATCH,
};
use std::sync::Arc;

/// How far beyond the tool radius a body's bounding box is still checked for contact, m. Covers
/// the tissue's motion during one step.
const CONTACT_MARGIN: f64 = 0.01;
/// A body running as a cage switches to its precise model when the tool comes this close to
/// touching it, m: one step early rather than one step late (a tool at 0.2 m/s covers 2 mm in a
/// 10 ms step).
pub const SWITCH_MARGIN: f64 = 0.002;

/// Most tools a world is stepped with at once (a scene's tools: two hands, a grasper and a
/// hook…). Fixed so a body's per-tool state needs no allocation.
pub const MAX_TOOLS: usize = 4;
// Every tool of a step may grab the same body.
const _: () = assert!(MAX_HOLDS >= MAX_TOOLS);

/// One deformable body.
#[derive(Debug, Clone)]
pub struct Body {
    /// Name from the scene.
    pub name: String,
    /// Rest mesh, placed in scene coordinates.
    pub mesh: TetMesh,
    /// The model that moves it now.
    pub model: Model,
    /// The levels-of-precision controller (`None`: pinned to `model`).
    pub lop: Option<PrecisionController>,
    /// External nodal loads for the next step, N. Filled by the caller between steps, cleared
    /// by [`World::clear_loads`].
    pub loads: Vec<[f64; 3]>,
    /// Simulated time of this body, s.
    pub time: f64,
    /// Blow-ups detected and reset since creation.
    pub resets: u32,
    /// Cause of the most recent blow-up.
    pub last_blow_up: Option<BlowUp>,
    /// What each tool (in the order the step was given them) did to the body in its last
    /// step; the default report for a tool that did not touch it.
    pub contacts: [ContactReport; MAX_TOOLS],
    /// Per tool, the haptic loop's local model of the last step's contact patch (see
    /// [`crate::haptic::LocalModel`]); `None` without one.
    pub locals: [Option<LocalModel>; MAX_TOOLS],
    /// Per tool, pairs consecutive patch steps for the local model's free motion.
    free_motion: [FreeMotion; MAX_TOOLS],
    /// The body's topology: 0 as loaded, one more for each cut that landed
    /// ([`World::apply_cut`]). Triangle and tetrahedron indices are meant within one epoch.
    pub epoch: u64,
    /// For each node, the surface triangles that use it (built once).
    node_triangles: Vec<Vec<u32>>,
    /// Scratch: filled by `step_body` with the triangles near the tool, read by the model.
    candidates: Vec<u32>,
    /// Scratch: the god-objects' presses as one contact patch, gathered by
    /// `step_body_tools`.
    patch_points: Vec<PatchPoint>,
    patch_scratch: GatherScratch,
}

impl Body {
    /// Drops the local models and the free motions' history (the model was replaced).
    pub fn forget_local(&mut self) {
        self.locals = [None; MAX_TOOLS];
        self.free_motion.iter_mut().for_each(FreeMotion::reset);
    }

    /// The force every tool together applied to the tissue in the last step, N.
    pub fn force_on_tissue(&self) -> [f64; 3] {
        self.contacts.iter().fold([0.0; 3], |acc, c| {
            let f = c.force_on_tissue;
            [acc[0] + f[0], acc[1] + f[1], acc[2] + f[2]]
        })
    }

    /// Whether a tool pressed or held the body in its last step.
    pub fn touched(&self) -> bool {
        self.contacts.iter().any(|c| c.depth > 0.0)
    }

    /// Forgets what the tools did in the last step (the body was reset).
    pub fn forget_contacts(&mut self) {
        self.contacts = [ContactReport::default(); MAX_TOOLS];
        self.forget_local();
    }
}

/// One tool as a body's step sees it: its sphere (the law against this body, centred on the
/// tool's device) and how it couples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyTool {
    /// The tool sphere against this body.
    pub sphere: ToolSphere,
    /// Which body the tool acts on, and where.
    pub coupling: Coupling,
}

/// How the tool acts on the bodies.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Coupling {
    /// The tool sphere presses on the closest surface of any body it reaches: no god-object
    /// (tests and tools that move the tool tip directly).
    #[default]
    Nearest,
    /// A god-object decides (the haptic loop's, or [`crate::haptic::GodObject`] offline): only
    /// the named body is touched, at the anchor; `None`: no body is.
    GodObject(Option<(usize, ToolAnchor)>),
}

/// All bodies of a scene.
#[derive(Debug, Clone)]
pub struct World {
    /// The bodies, in scene order.
    pub bodies: Vec<Body>,
    /// Gravity, m/s².
    pub gravity: [f64; 3],
    /// Organ-to-organ collision, once [enabled](World::enable_collisions).
    collisions: Option<Box<WorldCollisions>>,
    /// The heat model, once [attached](World::set_heat).
    heat: Option<Box<WorldHeat>>,
    /// What the last [`World::round`] did (one entry per body, reused).
    report: RoundReport,
    /// The worker pool of the FEM bodies' steps ([`World::set_threads`]).
    pool: Option<Arc<WorkerPool>>,
    /// Per tool (in the order the steps are given them): how it holds tissue when it grabs
    /// ([`World::set_grip`]).
    grips: [Grip; MAX_TOOLS],
    /// Electrosurgical cutting, once [turned on](World::set_cutting).
    pub(crate) cutting: Option<Box<crate::cut::Cutting>>,
}

/// The heat model of a world and its clock.
#[derive(Debug, Clone)]
struct WorldHeat {
    model: HeatWorld,
    /// Simulated time of the heat model, s.
    time: f64,
    /// Set once a heat step failed: the heat model stops, the bodies go on.
    failed: bool,
}

/// Organ-to-organ collision in a world: detection structures, the response's law and the
/// contact springs of the last detection, per body.
#[derive(Debug, Clone)]
struct WorldCollisions {
    detector: Collisions,
    params: CollisionParams,
    springs: Vec<Vec<ContactSpring>>,
    /// Simulated time between two detections in [`World::round`], s (0: every round).
    interval: f64,
    /// Simulated time of the last detection in a round, s.
    last: Option<f64>,
}

impl World {
    /// An empty world.
    pub fn new(gravity: [f64; 3]) -> World {
        World {
            bodies: Vec::new(),
            gravity,
            collisions: None,
            heat: None,
            report: RoundReport::default(),
            pool: None,
            grips: [Grip::Point; MAX_TOOLS],
            cutting: None,
        }
    }

    /// Sets how tool `tool` (its index in [`Round::tools`], or in the tools given to
    /// [`World::step_body_tools`]) holds tissue when it grabs: [`Grip::Point`] (the default)
    /// holds the god-object's anchored point, [`Grip::Jaws`] a grasper's footprint of the
    /// surface around it ([`crate::grasp`]). A property of the tool, kept until changed; a
    /// tool index of [`MAX_TOOLS`] or more is ignored.
    pub fn set_grip(&mut self, tool: usize, grip: Grip) {
        if let Some(g) = self.grips.get_mut(tool) {
            *g = grip;
        }
    }

    /// How tool `tool` holds tissue when it grabs ([`World::set_grip`]).
    pub fn grip(&self, tool: usize) -> Grip {
        self.grips.get(tool).copied().unwrap_or_default()
    }

    /// Runs every FEM body's step (active or parked behind the levels-of-precision
    /// controller, and those added later) on one shared pool of `threads` threads, the caller
    /// included (1: on the caller alone, no pool). Bodies step one after the other, so one
    /// pool serves them all; the results are bit for bit those of one thread
    /// (`crate::parallel`). Spawns the pool's threads now.
    pub fn set_threads(&mut self, threads: usize) {
        let pool = (threads > 1).then(|| Arc::new(WorkerPool::new(threads)));
        for b in &mut self.bodies {
            give_pool(&mut b.model, &pool);
            if let Some(lop) = &mut b.lop {
                give_pool(lop.parked_mut(), &pool);
            }
        }
        self.pool = pool;
    }

    /// Body `i`'s FEM model, running now or parked behind its levels-of-precision controller,
    /// for changes between rounds (its refactor policy, its period); `None` if it has none.
    pub fn fem_mut(&mut self, i: usize) -> Option<&mut crate::fem::Fem> {
        let b = &mut self.bodies[i];
        match (&mut b.model, b.lop.as_mut().map(|l| l.parked_mut())) {
            (Model::Fem(f), _) | (_, Some(Model::Fem(f))) => Some(f),
            _ => None,
        }
    }

    /// Threads the FEM bodies' steps run on ([`World::set_threads`]; 1 without a pool).
    pub fn threads(&self) -> usize {
        self.pool.as_ref().map_or(1, |p| p.threads())
    }

    /// Attaches the heat model (one heat body per world body, in the same order): each
    /// [`World::round`] then heats the point the tool's god-object holds while the heat button
    /// is pressed and takes the heat steps that are due. Its clock starts at 0.
    pub fn set_heat(&mut self, model: HeatWorld) {
        self.heat = Some(Box::new(WorldHeat {
            model,
            time: 0.0,
            failed: false,
        }));
    }

    /// Detaches the heat model.
    pub fn disable_heat(&mut self) {
        self.heat = None;
    }

    /// The heat model, if attached.
    pub fn heat(&self) -> Option<&HeatWorld> {
        self.heat.as_ref().map(|h| &h.model)
    }

    /// The heat model, if attached, for changes between rounds.
    pub fn heat_mut(&mut self) -> Option<&mut HeatWorld> {
        self.heat.as_mut().map(|h| &mut h.model)
    }

    /// What the last [`World::round`] did.
    pub fn last_round(&self) -> &RoundReport {
        &self.report
    }

    /// Turns organ-to-organ collision on for the bodies added so far (add bodies first): each
    /// [`World::detect_collisions`] finds the surface vertices inside other bodies and turns
    /// them into contact springs of stiffness `params.stiffness` (see
    /// [`Collisions::add_springs`]), which [`World::step_body`] hands to the body's model, to
    /// be resolved implicitly in its step whatever model it runs. Contact starts `skin` metres
    /// before the surfaces meet; vertices deeper than `depth_limit` are ignored (see
    /// [`Collisions::set_depth_limit`]).
    ///
    /// # Panics
    /// If the stiffness or skin is negative or not finite, or `depth_limit` is not positive.
    pub fn enable_collisions(&mut self, params: CollisionParams, skin: f64, depth_limit: f64) {
        assert!(
            params.stiffness >= 0.0 && params.stiffness.is_finite(),
            "collision stiffness must be finite and ≥ 0, got {}",
            params.stiffness
        );
        let surfaces: Vec<&[[u32; 3]]> = self.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
        let mut detector = Collisions::new(&surfaces);
        detector.set_skin(skin);
        detector.set_depth_limit(depth_limit);
        let springs = (0..self.bodies.len())
            .map(|i| Vec::with_capacity(detector.spring_capacity(i)))
            .collect();
        self.collisions = Some(Box::new(WorldCollisions {
            detector,
            params,
            springs,
            interval: 0.0,
            last: None,
        }));
    }

    /// Detects organ-to-organ collisions in [`World::round`] at most once per `interval` s of
    /// simulated time (the contact springs of the last detection hold meanwhile); 0, the
    /// default: every round in which a body steps. No effect while collision is off.
    ///
    /// # Panics
    /// If `interval` is negative or not finite.
    pub fn set_collision_interval(&mut self, interval: f64) {
        assert!(
            interval >= 0.0 && interval.is_finite(),
            "collision interval must be finite and ≥ 0, got {interval}"
        );
        if let Some(c) = self.collisions.as_mut() {
            c.interval = interval;
        }
    }

    /// Whether a round to simulated time `until` is due for a detection.
    pub(crate) fn detection_due(&self, until: f64) -> bool {
        self.collisions.as_ref().is_some_and(|c| match c.last {
            Some(t) => until - t >= c.interval - 1e-9 || until < t,
            None => true,
        })
    }

    /// Notes a detection in a round at simulated time `until`.
    pub(crate) fn detected_at(&mut self, until: f64) {
        if let Some(c) = self.collisions.as_mut() {
            c.last = Some(until);
        }
    }

    /// Turns organ-to-organ collision off.
    pub fn disable_collisions(&mut self) {
        self.collisions = None;
    }

    /// Whether organ-to-organ collision is on.
    pub fn collisions_enabled(&self) -> bool {
        self.collisions.is_some()
    }

    /// Detects organ-to-organ collisions at the current positions and sets each body's contact
    /// springs for its next steps (until the next detection). Call it once per scheduling
    /// round, before stepping the bodies due. `None` if collision is off, or (nothing detected)
    /// in a world of more than 32 bodies or with bodies added since collision was enabled.
    /// Allocation-free.
    pub fn detect_collisions(&mut self) -> Option<CollisionStats> {
        let c = self.collisions.as_mut()?;
        // Positions of every body, borrowed for the detection (at most a handful of bodies,
        // so a fixed array avoids allocating).
        const MAX: usize = 32;
        let n = self.bodies.len();
        // Bodies added after `enable_collisions` are not known to the detector: detect nothing
        // rather than fail (enable again to include them).
        if n > MAX || n != c.springs.len() {
            return None;
        }
        let empty: &[[f64; 3]] = &[];
        let mut bodies = [CollisionBody {
            positions: empty,
            surface: &[],
        }; MAX];
        for (slot, b) in bodies.iter_mut().zip(&self.bodies) {
            *slot = CollisionBody {
                positions: b.model.positions(),
                surface: &b.mesh.surface,
            };
        }
        c.detector.detect(&bodies[..n]);
        c.springs.iter_mut().for_each(Vec::clear);
        c.detector
            .add_springs(&c.params, &bodies[..n], &mut c.springs);
        Some(c.detector.stats())
    }

    /// Every body as collision detection sees it (current positions and surface), in scene
    /// order: for measuring penetrations with a [`Collisions`] of one's own (allocates).
    pub fn collision_bodies(&self) -> Vec<CollisionBody<'_>> {
        self.bodies
            .iter()
            .map(|b| CollisionBody {
                positions: b.model.positions(),
                surface: &b.mesh.surface,
            })
            .collect()
    }

    /// The contact springs acting on body `i` (from the last detection).
    pub fn contact_springs(&self, i: usize) -> &[ContactSpring] {
        self.collisions
            .as_ref()
            .and_then(|c| c.springs.get(i))
            .map_or(&[], |s| &s[..])
    }

    /// Adds a mass-spring body; returns its index.
    pub fn add_body(&mut self, name: &str, mesh: TetMesh, params: MsdParameters) -> usize {
        let model = Model::MassSpring(MassSpring::new(&mesh, params));
        self.add_model(name, mesh, model)
    }

    /// Adds a body with a model built by the caller (its rest shape must be `mesh`); returns its
    /// index.
    pub fn add_model(&mut self, name: &str, mesh: TetMesh, model: Model) -> usize {
        let mut model = model;
        if self.pool.is_some() {
            give_pool(&mut model, &self.pool);
        }
        self.report.bodies.push(BodyRound::default());
        let n = mesh.nodes.len();
        let node_triangles = node_triangles(&mesh.surface, n);
        let patch_scratch = GatherScratch::new(mesh.surface.len(), n);
        self.bodies.push(Body {
            patch_scratch,
            name: name.to_string(),
            mesh,
            model,
            lop: None,
            loads: vec![[0.0; 3]; n],
            time: 0.0,
            resets: 0,
            last_blow_up: None,
            contacts: [ContactReport::default(); MAX_TOOLS],
            locals: [None; MAX_TOOLS],
            free_motion: Default::default(),
            epoch: 0,
            node_triangles,
            candidates: Vec::with_capacity(64),
            patch_points: Vec::with_capacity(MAX_PATCH),
        });
        self.bodies.len() - 1
    }

    /// Gives body `i` the mesh and model a cut left (`crate::cut`, which checked the body and
    /// carried the state): its levels-of-precision controller goes, the tools' contacts and
    /// local models on it are forgotten, its surface's indices and organ collision are built
    /// again, and its epoch counts one more.
    pub(crate) fn replace_body_topology(&mut self, i: usize, mesh: TetMesh, model: Model) {
        let mut model = model;
        give_pool(&mut model, &self.pool);
        let n = mesh.nodes.len();
        let b = &mut self.bodies[i];
        b.node_triangles = node_triangles(&mesh.surface, n);
        b.patch_scratch = GatherScratch::new(mesh.surface.len(), n);
        b.mesh = mesh;
        b.model = model;
        b.lop = None;
        b.forget_contacts();
        b.candidates.clear();
        b.patch_points.clear();
        b.epoch += 1;
        if let Some(c) = self.collisions.as_mut() {
            let surfaces: Vec<&[[u32; 3]]> =
                self.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
            let mut detector = Collisions::new(&surfaces);
            detector.set_skin(c.detector.skin());
            detector.set_depth_limit(c.detector.depth_limit());
            c.springs = (0..self.bodies.len())
                .map(|j| Vec::with_capacity(detector.spring_capacity(j)))
                .collect();
            c.detector = detector;
            // Detected again in the next round that steps a body.
            c.last = None;
        }
    }

    /// Replaces body `i`'s heat model (`crate::cut`); false if the heat model refused it.
    pub(crate) fn replace_heat_body(&mut self, i: usize, body: crate::heat::HeatBody) -> bool {
        self.heat
            .as_mut()
            .is_some_and(|h| h.model.replace_body(i, body).is_ok())
    }

    /// Adds a body under a levels-of-precision controller: `model` is the one to run first (as
    /// returned by [`PrecisionController::new`]); returns its index.
    pub fn add_lop_body(
        &mut self,
        name: &str,
        mesh: TetMesh,
        model: Model,
        lop: PrecisionController,
    ) -> usize {
        let i = self.add_model(name, mesh, model);
        let mut lop = lop;
        if self.pool.is_some() {
            give_pool(lop.parked_mut(), &self.pool);
        }
        self.bodies[i].lop = Some(lop);
        i
    }

    /// Zeroes every body's external loads.
    pub fn clear_loads(&mut self) {
        for b in &mut self.bodies {
            b.loads.iter_mut().for_each(|f| *f = [0.0; 3]);
        }
    }

    /// Applies `force` (N) at a point of surface triangle `triangle` (index into the body's
    /// `mesh.surface`) given by barycentric coordinates, spread to the triangle's nodes by those
    /// weights (which keeps the total force and its point of application). Out-of-range indices
    /// are ignored: loads come from another process and may refer to a stale topology.
    pub fn add_surface_load(
        &mut self,
        body: usize,
        triangle: usize,
        bary: [f64; 3],
        force: [f64; 3],
    ) {
        let Some(b) = self.bodies.get_mut(body) else {
            return;
        };
        let Some(tri) = b.mesh.surface.get(triangle) else {
            return;
        };
        if !force.iter().chain(bary.iter()).all(|c| c.is_finite()) {
            return;
        }
        for (k, &node) in tri.iter().enumerate() {
            if let Some(f) = b.loads.get_mut(node as usize) {
                let add = scale(force, bary[k]);
                f[0] += add[0];
                f[1] += add[1];
                f[2] += add[2];
            }
        }
    }

    /// Whether body `i` has a step due to reach simulated time `until`.
    pub fn body_due(&self, i: usize, until: f64) -> bool {
        let b = &self.bodies[i];
        b.time + b.model.dt() <= until + 1e-12
    }

    /// Where tool `tool`'s god-object press (`coupling`) last balanced as a contact patch:
    /// the body and the proxy of its last step (see [`crate::patch`]); `None` for a grab, no
    /// contact, or a step that pressed at one point. The god-object rests its proxy there.
    pub fn contact_proxy(&self, tool: usize, coupling: Coupling) -> Option<(usize, [f64; 3])> {
        match coupling {
            Coupling::GodObject(Some((b, a))) if !a.grab => {
                Some((b, self.bodies.get(b)?.contacts.get(tool)?.proxy?))
            }
            _ => None,
        }
    }

    /// The local model of tool `tool`'s god-object press (`coupling`) after its body's last
    /// step: the body and what the haptic loop renders between frames (see
    /// [`crate::haptic::LocalModel`]); `None` when [`World::contact_proxy`] is.
    pub fn contact_local(&self, tool: usize, coupling: Coupling) -> Option<(usize, LocalModel)> {
        let (b, _) = self.contact_proxy(tool, coupling)?;
        Some((b, (*self.bodies.get(b)?.locals.get(tool)?)?))
    }

    /// Advances body `i` by one of its steps with its current loads and, if given, the tool
    /// pressing on the surface nearest to it ([`Coupling::Nearest`]), outside any round: for
    /// tests and benchmarks of one model. See [`World::step_body_coupled`].
    pub fn step_body(&mut self, i: usize, tool: Option<&ToolSphere>) -> Result<(), BlowUp> {
        self.step_body_coupled(i, tool, Coupling::Nearest)
    }

    /// Advances body `i` by one of its steps with its current loads and, if given, the tool
    /// acting on it as `coupling` says: [`World::step_body_tools`] with one tool.
    pub fn step_body_coupled(
        &mut self,
        i: usize,
        tool: Option<&ToolSphere>,
        coupling: Coupling,
    ) -> Result<(), BlowUp> {
        let tool = tool.map(|&sphere| BodyTool { sphere, coupling });
        self.step_body_tools(i, std::slice::from_ref(&tool))
    }

    /// Advances body `i` by one of its steps with its current loads and the tools acting on it
    /// (`None`: that tool has no law against this body). A blow-up resets the body (counted
    /// in `resets`) and is returned; the world stays valid either way. Allocation-free after
    /// the first steps. At most [`MAX_TOOLS`] tools; the rest are ignored.
    ///
    /// Every god-object press (linear law) on this body joins one contact patch, each tool
    /// with its own points, sphere and spring, solved together ([`crate::patch`]): tissue
    /// pinched between two tools pushes back on both, and each tool's share is its report in
    /// [`Body::contacts`]. When the tools press more points than a patch holds, each keeps
    /// an equal share of [`MAX_PATCH`].
    ///
    /// Grabs (linear law) join the same problem as bilateral springs ([`crate::grasp`]) when
    /// several tools grab the body, a tool presses beside a grab, or a tool grabs with jaws
    /// ([`World::set_grip`]): each grabbing tool holds its own point (or footprint) with its
    /// own spring, its report the force its spring applied, and the presses beside act on the
    /// tissue as the grabs hold it. A lone point grab stays the one-point contact it always
    /// was. A body grabbed under its cage, or pressed with the quadratic law (a point
    /// contact), takes that tool alone this step, the first such tool: the others' presses on
    /// it are not applied to the tissue until it lets go. [`Coupling::Nearest`] acts with the
    /// first tool whose sphere reaches the body.
    pub fn step_body_tools(&mut self, i: usize, tools: &[Option<BodyTool>]) -> Result<(), BlowUp> {
        let tools = &tools[..tools.len().min(MAX_TOOLS)];
        let gravity = self.gravity;
        let grips = self.grips;
        let springs: &[ContactSpring] = match &self.collisions {
            Some(c) => c.springs.get(i).map_or(&[], |v| &v[..]),
            None => &[],
        };
        let b = &mut self.bodies[i];
        b.candidates.clear();
        let mut touching = false;
        // Per tool: its god-object's anchor on this body.
        let mut anchors: [Option<ToolAnchor>; MAX_TOOLS] = [None; MAX_TOOLS];
        // The tool whose sphere presses the nearest surface (`Coupling::Nearest`).
        let mut nearest = None;
        for (t, tool) in tools.iter().enumerate() {
            let Some(BodyTool { sphere, coupling }) = tool else {
                continue;
            };
            let (god, anchor) = match *coupling {
                Coupling::Nearest => (false, None),
                Coupling::GodObject(Some((body, a))) if body == i => (true, Some(a)),
                Coupling::GodObject(_) => (true, None),
            };
            if near_bounds(
                b.model.positions(),
                sphere.center,
                sphere.radius + CONTACT_MARGIN,
            ) {
                if let Some(hit) =
                    closest_on_surface(b.model.positions(), &b.mesh.surface, sphere.center)
                {
                    touching |= hit.signed_distance() < sphere.radius + SWITCH_MARGIN;
                    if !god
                        && nearest.is_none()
                        && (hit.distance < sphere.radius + CONTACT_MARGIN || hit.inside)
                    {
                        nearest = Some(t);
                        for &node in &b.mesh.surface[hit.triangle] {
                            for &tri in &b.node_triangles[node as usize] {
                                if !b.candidates.contains(&tri) {
                                    b.candidates.push(tri);
                                }
                            }
                        }
                    }
                }
            }
            touching |= anchor.is_some();
            anchors[t] = anchor;
        }
        if let Some(lop) = &mut b.lop {
            lop.before_step(&mut b.model, touching, b.time);
        }
        let dt = b.model.dt();
        b.time += dt;
        let sphere = |t: usize| tools[t].map(|bt| bt.sphere);
        // A press by a god-object (linear law) acts over the tool's footprint: the patch of
        // the sphere resting at the anchor, held by the tool spring to the device. A grab
        // (linear law) holds its point or its jaws' footprint in the same problem when it
        // shares the body or holds with jaws (`crate::grasp`); a lone point grab, a grab of a
        // cage and a quadratic press are point contacts of one tool.
        let linear = |t: usize| sphere(t).is_some_and(|s| s.law == ForceLaw::Linear);
        let presses = |t: usize| anchors[t].is_some_and(|a| !a.grab) && linear(t);
        let grabs = |t: usize| anchors[t].is_some_and(|a| a.grab) && linear(t);
        let pressing = (0..tools.len()).filter(|&t| presses(t)).count();
        let grabbing = (0..tools.len()).filter(|&t| grabs(t)).count();
        let jaws = (0..tools.len()).any(|t| grabs(t) && grips[t].jaw_radius().is_some());
        let holding =
            b.model.resolves_holds() && grabbing > 0 && (grabbing > 1 || pressing > 0 || jaws);
        let patched = |t: usize| presses(t) || (holding && grabs(t));
        let point = (0..tools.len()).find(|&t| anchors[t].is_some() && !patched(t));
        // Per patch tool: the tool it is (an index into `tools`).
        let mut patch_of = [0usize; MAX_TOOLS];
        let mut patch_tools = [PatchTool {
            device: [0.0; 3],
            stiffness: 0.0,
        }; MAX_TOOLS];
        let mut in_patch = 0;
        let mut holds = [PatchHold::EMPTY; MAX_HOLDS];
        let mut n_holds = 0;
        b.patch_points.clear();
        if point.is_none() {
            for t in (0..tools.len()).filter(|&t| patched(t)) {
                let (Some(a), Some(s)) = (anchors[t], sphere(t)) else {
                    continue;
                };
                if a.grab {
                    let x = b.model.positions();
                    let hold = match grips[t].jaw_radius() {
                        Some(r) => jaw_hold(
                            &b.mesh.surface,
                            &b.node_triangles,
                            x,
                            &a,
                            r,
                            in_patch as u32,
                            &mut b.patch_scratch,
                        ),
                        None => PatchHold::at_anchor(&b.mesh.surface, &a, in_patch as u32),
                    };
                    let Some(hold) = hold.filter(|_| a.point(&b.mesh.surface, x).is_some()) else {
                        continue;
                    };
                    holds[n_holds] = hold;
                    n_holds += 1;
                } else if let Some(proxy) =
                    a.patch_proxy(&b.mesh.surface, b.model.positions(), s.radius)
                {
                    let max = b.patch_points.len() + MAX_PATCH / pressing;
                    gather(
                        &b.mesh.surface,
                        &b.node_triangles,
                        b.model.positions(),
                        GatherSphere {
                            start: a.triangle,
                            proxy,
                            radius: s.radius,
                            tool: in_patch as u32,
                        },
                        max,
                        &mut b.patch_points,
                        &mut b.patch_scratch,
                    );
                } else {
                    continue;
                }
                patch_tools[in_patch] = PatchTool {
                    device: s.center,
                    stiffness: s.stiffness,
                };
                patch_of[in_patch] = t;
                in_patch += 1;
            }
        }
        let patch = (in_patch > 0).then_some(ToolPatch {
            tools: &patch_tools[..in_patch],
            points: &b.patch_points,
            holds: &holds[..n_holds],
        });
        // The tool the contact is given as: the point contact's, else the patch's first,
        // else the first anchored tool's, else the nearest.
        let acting = point
            .or((in_patch > 0).then_some(patch_of[0]))
            .or((0..tools.len()).find(|&t| anchors[t].is_some()))
            .or(nearest);
        let contact = acting.and_then(|t| {
            let s = sphere(t)?;
            Some(ToolContact {
                tool: s,
                surface: &b.mesh.surface,
                candidates: &b.candidates,
                anchor: anchors[t],
                patch: if point.is_some() { None } else { patch },
            })
        });
        let r = b
            .model
            .step_colliding(gravity, &b.loads, contact.as_ref(), springs);
        match r {
            Ok(report) => {
                b.contacts = [ContactReport::default(); MAX_TOOLS];
                // A press's report has its proxy; a patch with grabs reports them either way.
                let solved = patch
                    .filter(|_| point.is_none())
                    .filter(|p| report.proxy.is_some() || !p.holds.is_empty());
                match solved {
                    Some(patch) => {
                        b.contacts[patch_of[0]] = report;
                        // The other tools' shares of the same solve.
                        if let (Some(limited), Some(solve)) =
                            (PatchSolve::limit(&patch), b.model.patch_solve())
                        {
                            for (k, &t) in patch_of.iter().enumerate().take(in_patch).skip(1) {
                                b.contacts[t] = solve.report(&limited, k);
                            }
                        }
                    }
                    None => {
                        if let Some(t) = acting {
                            b.contacts[t] = report;
                        }
                    }
                }
                for ((local, motion), c) in
                    b.locals.iter_mut().zip(&mut b.free_motion).zip(&b.contacts)
                {
                    *local = motion.step(dt, c.response.map(|r| (r, c.force_on_tissue)));
                }
                if let Some(lop) = &mut b.lop {
                    let touched = touching || b.contacts.iter().any(|c| c.depth > 0.0);
                    lop.after_step(&mut b.model, touched, dt, b.time);
                }
                Ok(())
            }
            Err(cause) => {
                b.forget_contacts();
                b.resets += 1;
                b.last_blow_up = Some(cause);
                Err(cause)
            }
        }
    }
}

/// Hands `pool` to `model` if it is an FEM body.
/// For each of `n` nodes, the triangles of `surface` that use it.
fn node_triangles(surface: &[[u32; 3]], n: usize) -> Vec<Vec<u32>> {
    let mut node_triangles = vec![Vec::new(); n];
    for (t, tri) in surface.iter().enumerate() {
        for &k in tri {
            node_triangles[k as usize].push(t as u32);
        }
    }
    node_triangles
}

fn give_pool(model: &mut Model, pool: &Option<Arc<WorkerPool>>) {
    if let Model::Fem(f) = model {
        f.set_worker_pool(pool.clone());
    }
}

/// Whether `p` is within `margin` of the bounding box of `positions`.
fn near_bounds(positions: &[[f64; 3]], p: [f64; 3], margin: f64) -> bool {
    let (lo, hi) = crate::mesh::bounds(positions);
    (0..3).all(|k| p[k] >= lo[k] - margin && p[k] <= hi[k] + margin)
}
