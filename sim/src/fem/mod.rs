//! Linear tetrahedral finite elements (thesis §4.2, eqs. 4.4–4.22), in two flavours:
//! [`FemMode::Linear`] as in the thesis, and [`FemMode::Corotational`] (stiffness warping, the
//! default), because linear elasticity measures strain with `sym(∇u)`, which is not zero under
//! a rotation: a linear body that turns inflates and pushes back against the turn.
//!
//! This file holds the body's types ([`Fem`] and its scratch); the work is split by stage:
//! `params.rs` (parameters, errors), `body.rs` (building, state), `forces.rs` (elastic forces,
//! assembly), `step.rs` (the dynamic step), `cg.rs` (the corotational CG), `precondition.rs`
//! (the lagged factor and its refactor policy), `contact.rs` (the tool inside the step),
//! `statics.rs` (static equilibrium); below them `element.rs`, `rotation.rs`, `batch.rs`
//! (element kernels), `system.rs`, `ordering.rs`, `packed.rs` (sparse matrix and factor).
//! Measured step times, iteration counts and factor sizes are in `docs/benchmarks.md`
//! ("Deformation models — `lop-bench models`"; what each solver phase costs, and why it is built
//! as it is, under "FEM internals").
//!
//! # Discretisation
//!
//! Each tetrahedron has constant shape-function gradients, the isotropic material matrix of
//! eq. 4.9 with the *correct* Lamé constant `λ = Eν/((1+ν)(1−2ν))` (eq. 4.10 prints a sum) and
//! `K_e = V Bᵀ C B` (eq. 4.15); `element.rs` writes it with the gradients instead of an
//! explicit `B`. Masses are lumped: each tetrahedron gives `ρV/4` to each of its nodes (eq.
//! 4.19's `1/3` cannot be right for a tetrahedron: the four shares must add up to `ρV`).
//! Damping is `D = αM`. The state is the nodal displacements `u = x − X` and velocities:
//! strains computed from displacements keep their full relative precision however far the
//! body sits from the origin (positions are kept alongside for callers).
//!
//! # Time integration (eqs. 4.20–4.22)
//!
//! Eq. 4.20 — central differences for `M` and `D`, stiffness at the new time:
//!
//! ```text
//! M/Δt² (u⁺ − 2u + u⁻) + D/(2Δt) (u⁺ − u⁻) + K u⁺ = f
//! K̃ = M/Δt² + D/(2Δt) + K
//! f̃ = (2M/Δt²) u − (M/Δt² − D/(2Δt)) u⁻ + f          (eq. 4.21, corrected)
//! K̃ u⁺ = f̃                                               (eq. 4.22)
//! ```
//!
//! It is solved in increment form, algebraically the same system: with the step `d = u⁺ − u`
//! and the backward-difference velocity `v = (u − u⁻)/Δt`,
//!
//! ```text
//! K̃ d = f − f_int(u) + (M/Δt − D/2) v,     u⁺ = u + d,     v⁺ = d/Δt
//! ```
//!
//! with `f_int(u) = K u` (linear mode). The right-hand side holds the true elastic forces, so
//! an equilibrium of the dynamics is exactly the static equilibrium, whatever the accuracy of
//! the linear solve. Linear mode adds `K̃ u` to both sides, where `K u` cancels:
//! `K̃ u⁺ = f + (M/Δt² + D/(2Δt)) u + (M/Δt − D/2) v`, a right-hand side of diagonal terms
//! only, so its step evaluates no element at all (one pair of triangular solves with the
//! factor made once; `d = u⁺ − u` then feeds the tool's update below). The scheme is
//! unconditionally stable and dissipative in the stiffness (undamped amplification
//! `1/√(1+ω²Δt²)`), so the thesis' Δt = 0.01 s on milligram nodes is fine.
//!
//! **Fixed nodes** (and nodes no tetrahedron uses) have no unknowns: the system is the reduced
//! one on the free DOFs, which eliminates them symmetrically and keeps it SPD. Fixed nodes
//! never move.
//!
//! # Corotational elements
//!
//! Per element, `R` is the rotation closest to `F = Ds Dm⁻¹` (polar decomposition by a
//! warm-started Newton iteration, with an SVD fallback that keeps `det R = +1` for flat and
//! inverted elements: `rotation.rs`). The elastic force is `f_int = Σₑ Rₑ Kₑ (Rₑᵀx − X)` — the
//! gradient of the corotated energy `Σₑ V (μ‖ε‖² + λ/2 tr²ε)`, `ε = sym(RᵀF) − I` — and `K` in
//! `K̃` becomes the warped stiffness `K_w = Σₑ Rₑ Kₑ Rₑᵀ` (Müller et al. 2002; Müller & Gross
//! 2004): one linearised implicit step about the current rotations.
//!
//! `K̃_w` changes every step. Refactorising it every step (symbolic analysis once, numeric into
//! reused buffers) costs milliseconds on an organ and a quarter of a second at 50k tets, so by
//! default the step is solved by **conjugate gradients preconditioned with a lagged factor**
//! instead:
//!
//! - `K̃_w p` is applied matrix-free, element by element from the rotated gradients (no
//!   assembly);
//! - the preconditioner is `Q K̃_lag Qᵀ`: the Cholesky factor of `K̃_w` from some recent step,
//!   turned by `Q`, the block-diagonal per-node rotations (normalised sums of the adjacent
//!   elements' quaternions) accumulated since — so a body that turns as a whole keeps a good
//!   preconditioner — and the tool's rank-one stiffness added by Sherman–Morrison;
//! - the factor is kept in single precision (half the memory traffic of solves and
//!   refactorisations; CG in double precision, in its flexible Polak–Ribière form, makes up for
//!   the rounding); from a million values on (the 10k-tetrahedra box and up) its solves use a
//!   copy in half precision, scaled to a unit diagonal (`packed.rs`: under half the memory
//!   traffic again, iteration counts of the smooth steps unchanged), and it is refreshed by
//!   *ski rental*: once the CG iterations beyond what the fresh factor needed, summed since the
//!   last refactorisation, reach the price of one — estimated from the factor's structure as
//!   `√(flops / nnz(L))` iterations, at least ten (`system.rs`);
//! - CG starts from the increment extrapolated from the last three steps,
//!   `Δt (3v − 3v⁻ + v⁻⁻)`, scaled to minimise the error in the energy norm (one extra
//!   product; never worse than starting from zero in that norm): on a smoothly moving body the
//!   initial residual is a few per cent of the right-hand side, which saves about one iteration
//!   in four;
//! - CG stops at a relative residual of 1e-5 (see `CG_TOLERANCE` for what that costs in
//!   accuracy); if it has not converged in 20 iterations, or from the third iteration on its
//!   mean rate so far predicts that it will not, the factor is refreshed within the step.
//!
//! Factorisation: faer's sparse Cholesky (supernodal; faer picks it by its flop estimate for
//! all these meshes, and its solves beat the simplicial ones even though relaxed supernodes
//! store more), on a numbering ordered by AMD or geometric nested dissection on the node graph,
//! whichever gives the smaller factor (`system.rs`, `ordering.rs`): AMD on the organ meshes,
//! nested dissection from ~10k tets.
//!
//! # Tool contact
//!
//! The tool's penalty acts on the closest candidate surface triangle, spread to its nodes by
//! the barycentric weights `wᵢ` of the contact point, with the law's magnitude `F(depth)`:
//! `f = −F c`, `c = (w₀n, w₁n, w₂n)` on the triangle's nodes. The direction `n` is the
//! triangle's vertex normals interpolated at the contact point (see `contact_normal` for why
//! not the face normal). Applied explicitly, a 300 N/m tool on milligram nodes would ring;
//! instead it is linearised inside the implicit step — the depth grows by `cᵀd` when the nodes
//! move by `d`, so its stiffness `k' c cᵀ` (`k' = dF/d depth`) joins `K̃`. A rank-one update:
//! the linear mode keeps its one factorisation and uses Sherman–Morrison, with `y = K̃⁻¹ r`
//! (no contact) and `z = K̃⁻¹ c`,
//!
//! ```text
//! λ = (F + k' cᵀy) / (1 + k' cᵀz),     d = y − λ z
//! ```
//!
//! (one extra pair of triangular solves, which linear mode saves: its factor never changes, so
//! it keeps the three columns of `K̃⁻¹` of each of the last 12 node blocks the tool touched and
//! builds `z` from them, paying three solves when the tool reaches a new node); the
//! corotational CG includes it in its operator and
//! preconditioner. `λ = F + k' cᵀd` is the force the step applies. If `λ ≤ 0` the tissue leaves
//! the tool during the step and the contact is dropped: the linearised penalty never pulls.
//!
//! # Static equilibrium
//!
//! [`Fem::solve_static`] solves `f_int(u) = f` with the fixed nodes held where they are:
//! iterations `K d = f − f_int(u)`. Linear mode: one factorisation, exact in one step (then
//! refinement to round-off). Corotational: `K` is the warped stiffness at the current
//! rotations, which omits the derivative of `R`; a line search on the corotated energy along
//! `d` (strong-Wolfe curvature test on its slope `−rᵀd`, secant steps back) keeps large
//! rotations from overshooting.
//!
//! # Threads, and factors off the critical path (issue 27)
//!
//! [`Fem::set_worker_pool`] (or [`crate::world::World::set_threads`]) runs the step's element
//! loops on a persistent pool: the corotational forces with the rotation search, every
//! matrix-free product of CG, and the per-node rotations of the preconditioner. Each is split
//! into an element phase (each batch writes its own outputs) and a node phase (each node sums its
//! elements' contributions in element order, from zero — the order of the one-thread scatter),
//! so the step is bit for bit the one-thread step at any thread count (`batch.rs`,
//! `tests/fem_threads.rs`). Not parallel (yet): the preconditioner's triangular solves (the
//! crate's own packed solves, one right-hand side, sequential along the elimination tree), the
//! patch's solves, the DOF-vector updates of CG, the assembly (off the critical path under the
//! background policy).
//!
//! [`RefactorPolicy::Background`] moves every factorisation of the lagged preconditioner out of
//! the step, onto a thread of the body's own, and swaps the new factor in a fixed number of
//! steps after it was asked for (`background.rs`); [`Fem::set_dt`] changes the step period
//! through the same machinery, so the new period and its factor start together.
//!
//! # Allocation
//!
//! Everything `step` touches is allocated by [`Fem::new`] (or by the first step after a change
//! of factor precision): the sparse pattern and factors, faer's scratch memory, and the
//! per-node, per-element and per-DOF scratch vectors documented on the struct.
//! [`Fem::solve_static`] and [`Fem::elastic_forces`] allocate.

// 3×3 and 4-node kernels index several arrays with the same small index; iterator chains
// would obscure the formulas they transcribe.
#![allow(clippy::needless_range_loop)]

mod background;
mod batch;
mod body;
mod cg;
mod contact;
pub(crate) mod element;
mod forces;
mod lanes;
mod ordering;
mod packed;
mod params;
mod patch;
mod precondition;
mod rotation;
mod shapes;
mod statics;
mod step;
mod system;

use std::sync::Arc;

use crate::parallel::WorkerPool;
use batch::Batches;
use element::Element;
use system::System;

pub use params::{FemError, FemMode, FemParameters};
pub use statics::StaticReport;
#[doc(hidden)]
pub use system::NodeOrdering;

#[doc(hidden)]
pub use shapes::box_mesh;

/// How a corotational body solves its per-step system (see the module docs).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CorotationalSolver {
    /// Assemble and refactorise the warped matrix every step, then solve directly.
    Refactor,
    /// Conjugate gradients on the warped matrix (matrix-free), preconditioned by the Cholesky
    /// factor of a recent warped matrix, refactorised when CG needs too many iterations.
    LaggedFactorPcg,
}

/// How the contact patch's correction `K̃⁻¹ C λ` is applied when the patch's nodes have their
/// `K̃⁻¹` columns cached (`patch.rs`): by whichever streams fewer bytes, or one way always, to
/// compare them.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PatchCorrection {
    /// The nodes' columns when they are fewer bytes than a solve pair, else a solve.
    #[default]
    Cheaper,
    /// Always the sum of the nodes' cached columns.
    Columns,
    /// Always one solve with the factor.
    Solve,
}

/// When a corotational body using the lagged factor refreshes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RefactorPolicy {
    /// Ski rental: once the CG iterations the lagged factor has cost beyond a fresh factor's
    /// add up to about the price of a refactorisation. Least total work; the step that
    /// refactorises takes several times the others.
    #[default]
    Amortized,
    /// Only when CG does not converge in its iteration limit (then within the step). For a
    /// body stepping at the haptic rate, on the real-time path of the hand: at such a step the
    /// matrix `M/Δt² + K` is dominated by the mass, so on a well-shaped mesh the lagged factor
    /// keeps CG at a few iterations whatever the rotations since, and a refactorisation
    /// (milliseconds on an organ) would be a spike several times the step. Slivers (flat
    /// tetrahedra, far stiffer than their mass) break that: a generated ellipsoid with 2–3°
    /// dihedral angles needs about 12 iterations per step while pressed. Measured on the `abdomen` liver
    /// pressed at Δt = 1 ms (`lopd simulate` of its poke): CG takes 1–2 iterations per step
    /// with the factor of the rest shape; the amortized policy, before CG's warm start took the
    /// patch's correction into account, refactorised every 11 steps, each a 3.3 ms step
    /// against a 0.4 ms median.
    RealTime,
    /// Never within a step: a new factor (CG stalled — a run of more than
    /// `BACKGROUND_STALL_ITERATIONS` iterations —, the ski-rental price reached, or a new
    /// period from [`Fem::set_dt`]) is assembled and factorised on the body's factor thread
    /// from a snapshot taken at the request, and swapped in `delay_steps` steps later
    /// (`background.rs`). Meanwhile CG goes on with the factor it has (up to
    /// `BACKGROUND_CG_MAX_ITERATIONS`). Deterministic whatever the thread's speed; a step
    /// whose factor is not ready waits for it (counted in [`SolverCounters::factor_waits`]).
    /// The exception: a step with organ-to-organ contact springs factorises its own matrix,
    /// as in every policy.
    Background {
        /// `D`: steps from the request to the swap, at least 1.
        delay_steps: u32,
    },
}

/// A finite-element body: one organ's tetrahedral mesh, its state (displacements and
/// velocities) and everything its steps need, allocated up front.
#[derive(Debug, Clone)]
pub struct Fem {
    params: FemParameters,
    lambda: f64,
    mu: f64,
    elements: Vec<Element>,
    mass: Vec<f64>,
    /// Nodes without unknowns: fixed by the mesh, or used by no tetrahedron.
    held: Vec<bool>,
    /// The mesh's outward surface, and for each node the surface triangles around it
    /// (`node_faces[node_face_ptr[i]..node_face_ptr[i + 1]]`), for the contact normal.
    surface: Vec<[u32; 3]>,
    node_face_ptr: Vec<usize>,
    node_faces: Vec<u32>,
    rest: Vec<[f64; 3]>,
    /// The state: displacements `u = x − X` (kept instead of positions so that small
    /// deformations of a body far from the origin keep full precision), and velocities.
    u: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    /// Positions `X + u`, refreshed whenever `u` changes (what callers and contact read).
    x: Vec<[f64; 3]>,
    /// Matrix, pattern and factor. What the factor holds is tracked by `factor`.
    system: Box<System>,
    factor: Factor,
    solver: CorotationalSolver,
    refactor: RefactorPolicy,
    /// CG iterations of the last corotational step (0 for a direct solve).
    last_iterations: usize,
    /// CG iterations of the first step with the current factor (`None` until it is taken),
    /// and the iterations beyond that count summed over the later steps (refactor policy).
    baseline_iterations: Option<usize>,
    extra_iterations: usize,
    /// Consecutive CG runs, up to the last, whose first iteration alone reached the
    /// tolerance relative to its start: from two on (not just after a refactorisation, whose
    /// fresh factor always does), one iteration suffices whatever the start, so the warm start
    /// cannot save one and the next run skips it (and its product).
    one_iteration_runs: u32,
    /// Running totals since construction, for benchmarks ([`Fem::solver_counters`]).
    counters: SolverCounters,
    /// The worker pool the step's element loops run on (`None`, or one thread: on the
    /// caller alone). Bit-for-bit the same results either way (`crate::parallel`).
    pool: Option<Arc<WorkerPool>>,
    /// The factor thread of [`RefactorPolicy::Background`] (`background.rs`), and a body's
    /// in-step factorisations are counted by `system`.
    background: Option<Box<background::FactorThread>>,
    /// Scratch buffers (boxed: keeps `Model` small).
    s: Box<Scratch>,
}

/// Running totals of a body's solver work since it was built: for benchmarks and logs.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolverCounters {
    /// Steps taken.
    pub steps: u64,
    /// Conjugate-gradient iterations, summed over the corotational steps.
    pub cg_iterations: u64,
    /// Numeric factorisations on the stepping thread (set-up, refactorisations of the lagged
    /// preconditioner, direct solves).
    pub factorizations: u64,
    /// Factorisations made on the factor thread and swapped in
    /// ([`RefactorPolicy::Background`]).
    pub background_factorizations: u64,
    /// Steps that had to wait for a background factor at their swap.
    pub factor_waits: u64,
    /// Applications of the lagged-factor preconditioner (each a pair of triangular solves
    /// with the factor), CG's and the contact term's.
    pub preconditioner_solves: u64,
    /// Updates of the per-node rotations that turn the lagged factor (one pass over the
    /// elements); skipped by the steps that apply no preconditioner.
    pub node_rotation_updates: u64,
}

/// Scratch of a [`Fem`]: every buffer `step` uses, allocated once.
#[derive(Debug, Clone)]
struct Scratch {
    /// The elements in SIMD batches, with per element the warm start of the rotation search
    /// (unit quaternion; reset to identity by `reset`/`set_state`) and the rotated gradients
    /// `R bᵢ`: written by `internal_forces` (corotational), read by the assembly and the
    /// matrix-free product.
    batch: Batches,
    /// Per node: its rotation (unit quaternion), the rotation it had when the
    /// factor was made, and a quaternion sum; written by `update_node_rotations` (and
    /// `factor_dynamic` for the lagged one), read by it. Reset with the element rotations.
    node_rot: Vec<[f64; 4]>,
    node_rot_lag: Vec<[f64; 4]>,
    node_sum: Vec<[f64; 4]>,
    /// Whether `node_rot` and `node_turn` lag the element rotations: set when those move
    /// (`internal_forces`), by a reset and by a factor landing; cleared by
    /// `ensure_node_rotations`, which the preconditioner and a factor's snapshot call first.
    node_rot_stale: bool,
    /// Scratch, per free node (DOF block): `R_now R_lagᵀ`, written by `update_node_rotations`,
    /// read by `precondition`.
    node_turn: Vec<element::Mat3>,
    /// Scratch, per node: `−f_int(x)`, written by `internal_forces`, read by the rhs build.
    force: Vec<[f64; 3]>,
    /// Per DOF: the right-hand side `b`, written by `step`/`solve_static`; the direct
    /// solves overwrite it with the increment `d`.
    rhs: Vec<f64>,
    /// Per DOF, one per contact direction: the contact vectors `c_a` (written by
    /// `contact_setup`); the direct solves overwrite them with `z_a = K̃⁻¹ c_a`.
    contact_dir: [Vec<f64>; 3],
    /// Scratch, per DOF and direction: `P⁻¹ c_a` for the preconditioner's contact term,
    /// written by `solve_pcg` / `cg_with_refactor`, read by `precondition`.
    contact_pc: [Vec<f64>; 3],
    /// Per DOF, the last three steps' tool-free velocities `w = K̃⁻¹ b / Δt` (the solve before
    /// the contact patch's correction; newest first): written by `step_colliding` (rotated,
    /// no allocation), set from the velocities by `set_state`, zeroed by a reset; read by
    /// `cg` for its first guess, the increment extrapolated from them, `Δt (3w − 3w⁻ + w⁻⁻)`.
    free_v: [Vec<f64>; 3],
    /// Per DOF: CG's iterate (the increment `d`), residual, preconditioned residual,
    /// search direction and matrix product; written and read by `cg` only (and `sol` by
    /// `apply_increment`).
    sol: Vec<f64>,
    cg_r: Vec<f64>,
    cg_z: Vec<f64>,
    cg_p: Vec<f64>,
    cg_q: Vec<f64>,
    /// Linear mode only (empty otherwise): the columns of `K̃⁻¹` for the DOF blocks the tool
    /// touched most recently, [`INVERSE_SLOTS`] slots of three `n_dof` columns; the key of each
    /// slot (the block's first DOF, or `NONE`) and when it was last used. Filled by
    /// `inverse_columns`, cleared by `factor_dynamic`.
    inv_cols: Vec<f64>,
    inv_key: Vec<u32>,
    inv_used: Vec<u64>,
    inv_clock: u64,
    /// The contact patch's solve (`patch_correct` only).
    patch: crate::patch::PatchSolve,
    /// Whether the last step's increment includes the patch's correction (`patch.correction`):
    /// CG's warm start then takes it off its extrapolation, since CG solves the step without
    /// the tool (`Fem::cg`).
    patch_applied: bool,
    /// Corotational mode only (empty otherwise), per DOF: the step's right-hand side `b`,
    /// its increment without the tool `K̃⁻¹ b`, and the gap between the increment with the
    /// patch's forces and the lagged factor's prediction of it; written and read by
    /// `patch::refine_patch`.
    refine_b: Vec<f64>,
    refine_free: Vec<f64>,
    refine_gap: Vec<f64>,
    /// Linear mode: the patch's cache of `K̃⁻¹` columns, three per node (`patch::patch_slot`):
    /// per node its slot or `NONE`, per slot its node and last use (grown to
    /// `PATCH_CACHE_NODES` on use), the columns.
    pc_slot_of: Vec<u32>,
    pc_node: Vec<u32>,
    pc_used: Vec<u64>,
    pc_cols: Vec<f64>,
    pc_clock: u64,
    /// The patch's forces on its nodes (node, N), summed per node for the correction
    /// (`patch::cached_correction`); room for every node of a full patch, reserved once.
    pc_force: Vec<(u32, [f64; 3])>,
    pc_correction: PatchCorrection,
}

/// Node blocks of `K̃⁻¹` columns kept by a linear body (see `Scratch::inv_cols`): a touched
/// triangle's three nodes and those around it as the god-object slides.
const INVERSE_SLOTS: usize = 12;

/// What the system's Cholesky factor currently holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Factor {
    /// `K̃` with the rest stiffness (the linear mode's matrix; at rest, also the corotational
    /// one).
    RestDynamic,
    /// `K̃` with the warped stiffness of some recent step (corotational preconditioner).
    WarpedDynamic,
    /// Something else (a static `K`), or a failed factorisation.
    Stale,
}

/// A solve that failed (non-finite numbers): the step becomes a blow-up.
#[derive(Debug, Clone, Copy)]
struct Failed;

impl From<system::NotPositiveDefinite> for Failed {
    fn from(_: system::NotPositiveDefinite) -> Failed {
        Failed
    }
}
