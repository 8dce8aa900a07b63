//! Linear tetrahedral finite elements (thesis §4.2, eqs. 4.4–4.22), in two flavours:
//! [`FemMode::Linear`] as in the thesis, and [`FemMode::Corotational`] (stiffness warping, the
//! default), because linear elasticity measures strain with `sym(∇u)`, which is not zero under
//! a rotation: a linear body that turns inflates and pushes back against the turn.
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
//! factor made once; `d = u⁺ − u` then feeds the tool's update below). The scheme is unconditionally stable and dissipative in the stiffness
//! (undamped amplification `1/√(1+ω²Δt²)`), so the thesis' Δt = 0.01 s on milligram nodes is
//! fine.
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
//! reused buffers) costs 1.5 ms on the liver (1706 tets) and 0.25 s at 52k tets, so by default
//! the step is solved by **conjugate gradients preconditioned with a lagged factor** instead:
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
//!   traffic again; 5.4 → 2.9 ms per solve at 50k tets, iteration counts of the smooth steps
//!   unchanged), and it is refreshed by *ski rental*: once the CG iterations beyond what the fresh
//!   factor needed, summed since the last refactorisation, reach the price of one — estimated
//!   from the factor's structure as `√(flops / nnz(L))` iterations, at least ten (`system.rs`:
//!   10 on the organ meshes, 27 at 50k tetrahedra, where a refactorisation costs about 26
//!   iterations);
//! - CG starts from the increment extrapolated from the last three steps,
//!   `Δt (3v − 3v⁻ + v⁻⁻)`, scaled to minimise the error in the energy norm (one extra
//!   product; never worse than starting from zero in that norm): on a smoothly moving body the
//!   initial residual is 1–5 % of the right-hand side, which saves about one iteration in
//!   four;
//! - CG stops at a relative residual of 1e-5 (on the liver swinging under gravity the
//!   trajectory stays within 1.2e-8 m of the refactorised one over 200 steps and 7 cm of
//!   motion); if it has not converged in 20 iterations, or from the third iteration on its
//!   mean rate so far predicts that it will not, the factor is refreshed within the step.
//!
//! Measured on one core (release, per step median / mean; `E` 140 Pa, `ν` 0.023, `ρ` 10,
//! `α` 10, `Δt` 0.01 s), *before* nested dissection, the warm start, the early give-up and the
//! structural refactor price (fixed at 10 iterations then):
//!
//! | body | corotational, lagged-factor CG | corotational, refactorised | linear |
//! |---|---|---|---|
//! | liver (1706 tets) swinging under gravity | 0.36 / 0.45 ms | 1.47 / 1.48 ms | 0.13 ms |
//! | liver settled, stroked by a 300 N/m tool | 0.60 / 0.71 ms | 1.62 / 1.63 ms | 0.23 ms |
//! | box, 4.3k tets, cantilever falling from rest | 2.0 / 2.4 ms | 4.6 ms | 0.37 ms |
//! | box, 24k tets, same | 16 / 22 ms | 93 ms | 4.2 ms |
//! | box, 52k tets, same | 35 / 52 ms | 250 ms | 10 ms |
//! | box, 52k tets, settled, touched by the tool | 21 / 24 ms | | |
//!
//! The means include the refactorisations (single precision: 1 ms on the liver, 0.15 s at
//! 52k), frequent in the violent transients and rare once a body has settled.
//!
//! After them (2026-11-21, `lop-bench models` part 2: soft bars, `E` 3 kPa, `ν` 0.45, `ρ`
//! 1000, `α` 1, fixed at one end, sagging from rest; the same 40 steps at every size — about
//! 30 smooth ones, then the bar folds at its clamp with thousands of inverted elements; the
//! same harness on the code before, on a busy machine: both columns are inflated alike):
//!
//! | box | before: median / mean / p99 | after: median / mean / p99 | CG iterations (40 steps) |
//! |---|---|---|---|
//! | 30k tets | 26 / 46 / 137 ms | 22 / 28 / 107 ms | 149 → 139 |
//! | 50k tets | 67 / 209 / 642 ms | 45 / 92 / 260 ms | 299 → 168 |
//! | 100k tets | 321 / 1024 / 2811 ms | 211 / 406 / 1024 ms | 352 → 179 |
//!
//! At 50k a step of the smooth phase then cost ~29 ms with 3 CG iterations and ~37 ms with 4:
//! 4 × 5.4 ms of preconditioning (two single-precision triangular solves, memory-bound), 5 ×
//! 1.1 ms of matrix-free products, 8.7 ms of element forces and rotations (two thirds of it
//! the polar decompositions) and 0.9 ms of node rotations; a refactorisation costs ~150 ms
//! (assembly and single-precision numeric factorisation). Since then the preconditioner solves
//! in half precision (3.0 ms per application) and the element loops run four elements at a
//! time in AVX registers (`batch.rs`, bit-for-bit the scalar arithmetic): element forces and
//! rotations 8 → 2.0 ms, a product 1.5 → 0.75 ms (timed phase by phase on the same machine),
//! so a smooth 50k step costs ~16 ms with 3 iterations and ~21 ms with 4.
//!
//! Factorisation: faer's sparse Cholesky (supernodal; faer picks it by its flop estimate for
//! all these meshes, and its solves beat the simplicial ones even though relaxed supernodes
//! store 40 % more — without relaxation the 50k factor is 6 % smaller but its solves are
//! slower), on a numbering ordered by AMD or geometric nested dissection on the node graph,
//! whichever gives the smaller factor (`system.rs`, `ordering.rs`): AMD on the organ meshes,
//! nested dissection from ~10k tets (50k: nnz(L) 23.2M → 16.1M, factorisation ×1.8 and solves
//! ×1.3–1.6 faster; 100k: 62.6M → 41.2M, ×2.3–2.4 and ×1.6–1.8).
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
//! # Allocation
//!
//! Everything `step` touches is allocated by [`Fem::new`] (or by the first step after a change
//! of factor precision): the sparse pattern and factors, faer's scratch memory, and the
//! per-node, per-element and per-DOF scratch vectors documented on the struct.
//! [`Fem::solve_static`] and [`Fem::elastic_forces`] allocate.

// 3×3 and 4-node kernels index several arrays with the same small index; iterator chains
// would obscure the formulas they transcribe.
#![allow(clippy::needless_range_loop)]

mod batch;
pub(crate) mod element;
mod ordering;
mod packed;
mod rotation;
mod shapes;
mod system;

use thiserror::Error;

use crate::contact::{closest_on_surface, SurfaceHit};
use crate::mesh::TetMesh;
use crate::model::{BlowUp, ContactReport, ContactSpring, ToolAnchor, ToolContact, RUNAWAY_SPEED};

use batch::Batches;
use element::{
    add, cross, dot, lame, mat_mul_t, mat_t_mul, mat_t_vec, mat_vec, norm, scale, stress, sub,
    Element,
};
use rotation::{closest_rotation, quat_to_mat, quat_to_mat_minus_identity, QUAT_IDENTITY};
#[doc(hidden)]
pub use system::NodeOrdering;
use system::{Precision, System, NONE};

#[doc(hidden)]
pub use shapes::box_mesh;

/// Which elasticity the elements use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FemMode {
    /// Linear elasticity (thesis §4.2): one factorisation per scene; inflates under rotation.
    Linear,
    /// Corotational (stiffness warping): rotation-invariant; solved by preconditioned CG.
    #[default]
    Corotational,
}

/// Parameters of a finite-element body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FemParameters {
    /// Young's modulus `E`, Pa.
    pub young: f64,
    /// Poisson's ratio `ν`, in (−1, 0.5).
    pub poisson: f64,
    /// Density `ρ`, kg/m³.
    pub density: f64,
    /// Mass-proportional damping `α`, 1/s: `D = αM`.
    pub damping: f64,
    /// Time step, s.
    pub dt: f64,
    /// Linear or corotational elements.
    pub mode: FemMode,
}

/// Why a finite-element body could not be built or solved.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FemError {
    /// A parameter is out of range or not finite.
    #[error("FEM parameter `{name}` = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// Field of [`FemParameters`].
        name: &'static str,
        /// The value given.
        value: f64,
        /// The valid range.
        expected: &'static str,
    },
    /// A tetrahedron is flat, inverted or collapsed at rest.
    #[error(
        "tetrahedron {element} (nodes {nodes:?}, 0-based) is degenerate or inverted: \
         signed volume {volume:e} m^3"
    )]
    DegenerateElement {
        /// 0-based tetrahedron index.
        element: usize,
        /// Its 0-based node indices.
        nodes: [u32; 4],
        /// Its signed rest volume.
        volume: f64,
    },
    /// A static solve on a body with no fixed node (it has no equilibrium under a net load).
    #[error("the body has no fixed nodes: a static equilibrium needs supports")]
    Unsupported,
    /// The stiffness matrix is not positive definite: the fixed nodes leave a rigid motion free.
    #[error("the stiffness matrix is singular: the fixed nodes do not prevent every rigid motion")]
    Singular,
    /// The corotational static iteration did not reach the tolerance.
    #[error(
        "static solve did not converge in {iterations} iterations \
         (relative residual {residual:e})"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Final residual relative to the load.
        residual: f64,
    },
    /// faer could not build the sparse structures (out of memory, index overflow).
    #[error("sparse solver setup failed: {0}")]
    Solver(String),
}

/// Result of [`Fem::solve_static`].
#[derive(Debug, Clone, PartialEq)]
pub struct StaticReport {
    /// Equilibrium positions, m (also the body's new state, at rest).
    pub positions: Vec<[f64; 3]>,
    /// Linear solves done.
    pub iterations: usize,
    /// `‖f − f_int‖` on the free DOFs at `positions`, relative to the load (or, with no load,
    /// to the initial residual): at most 1e-10, or the round-off floor of a stiff body (see
    /// [`Fem::solve_static`]).
    pub residual: f64,
}

/// Relative residual at which [`Fem::solve_static`] stops.
const STATIC_TOLERANCE: f64 = 1e-10;
/// [`Fem::solve_static`] also stops when no node moves by more than this many times the
/// largest displacement (a few dozen ulps): the residual is then at its round-off floor.
const STATIC_ROUND_OFF: f64 = 1e-14;
/// Trial steps of [`Fem::solve_static`]'s line search (corotational).
const STATIC_LINE_SEARCH: usize = 8;
/// Iteration limit of [`Fem::solve_static`].
const STATIC_MAX_ITERATIONS: usize = 200;

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

/// CG stops at `‖r‖ ≤ CG_TOLERANCE · ‖b‖`. On the liver swinging under gravity (Table 6.2)
/// this keeps the trajectory within 1.2e-8 m of the one solved exactly by refactorisation
/// (200 steps, 7 cm of motion); equilibria are exact whatever the tolerance, since the
/// right-hand side always holds the true elastic forces.
const CG_TOLERANCE: f64 = 1e-5;
/// CG iterations before giving up on the lagged factor and refactorising within the step.
const CG_MAX_ITERATIONS: usize = 20;

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
    /// Numeric factorisations (set-up, refactorisations of the lagged preconditioner, direct
    /// solves).
    pub factorizations: u64,
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
    /// Per node: the velocities before the last step and the one before it (`v⁻`, `v⁻⁻`),
    /// written by `step_colliding`, reset with the state; read by `cg` for its first guess,
    /// the increment extrapolated from the last three, `Δt (3v − 3v⁻ + v⁻⁻)`.
    v_before: Vec<[f64; 3]>,
    v_before2: Vec<[f64; 3]>,
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

impl Fem {
    /// Builds the body on `mesh` (rest shape = the mesh's nodes; fixed = `mesh.fixed`),
    /// analyses the sparsity pattern and factorises the system matrix at rest.
    ///
    /// # Errors
    /// [`FemError::InvalidParameter`] for a non-finite or out-of-range parameter,
    /// [`FemError::DegenerateElement`] for a flat or inverted tetrahedron,
    /// [`FemError::Solver`] if the sparse structures cannot be built.
    pub fn new(mesh: &TetMesh, params: FemParameters) -> Result<Fem, FemError> {
        Fem::with_factorization(mesh, params, None)
    }

    /// [`Fem::new`] with the fill-reducing ordering forced instead of the smaller-fill one of
    /// AMD and nested dissection: for benchmarks and tests.
    #[doc(hidden)]
    pub fn with_ordering(
        mesh: &TetMesh,
        params: FemParameters,
        ordering: NodeOrdering,
    ) -> Result<Fem, FemError> {
        Fem::build(mesh, params, None, ordering)
    }

    /// [`Fem::new`] with the factorisation forced supernodal (`Some(true)`) or simplicial
    /// (`Some(false)`) instead of faer's choice: for benchmarks.
    #[doc(hidden)]
    pub fn with_factorization(
        mesh: &TetMesh,
        params: FemParameters,
        supernodal: Option<bool>,
    ) -> Result<Fem, FemError> {
        Fem::build(mesh, params, supernodal, NodeOrdering::Auto)
    }

    fn build(
        mesh: &TetMesh,
        params: FemParameters,
        supernodal: Option<bool>,
        ordering: NodeOrdering,
    ) -> Result<Fem, FemError> {
        validate(&params)?;
        let (lambda, mu) = lame(params.young, params.poisson);
        let n = mesh.nodes.len();
        let mut elements = Vec::with_capacity(mesh.tets.len());
        for (i, t) in mesh.tets.iter().enumerate() {
            let corners = t.map(|k| mesh.nodes[k as usize]);
            let e = Element::new(*t, corners).ok_or_else(|| FemError::DegenerateElement {
                element: i,
                nodes: *t,
                volume: mesh.tet_volume(i),
            })?;
            elements.push(e);
        }
        let mut mass = vec![0.0; n];
        for e in &elements {
            for &k in &e.nodes {
                mass[k as usize] += params.density * e.volume / 4.0;
            }
        }
        let mut held: Vec<bool> = mass.iter().map(|&m| !(m > 0.0)).collect();
        for &f in &mesh.fixed {
            held[f as usize] = true;
        }
        let system = System::new(&mesh.nodes, &elements, &held, supernodal, ordering)
            .map_err(|e| FemError::Solver(format!("{e:?}")))?;
        let n_dof = system.n_dof;
        let mut node_face_ptr = vec![0usize; n + 1];
        for tri in &mesh.surface {
            for &k in tri {
                node_face_ptr[k as usize + 1] += 1;
            }
        }
        for i in 0..n {
            node_face_ptr[i + 1] += node_face_ptr[i];
        }
        let mut node_faces = vec![0u32; node_face_ptr[n]];
        let mut fill = node_face_ptr.clone();
        for (f, tri) in mesh.surface.iter().enumerate() {
            for &k in tri {
                node_faces[fill[k as usize]] = f as u32;
                fill[k as usize] += 1;
            }
        }
        let s = Box::new(Scratch {
            batch: Batches::new(&elements, &system.dof, lambda, mu),
            node_rot: vec![QUAT_IDENTITY; n],
            node_rot_lag: vec![QUAT_IDENTITY; n],
            node_sum: vec![[0.0; 4]; n],
            node_turn: vec![rotation::IDENTITY; n_dof / 3],
            force: vec![[0.0; 3]; n],
            rhs: vec![0.0; n_dof],
            contact_dir: [vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]],
            contact_pc: [vec![0.0; n_dof], vec![0.0; n_dof], vec![0.0; n_dof]],
            v_before: vec![[0.0; 3]; n],
            v_before2: vec![[0.0; 3]; n],
            sol: vec![0.0; n_dof],
            cg_r: vec![0.0; n_dof],
            cg_z: vec![0.0; n_dof],
            cg_p: vec![0.0; n_dof],
            cg_q: vec![0.0; n_dof],
            inv_cols: if params.mode == FemMode::Linear {
                vec![0.0; 3 * INVERSE_SLOTS * n_dof]
            } else {
                Vec::new()
            },
            inv_key: if params.mode == FemMode::Linear {
                vec![NONE; INVERSE_SLOTS]
            } else {
                Vec::new()
            },
            inv_used: vec![0; INVERSE_SLOTS],
            inv_clock: 0,
        });
        let mut fem = Fem {
            params,
            surface: mesh.surface.clone(),
            node_face_ptr,
            node_faces,
            lambda,
            mu,
            elements,
            mass,
            held,
            rest: mesh.nodes.clone(),
            u: vec![[0.0; 3]; n],
            x: mesh.nodes.clone(),
            v: vec![[0.0; 3]; n],
            system: Box::new(system),
            factor: Factor::Stale,
            solver: CorotationalSolver::LaggedFactorPcg,
            last_iterations: 0,
            baseline_iterations: None,
            extra_iterations: 0,
            one_iteration_runs: 0,
            counters: SolverCounters::default(),
            s,
        };
        fem.factor_dynamic(false)
            .map_err(|_| FemError::Solver("system matrix at rest is not SPD".into()))?;
        Ok(fem)
    }

    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }
    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }
    /// Lumped nodal masses, kg.
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }
    /// The body's time step, s.
    pub fn dt(&self) -> f64 {
        self.params.dt
    }
    /// The parameters the body was built with.
    pub fn parameters(&self) -> &FemParameters {
        &self.params
    }
    /// Sub-steps per step: always 1 (the scheme is implicit).
    pub fn substeps(&self) -> usize {
        1
    }
    /// Free degrees of freedom (3 per node that is neither fixed nor unused).
    pub fn dofs(&self) -> usize {
        self.system.n_dof
    }
    /// Conjugate-gradient iterations of the last corotational step (0 when it was solved
    /// directly, and always 0 in linear mode): for logs and benchmarks.
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }
    /// Stored non-zeros of the system matrix (one triangle) and of its Cholesky factor, and
    /// whether faer factorises it supernodally: for logs and benchmarks.
    pub fn solver_info(&self) -> (usize, usize, bool) {
        let (a, l) = self.system.nnz();
        (a, l, self.system.is_supernodal())
    }
    /// The fill-reducing ordering of the system (AMD or nested dissection): for benchmarks.
    #[doc(hidden)]
    pub fn ordering(&self) -> NodeOrdering {
        self.system.ordering()
    }
    /// Factorises `K̃` at rest again, in the precision the body's solver uses (single for the
    /// corotational preconditioner, double otherwise): for benchmarks of the factorisation.
    /// Allocation-free after the first call.
    #[doc(hidden)]
    pub fn refactorize_at_rest(&mut self) -> bool {
        self.factor_dynamic(false).is_ok()
    }
    /// Solves `K̃ x = rhs` in place (one DOF vector, [`Fem::dofs`] long) with the body's
    /// current factor: for benchmarks of the triangular solves.
    ///
    /// # Panics
    /// If `rhs` does not have one entry per DOF.
    #[doc(hidden)]
    pub fn solve_with_factor(&mut self, rhs: &mut [f64]) {
        assert_eq!(rhs.len(), self.system.n_dof, "one entry per DOF");
        self.system.solve_in_place(rhs);
    }
    /// Steps, CG iterations and factorisations since the body was built: for benchmarks.
    #[doc(hidden)]
    pub fn solver_counters(&self) -> SolverCounters {
        SolverCounters {
            factorizations: self.system.factorizations(),
            ..self.counters
        }
    }
    /// Chooses how corotational steps are solved: for benchmarks.
    #[doc(hidden)]
    pub fn set_corotational_solver(&mut self, solver: CorotationalSolver) {
        self.solver = solver;
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| 0.5 * m * dot(*v, *v))
            .sum()
    }

    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        self.v.iter().map(|v| norm(*v)).fold(0.0, f64::max)
    }

    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        self.x.copy_from_slice(&self.rest);
        self.u.iter_mut().for_each(|u| *u = [0.0; 3]);
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.v_before.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.v_before2.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.one_iteration_runs = 0;
        self.s.batch.reset_rotations();
        self.s.node_rot.iter_mut().for_each(|q| *q = QUAT_IDENTITY);
    }

    /// Replaces the state (for levels-of-precision switching, or to prescribe boundary
    /// displacements before [`Fem::solve_static`]). Fixed nodes take the given positions and
    /// are held there, at zero velocity. The rotation search restarts cold, so what follows
    /// depends on `x` and `v` only (and, for the corotational solver's speed, not its result,
    /// on which factor it holds).
    ///
    /// # Panics
    /// If `x` or `v` does not have one entry per node.
    pub fn set_state(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) {
        assert_eq!(x.len(), self.x.len(), "set_state: one position per node");
        assert_eq!(v.len(), self.v.len(), "set_state: one velocity per node");
        self.x.copy_from_slice(x);
        for ((u, x), r) in self.u.iter_mut().zip(x).zip(&self.rest) {
            *u = sub(*x, *r);
        }
        for (i, vi) in self.v.iter_mut().enumerate() {
            *vi = if self.held[i] { [0.0; 3] } else { v[i] };
        }
        self.s.v_before.copy_from_slice(&self.v);
        self.s.v_before2.copy_from_slice(&self.v);
        self.one_iteration_runs = 0;
        self.s.batch.reset_rotations();
        self.s.node_rot.iter_mut().for_each(|q| *q = QUAT_IDENTITY);
    }

    /// Elastic force on every node at the current positions, N: `−K(x − X)` (linear) or
    /// `−Σₑ Rₑ Kₑ (Rₑᵀx − X)` (corotational). On a fixed node it is the load the node passes
    /// to its support. Allocates; not for the real-time path.
    pub fn elastic_forces(&self) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; self.x.len()];
        for (e, el) in self.elements.iter().enumerate() {
            let mut q = self.s.batch.rotation(e);
            let (f, _) =
                element_forces(el, &self.u, self.params.mode, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                out[n as usize] = add(out[n as usize], f[k]);
            }
        }
        out
    }

    /// `K u`: the rest (linear) stiffness applied to a displacement field `u` (m, one per
    /// node), N — what a linear body would push back with, `−f_int(X + u)`. The same in both
    /// modes (corotational elements linearise to it at rest). For reduced models built on top of
    /// this one, such as the cage dynamics of `crate::lop`. Allocates; not for the real-time
    /// path.
    ///
    /// # Panics
    /// If `u` does not have one entry per node.
    pub fn rest_stiffness_product(&self, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
        assert_eq!(u.len(), self.x.len(), "one displacement per node");
        let mut out = vec![[0.0; 3]; u.len()];
        for el in &self.elements {
            let mut q = QUAT_IDENTITY;
            let (f, _) = element_forces(el, u, FemMode::Linear, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                out[n as usize] = sub(out[n as usize], f[k]);
            }
        }
        out
    }

    /// Whether node `i` is held (fixed by the mesh, or used by no tetrahedron).
    pub fn is_held(&self, i: usize) -> bool {
        self.held[i]
    }

    /// Advances by `dt` under `gravity` (m/s²), the nodal loads `external` (N, one per node;
    /// missing entries count as zero) and the tool. On a blow-up the body is reset to rest and
    /// the cause returned. Allocation-free.
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        self.step_colliding(gravity, external, contact, &[])
    }

    /// [`Fem::step`] with organ-to-organ contact springs. While any spring pushes, the step
    /// assembles the springs' stiffness into `K̃` and solves directly (refactorising, in both
    /// modes: their number and place change every step, so neither the linear mode's
    /// factor nor the lagged preconditioner can hold them); the tool still enters by
    /// Sherman–Morrison–Woodbury on that factor.
    pub fn step_colliding(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, BlowUp> {
        let dt = self.params.dt;
        let colliding = springs.iter().any(|s| s.touch(&self.x).is_some());
        // Linear mode without contact springs solves for the new displacement directly (see
        // `solve_linear_total`): no elastic forces to evaluate.
        let total = self.params.mode == FemMode::Linear && !colliding;
        if !total {
            self.internal_forces();
        }
        // b = f − f_int(x) + (M/Δt − D/2) v on the free DOFs; in linear mode without springs
        // K̃ u + b = f + (M/Δt² + D/(2Δt)) u + (M/Δt − D/2) v instead (f_int = K u cancels).
        let vel_coef = 1.0 / dt - self.params.damping / 2.0;
        let disp_coef = 1.0 / (dt * dt) + self.params.damping / (2.0 * dt);
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            let m = self.mass[i];
            let ext = external.get(i).copied().unwrap_or([0.0; 3]);
            for c in 0..3 {
                let state = if total {
                    m * disp_coef * self.u[i][c]
                } else {
                    self.s.force[i][c]
                };
                self.s.rhs[d as usize + c] =
                    state + m * gravity[c] + ext[c] + m * vel_coef * self.v[i][c];
            }
        }
        let pressed = contact.and_then(|c| self.contact_setup(c));
        let solved = match self.params.mode {
            _ if colliding => self.solve_colliding(pressed, springs),
            FemMode::Linear => self.solve_linear_total(pressed),
            FemMode::Corotational => match self.solver {
                CorotationalSolver::Refactor => self.solve_refactor(pressed),
                CorotationalSolver::LaggedFactorPcg => self.solve_pcg(pressed),
            },
        };
        self.counters.steps += 1;
        let Ok(report) = solved else {
            return self.blow_up(BlowUp::NonFinite);
        };
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d == NONE {
                continue;
            }
            self.s.v_before2[i] = self.s.v_before[i];
            self.s.v_before[i] = self.v[i];
            for c in 0..3 {
                let inc = self.s.sol[d as usize + c];
                self.u[i][c] += inc;
                self.x[i][c] = self.rest[i][c] + self.u[i][c];
                self.v[i][c] = inc / dt;
            }
        }
        self.check().map(|()| report)
    }

    /// Linear mode: the scene's factor of `K̃`, contact by Sherman–Morrison–Woodbury (module
    /// docs). `rhs` holds `K̃ u + b` (the step's right-hand side plus `K̃` times the current
    /// displacement, which needs no stiffness product since `K u = f_int`): the solve gives the
    /// new displacement, and the increment `K̃⁻¹ b` is its difference with `u` — one sparse
    /// triangular solve pair per step and nothing else. Leaves the increment in `sol`.
    fn solve_linear_total(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        if self.factor != Factor::RestDynamic {
            self.factor_dynamic(false)?;
        }
        self.system.solve_in_place(&mut self.s.rhs);
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    let k = d as usize + c;
                    self.s.sol[k] = self.s.rhs[k] - self.u[i][c];
                }
            }
        }
        self.last_iterations = 0;
        // K̃⁻¹ c from the cached columns of the touched nodes (the factor never changes).
        Ok(match pressed {
            Some(p) => self.woodbury_cached(&p),
            None => ContactReport::default(),
        })
    }

    /// Corotational, direct: refactorise the warped `K̃`, solve, and add the tool by
    /// Sherman–Morrison–Woodbury (dropping a push that would pull).
    fn solve_refactor(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        self.factor_dynamic(true)?;
        self.last_iterations = 0;
        self.s.sol.copy_from_slice(&self.s.rhs);
        self.system.solve_in_place(&mut self.s.sol);
        Ok(match pressed {
            Some(p) => self.woodbury(&p),
            None => ContactReport::default(),
        })
    }

    /// With contact springs: `(K̃ + K_c) d = b + f_c`, assembled (warped in corotational mode)
    /// and factorised for this step only (the factor is marked stale for the next).
    fn solve_colliding(
        &mut self,
        pressed: Option<Pressed>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, Failed> {
        let dt = self.params.dt;
        let warped = self.params.mode == FemMode::Corotational;
        self.factor = Factor::Stale;
        self.assemble(1.0 / (dt * dt) + self.params.damping / (2.0 * dt), warped);
        for s in springs {
            let Some(t) = s.touch(&self.x) else {
                continue;
            };
            let nn = outer(t.normal);
            for p in 0..3 {
                let dp = self.system.dof[t.tri[p] as usize];
                if dp == NONE || t.weights[p] == 0.0 {
                    continue;
                }
                for c in 0..3 {
                    self.s.rhs[dp as usize + c] += t.weights[p] * t.on_tissue[c];
                }
                for q in 0..3 {
                    let dq = self.system.dof[t.tri[q] as usize];
                    // Each unordered pair once; repeated nodes (a vertex) only on the diagonal.
                    if dq == NONE || t.weights[q] == 0.0 || dq < dp || (dq == dp && q != p) {
                        continue;
                    }
                    let w = t.stiffness * t.weights[p] * t.weights[q];
                    self.system.add_node_block(dp, dq, &nn, w);
                }
            }
        }
        self.system
            .factorize(Precision::Double)
            .map_err(|_| Failed)?;
        self.last_iterations = 0;
        self.s.sol.copy_from_slice(&self.s.rhs);
        self.system.solve_in_place(&mut self.s.sol);
        Ok(match pressed {
            Some(p) => self.woodbury(&p),
            None => ContactReport::default(),
        })
    }

    /// [`Fem::woodbury`] with `K̃⁻¹ c_a` assembled from cached columns of `K̃⁻¹` (linear mode:
    /// the factor is fixed, and `c_a` only involves the touched triangle's nodes), computed by
    /// three solves the first time a node is touched instead of one solve per direction every
    /// step.
    fn woodbury_cached(&mut self, p: &Pressed) -> ContactReport {
        let mut slots = [None; 3];
        for k in 0..3 {
            if p.dofs[k] != NONE && p.weights[k] != 0.0 {
                slots[k] = self.inverse_columns(p.dofs[k]);
                if slots[k].is_none() {
                    return self.woodbury(p);
                }
            }
        }
        let n = self.system.n_dof;
        for a in 0..p.m {
            let z = &mut self.s.contact_dir[a];
            z.fill(0.0);
            for (k, slot) in slots.iter().enumerate() {
                let Some(slot) = *slot else {
                    continue;
                };
                for b in 0..3 {
                    let w = p.weights[k] * p.dirs[a][b];
                    if w != 0.0 {
                        let col = &self.s.inv_cols[(3 * slot + b) * n..(3 * slot + b + 1) * n];
                        z.iter_mut().zip(col).for_each(|(z, c)| *z += w * c);
                    }
                }
            }
        }
        self.woodbury_solved(p)
    }

    /// The cache slot holding the three columns of `K̃⁻¹` for the DOF block starting at `d`,
    /// computed into the least recently used slot if missing. `None` without a cache (not
    /// linear mode) or without the rest factor.
    fn inverse_columns(&mut self, d: u32) -> Option<usize> {
        if self.s.inv_key.is_empty() || self.factor != Factor::RestDynamic {
            return None;
        }
        self.s.inv_clock += 1;
        let clock = self.s.inv_clock;
        if let Some(k) = self.s.inv_key.iter().position(|&key| key == d) {
            self.s.inv_used[k] = clock;
            return Some(k);
        }
        let k = (0..self.s.inv_key.len()).min_by_key(|&k| self.s.inv_used[k])?;
        let n = self.system.n_dof;
        for b in 0..3 {
            let col = &mut self.s.inv_cols[(3 * k + b) * n..(3 * k + b + 1) * n];
            col.fill(0.0);
            col[d as usize + b] = 1.0;
            self.system.solve_in_place(col);
        }
        self.s.inv_key[k] = d;
        self.s.inv_used[k] = clock;
        Some(k)
    }

    /// With `sol = K̃⁻¹ b`: the increment of `(K̃ + k' C Cᵀ) d = b − C F` is
    /// `d = sol − Z λ`, `Z = K̃⁻¹ C`, `(I + k' Cᵀ Z) λ = F + k' Cᵀ sol`; `λ` is the contact
    /// force after the step. A press whose `λ` would pull is dropped.
    fn woodbury(&mut self, p: &Pressed) -> ContactReport {
        for a in 0..p.m {
            self.system.solve_in_place(&mut self.s.contact_dir[a]);
        }
        self.woodbury_solved(p)
    }

    /// [`Fem::woodbury`] once `contact_dir` holds `Z = K̃⁻¹ C`.
    fn woodbury_solved(&mut self, p: &Pressed) -> ContactReport {
        let m = p.m;
        let mut sm = [[0.0; 3]; 3];
        let mut r = [0.0; 3];
        for a in 0..m {
            for b in 0..m {
                sm[a][b] = (a == b) as u8 as f64 + p.stiffness * p.dot(a, &self.s.contact_dir[b]);
            }
            r[a] = p.force[a] + p.stiffness * p.dot(a, &self.s.sol);
        }
        let Some(lambda) = solve_small(sm, r, m) else {
            return ContactReport::default();
        };
        if !p.admissible(lambda) {
            return ContactReport::default();
        }
        for a in 0..m {
            for (d, z) in self.s.sol.iter_mut().zip(&self.s.contact_dir[a]) {
                *d -= lambda[a] * z;
            }
        }
        p.report(lambda, &self.s.sol)
    }

    /// Corotational, iterative: CG on `K̃_w + k' C Cᵀ` with the lagged factor as
    /// preconditioner (module docs).
    fn solve_pcg(&mut self, pressed: Option<Pressed>) -> Result<ContactReport, Failed> {
        self.update_node_rotations();
        if self.factor != Factor::WarpedDynamic && self.factor != Factor::RestDynamic {
            self.factor_dynamic(true)?;
        }
        // With contact: (K̃ + k' C Cᵀ) d = b − C F.
        if let Some(p) = pressed {
            self.prepare_contact_pc(&p);
            for a in 0..p.m {
                for (b, c) in self.s.rhs.iter_mut().zip(&self.s.contact_dir[a]) {
                    *b -= p.force[a] * c;
                }
            }
        }
        let (mut iterations, run) = self.cg_with_refactor(pressed)?;
        let mut report = ContactReport::default();
        if let Some(p) = pressed {
            let mut lambda = [0.0; 3];
            for (a, l) in lambda.iter_mut().enumerate().take(p.m) {
                *l = p.force[a] + p.stiffness * p.dot(a, &self.s.sol);
            }
            if p.admissible(lambda) {
                report = p.report(lambda, &self.s.sol);
            } else {
                // The linearised penalty would pull: solve again without the tool.
                for a in 0..p.m {
                    for (b, c) in self.s.rhs.iter_mut().zip(&self.s.contact_dir[a]) {
                        *b += p.force[a] * c;
                    }
                }
                iterations += self.cg_with_refactor(None)?.0;
            }
        }
        self.last_iterations = iterations;
        self.counters.cg_iterations += iterations as u64;
        // Ski rental: refresh the lagged factor once the iterations it has cost beyond what a
        // fresh factor needs (its first step's count) add up to about the price of a
        // refactorisation.
        match self.baseline_iterations {
            None => self.baseline_iterations = Some(run),
            Some(base) => self.extra_iterations += run.saturating_sub(base),
        }
        if self.extra_iterations >= self.system.refactor_price() {
            self.factor = Factor::Stale;
        }
        Ok(report)
    }

    /// `contact_pc[a] = (Q K̃_lag Qᵀ)⁻¹ c_a`, for the preconditioner.
    fn prepare_contact_pc(&mut self, p: &Pressed) {
        for a in 0..p.m {
            turned_solve(
                &mut self.system,
                &self.s.node_turn,
                &self.s.contact_dir[a],
                &mut self.s.contact_pc[a],
            );
        }
    }

    /// CG from zero; if it has not converged in [`CG_MAX_ITERATIONS`], refactorise with the
    /// current matrix and run it again (then it converges in one or two iterations). Returns
    /// the iterations done in all, and those of the run that converged.
    fn cg_with_refactor(&mut self, pressed: Option<Pressed>) -> Result<(usize, usize), Failed> {
        let spent = match self.cg(pressed, CG_MAX_ITERATIONS, true) {
            Ok(it) => return Ok((it, it)),
            Err(spent) => spent,
        };
        self.factor_dynamic(true)?;
        if let Some(p) = pressed {
            self.prepare_contact_pc(&p);
        }
        self.cg(pressed, CG_MAX_ITERATIONS, false)
            .map(|it| (it + spent, it))
            .map_err(|_| Failed)
    }

    /// Preconditioned CG for `A sol = rhs`, `A = K̃_w (+ k' c cᵀ)` applied matrix-free, the
    /// preconditioner the current factor. Returns the iterations, or as an error those done
    /// when `max` did not reach the tolerance (or the numbers went non-finite). With
    /// `give_up_early` it also stops as soon as, from the third iteration on, the residual's
    /// mean rate of decrease so far predicts more than `max` iterations (or none at all): a
    /// preconditioner that stale is refreshed at once rather than after `max` wasted
    /// iterations.
    ///
    /// It starts from the increment extrapolated quadratically from the last three steps,
    /// `g = Δt (3v − 3v⁻ + v⁻⁻)`, scaled by the `α` that minimises the error in the `A`-norm
    /// along it (`α = gᵀb / gᵀAg`), so the start is never worse than zero in that norm. One
    /// extra product; on a smoothly moving body the initial residual is 1–5 % of `‖b‖`,
    /// which saves about one preconditioned iteration of the usual four (linear
    /// extrapolation, `Δt (2v − v⁻)`, leaves about twice the residual and needs ~9 % more
    /// iterations on the 50k-tet bar). The stopping test stays relative to `‖b‖`. When the
    /// last two runs' first iterations alone reduced their residuals by the tolerance (a
    /// settled body: one iteration whatever the start), the start is zero instead.
    fn cg(
        &mut self,
        pressed: Option<Pressed>,
        max: usize,
        give_up_early: bool,
    ) -> Result<usize, usize> {
        let b_norm2 = self.s.rhs.iter().map(|b| b * b).sum::<f64>();
        let tol2 = CG_TOLERANCE * CG_TOLERANCE * b_norm2;
        self.s.sol.fill(0.0);
        self.s.cg_r.copy_from_slice(&self.s.rhs);
        if b_norm2 == 0.0 {
            return Ok(0);
        }
        if self.one_iteration_runs < 2 {
            self.warm_start(pressed);
        }
        let r2_start = dot_n(&self.s.cg_r, &self.s.cg_r);
        if !r2_start.is_finite() {
            return Err(0);
        }
        if r2_start <= tol2 {
            return Ok(0);
        }
        self.precondition(pressed);
        self.s.cg_p.copy_from_slice(&self.s.cg_z);
        let mut rz = dot_n(&self.s.cg_r, &self.s.cg_z);
        for it in 1..=max {
            self.apply_dynamic(pressed);
            let pq = dot_n(&self.s.cg_p, &self.s.cg_q);
            if !(pq > 0.0) {
                return Err(it);
            }
            let alpha = rz / pq;
            let mut r2 = 0.0;
            for k in 0..self.s.sol.len() {
                self.s.sol[k] += alpha * self.s.cg_p[k];
                self.s.cg_r[k] -= alpha * self.s.cg_q[k];
                r2 += self.s.cg_r[k] * self.s.cg_r[k];
            }
            if !r2.is_finite() {
                return Err(it);
            }
            if it == 1 {
                self.one_iteration_runs = if r2 <= CG_TOLERANCE * CG_TOLERANCE * r2_start {
                    self.one_iteration_runs.saturating_add(1)
                } else {
                    0
                };
            }
            if r2 <= tol2 {
                return Ok(it);
            }
            if give_up_early && it >= 3 {
                // ln of the mean reduction per iteration so far, and the iterations it
                // would still take (residuals squared: the factors of ½ cancel).
                let rate = (r2 / r2_start).ln() / it as f64;
                if !(rate < 0.0) || it as f64 + (tol2 / r2).ln() / rate > max as f64 {
                    return Err(it);
                }
            }
            self.precondition(pressed);
            // Polak–Ribière β = z⁺ᵀ(r⁺ − r)/zᵀr with r⁺ − r = −αq: "flexible" CG, robust to the
            // rounding of the single-precision preconditioner.
            let beta = -alpha * dot_n(&self.s.cg_z, &self.s.cg_q) / rz;
            rz = dot_n(&self.s.cg_r, &self.s.cg_z);
            for (p, z) in self.s.cg_p.iter_mut().zip(&self.s.cg_z) {
                *p = z + beta * *p;
            }
        }
        Err(max)
    }

    /// CG's start (see [`Fem::cg`]): with `sol = 0` and `cg_r = rhs` on entry, sets
    /// `sol = α g` and `cg_r = rhs − α A g` for the extrapolated increment `g`; leaves them
    /// if `gᵀAg` is not positive (a body at rest) or not finite.
    fn warm_start(&mut self, pressed: Option<Pressed>) {
        let dt = self.params.dt;
        let mut moving = false;
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                let (v, w, w2) = (self.v[i], self.s.v_before[i], self.s.v_before2[i]);
                for c in 0..3 {
                    let g = dt * (3.0 * (v[c] - w[c]) + w2[c]);
                    self.s.cg_p[d as usize + c] = g;
                    moving |= g != 0.0;
                }
            }
        }
        if !moving {
            return;
        }
        self.apply_dynamic(pressed);
        let gag = dot_n(&self.s.cg_p, &self.s.cg_q);
        let gb = dot_n(&self.s.cg_p, &self.s.rhs);
        if !(gag > 0.0 && gag.is_finite() && gb.is_finite()) {
            return;
        }
        let alpha = gb / gag;
        for k in 0..self.s.sol.len() {
            self.s.sol[k] = alpha * self.s.cg_p[k];
            self.s.cg_r[k] -= alpha * self.s.cg_q[k];
        }
    }

    /// `cg_z = P⁻¹ cg_r`, the preconditioner: `P = Q K̃_lag Qᵀ (+ k' c cᵀ)` — the lagged
    /// factor `K̃_lag` (of the warped matrix at some earlier step, or at rest) turned by `Q`,
    /// the block-diagonal per-node rotations accumulated since that factorisation
    /// (`node_turn`), plus the tool's rank-one stiffness by Sherman–Morrison with
    /// `contact_pc = (Q K̃_lag Qᵀ)⁻¹ c` (prepared by `solve_pcg`).
    fn precondition(&mut self, pressed: Option<Pressed>) {
        turned_solve(
            &mut self.system,
            &self.s.node_turn,
            &self.s.cg_r,
            &mut self.s.cg_z,
        );
        if let Some(p) = pressed {
            // Woodbury: z −= PC (I + k' Cᵀ PC)⁻¹ k' Cᵀ z.
            let m = p.m;
            let mut sm = [[0.0; 3]; 3];
            let mut r = [0.0; 3];
            for a in 0..m {
                for b in 0..m {
                    sm[a][b] =
                        (a == b) as u8 as f64 + p.stiffness * p.dot(a, &self.s.contact_pc[b]);
                }
                r[a] = p.stiffness * p.dot(a, &self.s.cg_z);
            }
            if let Some(s) = solve_small(sm, r, m) {
                for a in 0..m {
                    for (z, y) in self.s.cg_z.iter_mut().zip(&self.s.contact_pc[a]) {
                        *z -= s[a] * y;
                    }
                }
            }
        }
    }

    /// Per-node rotations: the normalised sum of the adjacent elements' quaternions (signs
    /// aligned with the node's previous rotation), into `node_rot`; and `node_turn`, each free
    /// node's rotation since the factor was made (`R_now R_lagᵀ`), indexed by DOF block.
    fn update_node_rotations(&mut self) {
        self.s.node_sum.iter_mut().for_each(|q| *q = [0.0; 4]);
        for (e, el) in self.elements.iter().enumerate() {
            let qe = self.s.batch.rotation(e);
            for &n in &el.nodes {
                let n = n as usize;
                let prev = self.s.node_rot[n];
                let sign = if quat_dot(&prev, &qe) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for c in 0..4 {
                    self.s.node_sum[n][c] += sign * qe[c];
                }
            }
        }
        for (n, &d) in self.system.dof.iter().enumerate() {
            let q = self.s.node_sum[n];
            let len = quat_dot(&q, &q).sqrt();
            if len > 1e-12 && len.is_finite() {
                self.s.node_rot[n] = q.map(|c| c / len);
            }
            if d != NONE {
                let now = quat_to_mat(&self.s.node_rot[n]);
                let lag = quat_to_mat(&self.s.node_rot_lag[n]);
                self.s.node_turn[d as usize / 3] = mat_mul_t(&now, &lag);
            }
        }
    }

    /// `cg_q = (M/Δt² + D/(2Δt) + K_w + k' c cᵀ) cg_p`, matrix-free.
    fn apply_dynamic(&mut self, pressed: Option<Pressed>) {
        let dt = self.params.dt;
        let coef = 1.0 / (dt * dt) + self.params.damping / (2.0 * dt);
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                let m = coef * self.mass[i];
                for c in 0..3 {
                    let k = d as usize + c;
                    self.s.cg_q[k] = m * self.s.cg_p[k];
                }
            }
        }
        self.s
            .batch
            .add_stiffness_product(&self.s.cg_p, &mut self.s.cg_q);
        if let Some(p) = pressed {
            for a in 0..p.m {
                let s = p.stiffness * p.dot(a, &self.s.cg_p);
                for k in 0..3 {
                    if p.dofs[k] != NONE {
                        let d = p.dofs[k] as usize;
                        for c in 0..3 {
                            self.s.cg_q[d + c] += s * p.weights[k] * p.dirs[a][c];
                        }
                    }
                }
            }
        }
    }

    /// Static equilibrium under `gravity` and `external` with the fixed nodes held where they
    /// are (see the module docs); leaves the body there, at rest, and returns the positions.
    ///
    /// Iterates `K d = f − f_int(x)`, `x += d` (`K` warped at the current rotations in
    /// corotational mode) until the relative residual is below 1e-10 or the update is at the
    /// rounding level of the positions (a stiff body whose load is tiny next to its internal
    /// forces cannot get below a residual of about `ε‖K‖‖x‖/‖f‖`). Linear mode: one
    /// factorisation, the second and later solves are iterative refinement.
    ///
    /// # Errors
    /// [`FemError::Unsupported`] for a body without fixed nodes, [`FemError::Singular`] if the
    /// supports leave a rigid motion free, [`FemError::NotConverged`] if the corotational
    /// iteration does not reach a relative residual of 1e-10 in 200 iterations (the state is
    /// then the last iterate).
    pub fn solve_static(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
    ) -> Result<StaticReport, FemError> {
        if !self.held.iter().any(|&h| h) {
            return Err(FemError::Unsupported);
        }
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.v_before.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.s.v_before2.iter_mut().for_each(|v| *v = [0.0; 3]);
        self.factor = Factor::Stale;
        let n_dof = self.system.n_dof;
        let mut load = vec![0.0; n_dof];
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                let ext = external.get(i).copied().unwrap_or([0.0; 3]);
                for c in 0..3 {
                    load[d as usize + c] = self.mass[i] * gravity[c] + ext[c];
                }
            }
        }
        let corotational = self.params.mode == FemMode::Corotational;
        let mut residual_vec = vec![0.0; n_dof];
        let mut r = self.static_residual(&load, &mut residual_vec);
        let mut reference = load.iter().map(|f| f * f).sum::<f64>().sqrt();
        if reference == 0.0 {
            reference = r;
        }
        let mut u_start = self.u.clone();
        let mut factored = false;
        let mut at_round_off = false;
        for iteration in 0..=STATIC_MAX_ITERATIONS {
            let residual = if reference > 0.0 { r / reference } else { 0.0 };
            if !residual.is_finite() {
                return Err(FemError::Singular);
            }
            if residual <= STATIC_TOLERANCE || at_round_off {
                return Ok(StaticReport {
                    positions: self.x.clone(),
                    iterations: iteration,
                    residual,
                });
            }
            if iteration == STATIC_MAX_ITERATIONS {
                return Err(FemError::NotConverged {
                    iterations: iteration,
                    residual,
                });
            }
            if !factored || corotational {
                self.assemble(0.0, corotational);
                self.system
                    .factorize(Precision::Double)
                    .map_err(|_| FemError::Singular)?;
                factored = true;
            }
            // The step d = K⁻¹ r, kept in `rhs`.
            self.s.rhs.copy_from_slice(&residual_vec);
            self.system.solve_in_place(&mut self.s.rhs);
            let slope0 = dot_n(&residual_vec, &self.s.rhs);
            u_start.copy_from_slice(&self.u);
            let mut alpha = 1.0;
            for _ in 0..STATIC_LINE_SEARCH {
                self.move_along_step(&u_start, alpha);
                r = self.static_residual(&load, &mut residual_vec);
                if !corotational {
                    break;
                }
                // Curvature (strong Wolfe) test on Π along d: its slope at α is −r(α)ᵀd.
                let slope = dot_n(&residual_vec, &self.s.rhs);
                if !(slope < -0.9 * slope0) {
                    break;
                }
                // Overshot the minimum along d: secant on the slope, kept in bounds.
                alpha *= (slope0 / (slope0 - slope)).clamp(0.1, 0.9);
            }
            let (mut step, mut size) = (0.0f64, 0.0f64);
            for (u, u0) in self.u.iter().zip(&u_start) {
                for c in 0..3 {
                    step = step.max((u[c] - u0[c]).abs());
                    size = size.max(u[c].abs());
                }
            }
            // An update at the rounding level of the displacements: what residual is left is
            // round-off in f_int, which no further iteration can remove.
            at_round_off = step <= STATIC_ROUND_OFF * size;
        }
        unreachable!("the loop returns on its last iteration")
    }

    /// `u = u_start + alpha · d` (`d` in `rhs`) on the free DOFs, positions refreshed.
    fn move_along_step(&mut self, u_start: &[[f64; 3]], alpha: f64) {
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    self.u[i][c] = u_start[i][c] + alpha * self.s.rhs[d as usize + c];
                    self.x[i][c] = self.rest[i][c] + self.u[i][c];
                }
            }
        }
    }

    /// `f − f_int(u)` on the free DOFs into `out`; returns its norm. Refreshes `force` and
    /// `grads` (the rotations) at the current state.
    fn static_residual(&mut self, load: &[f64], out: &mut [f64]) -> f64 {
        self.internal_forces();
        let mut r2 = 0.0;
        for (i, &d) in self.system.dof.iter().enumerate() {
            if d != NONE {
                for c in 0..3 {
                    let r = load[d as usize + c] + self.s.force[i][c];
                    out[d as usize + c] = r;
                    r2 += r * r;
                }
            }
        }
        r2.sqrt()
    }

    /// Fills `force` with `−f_int(x)` and (corotational) `grads` with the rotated gradients.
    fn internal_forces(&mut self) {
        self.s.force.iter_mut().for_each(|f| *f = [0.0; 3]);
        if self.params.mode == FemMode::Corotational {
            let (u, force) = (&self.u, &mut self.s.force);
            self.s
                .batch
                .corotational_forces(u, self.lambda, self.mu, force);
            return;
        }
        for el in &self.elements {
            let mut q = QUAT_IDENTITY;
            let (f, _) = element_forces(el, &self.u, FemMode::Linear, self.lambda, self.mu, &mut q);
            for (k, &n) in el.nodes.iter().enumerate() {
                self.s.force[n as usize] = add(self.s.force[n as usize], f[k]);
            }
        }
    }

    /// Assembles `mass_coef · M + K` into the system matrix, `K` warped (from `grads`) or at
    /// rest.
    fn assemble(&mut self, mass_coef: f64, warped: bool) {
        self.system.clear_with_mass(&self.mass, mass_coef);
        for (e, el) in self.elements.iter().enumerate() {
            let (vl, vm) = (el.volume * self.lambda, el.volume * self.mu);
            let g = if warped {
                self.s.batch.warped_gradients(e)
            } else {
                el.grad
            };
            self.system.add_element(e, &g, vl, vm);
        }
    }

    /// Assembles and factorises `K̃`, warped (from `grads`) or at rest.
    fn factor_dynamic(&mut self, warped: bool) -> Result<(), Failed> {
        let dt = self.params.dt;
        self.factor = Factor::Stale;
        self.assemble(1.0 / (dt * dt) + self.params.damping / (2.0 * dt), warped);
        // The corotational preconditioner is factorised in single precision (half the memory
        // traffic; CG in double precision makes up for it), falling back to double if rounding
        // breaks positive definiteness; direct solves use double.
        let single = self.params.mode == FemMode::Corotational
            && self.solver == CorotationalSolver::LaggedFactorPcg;
        if !(single && self.system.factorize(Precision::Single).is_ok()) {
            self.system
                .factorize(Precision::Double)
                .map_err(|_| Failed)?;
        }
        self.extra_iterations = 0;
        self.baseline_iterations = None;
        self.s.inv_key.iter_mut().for_each(|k| *k = NONE);
        if warped {
            self.factor = Factor::WarpedDynamic;
            self.s.node_rot_lag.copy_from_slice(&self.s.node_rot);
        } else {
            self.factor = Factor::RestDynamic;
            self.s
                .node_rot_lag
                .iter_mut()
                .for_each(|q| *q = QUAT_IDENTITY);
        }
        self.s
            .node_turn
            .iter_mut()
            .for_each(|t| *t = rotation::IDENTITY);
        Ok(())
    }

    /// Finds the tool's contact at the current positions (closest candidate triangle, as the
    /// mass-spring model does); if the tool presses, fills `contact_dir` with `c`.
    fn contact_setup(&mut self, c: &ToolContact<'_>) -> Option<Pressed> {
        if let Some(a) = c.anchor {
            return self.anchored_setup(c, a);
        }
        let mut best: Option<(u32, SurfaceHit)> = None;
        for &t in c.candidates {
            let Some(tri) = c.surface.get(t as usize) else {
                continue;
            };
            if tri.iter().any(|&k| k as usize >= self.x.len()) {
                continue;
            }
            if let Some(hit) =
                closest_on_surface(self.x.as_slice(), std::slice::from_ref(tri), c.tool.center)
            {
                if best.is_none_or(|(_, b)| hit.distance < b.distance) {
                    best = Some((t, hit));
                }
            }
        }
        let (t, hit) = best?;
        let depth = c.tool.depth(&hit);
        let force = c.tool.force_magnitude(depth);
        if !(depth > 0.0) || !(force > 0.0) {
            return None;
        }
        let tri = c.surface[t as usize];
        let dofs = tri.map(|k| self.system.dof[k as usize]);
        let normal = self.contact_normal(c.surface, t as usize, &hit);
        let p = Pressed::press(
            dofs,
            hit.barycentric,
            normal,
            depth,
            force,
            c.tool.max_stiffness(depth),
        );
        self.fill_contact_dirs(&p);
        Some(p)
    }

    /// The god-object's contact (see [`ToolAnchor`]): the spring between god-object and device
    /// that the hand feels, `−k g` on the tissue, with its stiffness in every direction
    /// (rank three: along the gap only, the sideways stiffness `F/|g|` of the turning spring
    /// would be explicit, and with the small gaps of soft tissue the point rings). A press
    /// may only push (`outward`), a grab pulls too. The Phong normal below is not used: the
    /// direction is the god-object's, so the tissue receives what the hand feels.
    fn anchored_setup(&mut self, c: &ToolContact<'_>, a: ToolAnchor) -> Option<Pressed> {
        let t = crate::model::anchored_touch(c, a, &self.x)?;
        let dofs = t.tri.map(|k| self.system.dof[k as usize]);
        // The tissue receives on_tissue = Σ −λ_a n_a with n_a = −e_a: λ = on_tissue.
        let p = Pressed {
            dofs,
            weights: t.weights,
            dirs: [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            m: 3,
            force: t.on_tissue,
            stiffness: t.stiffness,
            depth: t.depth,
            outward: (!a.grab).then_some(a.offset),
        };
        self.fill_contact_dirs(&p);
        Some(p)
    }

    /// Writes the contact vectors `c_a = (w₀ n_a, w₁ n_a, w₂ n_a)` into `contact_dir`.
    fn fill_contact_dirs(&mut self, p: &Pressed) {
        for a in 0..p.m {
            let v = &mut self.s.contact_dir[a];
            v.fill(0.0);
            for k in 0..3 {
                if p.dofs[k] != NONE {
                    for d in 0..3 {
                        v[p.dofs[k] as usize + d] = p.weights[k] * p.dirs[a][d];
                    }
                }
            }
        }
    }

    /// Direction of the tool's push on the contact point: the vertex normals of the triangle
    /// at the current positions (area-weighted means of the adjacent face normals),
    /// interpolated with the barycentric weights and normalised — a Phong normal.
    ///
    /// Why not the triangle's face normal: the contact law acts on the single closest triangle,
    /// and when a stiff tool on soft tissue has pushed a vertex into a pit, the closest
    /// triangle alternates between the pit's walls from one step to the next; with face
    /// normals the push alternates sideways with them and the tissue never settles (a
    /// period-2 limit cycle a large implicit step cannot damp). The interpolated normal is
    /// continuous across triangle edges, so a jump of the closest point between triangles that
    /// share the pressed vertex barely changes the force. On a flat patch it is the face
    /// normal. The depth, and so the force magnitude, is the shared law's. Falls back to the
    /// face normal if `surface` is not this body's surface or a normal degenerates.
    fn contact_normal(&self, surface: &[[u32; 3]], t: usize, hit: &SurfaceHit) -> [f64; 3] {
        if surface.len() != self.surface.len() || surface[t] != self.surface[t] {
            return hit.normal;
        }
        let mut n = [0.0; 3];
        for (k, &node) in surface[t].iter().enumerate() {
            let node = node as usize;
            let mut vn = [0.0; 3];
            for &f in &self.node_faces[self.node_face_ptr[node]..self.node_face_ptr[node + 1]] {
                let [a, b, c] = self.surface[f as usize].map(|i| self.x[i as usize]);
                vn = add(vn, cross(sub(b, a), sub(c, a)));
            }
            let len = norm(vn);
            if !(len > 0.0) {
                return hit.normal;
            }
            n = add(n, scale(vn, hit.barycentric[k] / len));
        }
        let len = norm(n);
        if len > 1e-6 && len.is_finite() {
            scale(n, 1.0 / len)
        } else {
            hit.normal
        }
    }

    fn blow_up(&mut self, cause: BlowUp) -> Result<ContactReport, BlowUp> {
        self.reset();
        Err(cause)
    }

    fn check(&mut self) -> Result<(), BlowUp> {
        let mut cause = None;
        for (x, v) in self.x.iter().zip(&self.v) {
            if !(x.iter().chain(v.iter()).all(|c| c.is_finite())) {
                cause = Some(BlowUp::NonFinite);
                break;
            }
            if dot(*v, *v) > RUNAWAY_SPEED * RUNAWAY_SPEED {
                cause = Some(BlowUp::Runaway);
                break;
            }
        }
        match cause {
            Some(c) => self.blow_up(c).map(|_| ()),
            None => Ok(()),
        }
    }
}

/// A solve that failed (non-finite numbers): the step becomes a blow-up.
#[derive(Debug, Clone, Copy)]
struct Failed;

impl From<system::NotPositiveDefinite> for Failed {
    fn from(_: system::NotPositiveDefinite) -> Failed {
        Failed
    }
}

/// `z = Q K̃⁻¹ Qᵀ r` with the system's factor and the per-node rotations `turn` (one 3×3 block
/// per free node, in DOF order).
fn turned_solve(system: &mut System, turn: &[element::Mat3], r: &[f64], z: &mut [f64]) {
    for (k, t) in turn.iter().enumerate() {
        let d = 3 * k;
        z[d..d + 3].copy_from_slice(&mat_t_vec(t, [r[d], r[d + 1], r[d + 2]]));
    }
    system.solve_in_place(z);
    for (k, t) in turn.iter().enumerate() {
        let d = 3 * k;
        let w = mat_vec(t, [z[d], z[d + 1], z[d + 2]]);
        z[d..d + 3].copy_from_slice(&w);
    }
}

/// `n nᵀ`.
fn outer(n: [f64; 3]) -> element::Mat3 {
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = n[r] * n[c];
        }
    }
    m
}

fn quat_dot(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

fn dot_n(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Elastic forces on an element's four nodes (`−f_int`) and the gradients its stiffness is
/// built from (`R bᵢ`, or `bᵢ` in linear mode). `q` is the rotation's warm start.
#[inline]
fn element_forces(
    el: &Element,
    u: &[[f64; 3]],
    mode: FemMode,
    lambda: f64,
    mu: f64,
    q: &mut [f64; 4],
) -> ([[f64; 3]; 4], [[f64; 3]; 4]) {
    let g = el.displacement_gradient(u);
    let mut out = [[0.0; 3]; 4];
    match mode {
        FemMode::Linear => {
            let s = stress(&g, lambda, mu);
            for k in 0..4 {
                out[k] = scale(mat_vec(&s, el.grad[k]), -el.volume);
            }
            (out, el.grad)
        }
        FemMode::Corotational => {
            let h = corotated_strain(&g, q);
            let r = quat_to_mat(q);
            let s = stress(&h, lambda, mu);
            let mut c = [[0.0; 3]; 4];
            for k in 0..4 {
                // −V R σ bᵢ, and R bᵢ for the warped stiffness.
                out[k] = scale(mat_vec(&r, mat_vec(&s, el.grad[k])), -el.volume);
                c[k] = mat_vec(&r, el.grad[k]);
            }
            (out, c)
        }
    }
}

/// `RᵀF − I` for the displacement gradient `g = F − I`, with `R` the rotation closest to `F`
/// (stored in `q`, warm-started from it), computed without cancellation.
#[inline]
fn corotated_strain(g: &element::Mat3, q: &mut [f64; 4]) -> element::Mat3 {
    let mut f = *g;
    for (k, row) in f.iter_mut().enumerate() {
        row[k] += 1.0;
    }
    closest_rotation(&f, q);
    let r = quat_to_mat(q);
    // RᵀF − I = Rᵀ ∇u + (R − I)ᵀ.
    let mut h = mat_t_mul(&r, g);
    let rm = quat_to_mat_minus_identity(q);
    for a in 0..3 {
        for b in 0..3 {
            h[a][b] += rm[b][a];
        }
    }
    h
}

fn validate(p: &FemParameters) -> Result<(), FemError> {
    let bad = |name, value, expected| {
        Err(FemError::InvalidParameter {
            name,
            value,
            expected,
        })
    };
    if !(p.young > 0.0 && p.young.is_finite()) {
        return bad("young", p.young, "a finite modulus > 0 Pa");
    }
    if !(p.poisson > -1.0 && p.poisson < 0.5) {
        return bad("poisson", p.poisson, "a ratio in (-1, 0.5)");
    }
    if !(p.density > 0.0 && p.density.is_finite()) {
        return bad("density", p.density, "a finite density > 0 kg/m^3");
    }
    if !(p.damping >= 0.0 && p.damping.is_finite()) {
        return bad("damping", p.damping, "a finite alpha >= 0 1/s");
    }
    if !(p.dt > 0.0 && p.dt.is_finite()) {
        return bad("dt", p.dt, "a finite time step > 0 s");
    }
    Ok(())
}

/// The tool on a triangle during one step: `m` contact vectors `c_a = (w₀n_a, w₁n_a, w₂n_a)`
/// on its nodes — one along the normal for a press, three (the axes) for a grab.
#[derive(Debug, Clone, Copy)]
struct Pressed {
    /// First DOF of each triangle node, or `NONE` if held.
    dofs: [u32; 3],
    /// Barycentric weights of the contact point.
    weights: [f64; 3],
    /// Unit directions `n_a`; the tissue receives `−λ_a n_a`.
    dirs: [[f64; 3]; 3],
    /// Directions in use: 1 (press) or 3 (grab).
    m: usize,
    /// `λ_a` at the start of the step, N.
    force: [f64; 3],
    /// `dF/d depth`, N/m (the same along every direction).
    stiffness: f64,
    /// Press: penetration at the start of the step; god-object: the gap's length, m.
    depth: f64,
    /// For a contact that may only push: its outward direction (the force on the tissue must
    /// point against it). `None`: a grab, which pulls too.
    outward: Option<[f64; 3]>,
}

impl Pressed {
    /// A press along `normal` with force `force` at `depth`.
    fn press(
        dofs: [u32; 3],
        weights: [f64; 3],
        normal: [f64; 3],
        depth: f64,
        force: f64,
        stiffness: f64,
    ) -> Pressed {
        Pressed {
            dofs,
            weights,
            dirs: [normal, [0.0; 3], [0.0; 3]],
            m: 1,
            force: [force, 0.0, 0.0],
            stiffness,
            depth,
            outward: Some(normal),
        }
    }

    /// The force on the tissue for contact forces `λ`.
    fn on_tissue(&self, lambda: [f64; 3]) -> [f64; 3] {
        let mut f = [0.0; 3];
        for a in 0..self.m {
            f = add(f, scale(self.dirs[a], -lambda[a]));
        }
        f
    }

    /// Whether forces `λ` are allowed: a press must push.
    fn admissible(&self, lambda: [f64; 3]) -> bool {
        match self.outward {
            None => true,
            Some(o) => dot(self.on_tissue(lambda), o) < 0.0,
        }
    }

    /// What the step applied: forces `λ_a` along `−n_a`; the press's depth grown by `c₀ᵀd`
    /// (a grab's gap: `|λ| / k'`).
    fn report(&self, lambda: [f64; 3], d: &[f64]) -> ContactReport {
        let f = self.on_tissue(lambda);
        let depth = if self.m == 3 {
            if self.stiffness > 0.0 {
                norm(lambda) / self.stiffness
            } else {
                self.depth
            }
        } else {
            (self.depth + self.dot(0, d)).max(0.0)
        };
        ContactReport {
            force_on_tissue: f,
            depth,
        }
    }

    /// `c_aᵀ v` for a DOF vector `v`.
    fn dot(&self, a: usize, v: &[f64]) -> f64 {
        let mut s = 0.0;
        for k in 0..3 {
            let d = self.dofs[k];
            if d != NONE {
                let d = d as usize;
                s += self.weights[k] * dot(self.dirs[a], [v[d], v[d + 1], v[d + 2]]);
            }
        }
        s
    }
}

/// Solves the leading `m × m` block of `a x = b` (m ≤ 3) by Gaussian elimination with partial
/// pivoting; `None` if singular or not finite.
fn solve_small(mut a: [[f64; 3]; 3], mut b: [f64; 3], m: usize) -> Option<[f64; 3]> {
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if !(a[piv][col].abs() > 1e-300) {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..m {
            let f = a[row][col] / a[col][col];
            for k in col..m {
                a[row][k] -= f * a[col][k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..m).rev() {
        let mut s = b[row];
        for k in row + 1..m {
            s -= a[row][k] * x[k];
        }
        x[row] = s / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}
