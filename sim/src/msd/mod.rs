//! Mass-spring-damper model (thesis §4.1, eq. 4.2) with five integrators: the explicit schemes
//! of the thesis' ch. 3 study (explicit and symplectic Euler, Verlet, RK4) and implicit Euler.
//!
//! # The model
//! Springs on the tetrahedron edges (every spring the same stiffness `k`, rest length = the
//! mesh's edge length), lumped nodal masses, viscous damping `γ` per node, fixed nodes, gravity,
//! external nodal loads and the tool's penalty contact:
//!
//! ```text
//! M ẍ = f_spring(x) − γ ẋ + M g + f_ext + f_tool(x)          (eq. 4.2)
//! ```
//!
//! Fixed nodes (and nodes without mass, e.g. unused nodes of a mesh with density-lumped
//! masses) never move: their inverse mass is zero for the explicit integrators and they are
//! eliminated from the implicit system.
//!
//! # Integrators
//! | [`Integrator`] | order | stable sub-step (undamped spring, `ω² = k/m`) | force evaluations per sub-step |
//! |---|---|---|---|
//! | `ExplicitEuler` | 1 | never undamped (energy × `1 + (hω)²` per step); damped: `h < γ/k = 2ζ/ω` (underdamped), `h < 2m/γ` | 1 |
//! | `SymplecticEuler` | 1 | `hω < 2` (`(hω)² + 2hγ/m ≤ 4` with damping) | 1 |
//! | `Verlet` | 2 | `hω < 2` | 1 (+1 per step) |
//! | `Rk4` | 4 | `hω < 2√2 ≈ 2.828` (imaginary axis); pure damping `hγ/m < 2.785` (real axis) | 4 |
//! | `ImplicitEuler` | 1 | unconditional (A- and L-stable) | 1 + Jacobian assembly + sparse `LLᵀ` refactorisation + solve |
//!
//! - **Explicit (forward) Euler**: `x += h v; v += h a(x, v)`, both from the old state.
//! - **Symplectic (semi-implicit) Euler**: `v += h a(x, v); x += h v_new`.
//! - **Verlet**: velocity Verlet (kick–drift–kick), which produces the same positions as
//!   Störmer–Verlet (thesis eq. 3.8) but carries the velocity the damping term needs. Damping is
//!   explicit in the first half-kick and implicit in the second (`v_{n+1} = (v_{½} + ½h F/m) /
//!   (1 + ½hγ/m)`), the adjoint pair of Euler half-steps, so the step stays symmetric and
//!   second order with damping; the position-only force at the end of a sub-step is reused at
//!   the start of the next (one spring evaluation per sub-step, one more per step because loads
//!   may change between steps).
//! - **RK4**: classic four-stage Runge–Kutta (thesis eq. 3.4) on the first-order system
//!   `(x, v)`, with preallocated stage buffers.
//! - **Implicit Euler**: linearised backward Euler (Baraff & Witkin 1998, one Newton step):
//!   `(M + hD + h²K(x)) Δv = h (f(x) − D v − h K(x) v)`, `v += Δv`, `x += h v`, with `D = γI` and
//!   `K = −∂f/∂x` the spring Jacobian; see "Implicit Euler: matrix and solver" below.
//!
//! The limits in the table are for a single undamped spring; [`Integrator::order`] and
//! [`Integrator::stability_limit`] return them, and `sim/tests/physics/msd_integrators.rs` checks them:
//! the observed convergence order, energy behaviour, and the blow-up just above each limit.
//!
//! # Sub-stepping ([`SubstepPolicy`])
//! A body advances by its configured `dt` per [`MassSpring::step`]. With
//! [`SubstepPolicy::Auto`] (the default) an explicit integrator splits `dt` into as many equal
//! sub-steps as its stability bound requires, so a scene's thesis time step (often far above the
//! bound for light, stiff meshes) never makes the body explode; implicit Euler takes one
//! sub-step. [`SubstepPolicy::Fixed`] takes exactly the given number of sub-steps, whatever the
//! integrator: `Fixed(1)` is the raw integrator at the given step, which the thesis ch. 3 study
//! and the stability tests need.
//!
//! The automatic bound, per free node `i`: `ω_i² = 4 Σ_j k / m_i` (Gershgorin on `M⁻¹K`, each
//! spring contributing at most `2k` to a row in any direction, twice over for stretched springs)
//! and `c_i = γ / m_i`; with a safety factor of 2 below each limit,
//! `h ≤ ½ · min(L_ω / ω_i, L_c / c_i)` where `(L_ω, L_c)` is `(2, 2)` for symplectic Euler and
//! Verlet and `(2√2, 2.785)` for RK4; explicit Euler uses `h ≤ ½ · min(c_i / ω_i², 2 / c_i)` (its
//! disc-shaped stability region only contains damped modes). Without damping explicit Euler has
//! no stable step at all: `Auto` then takes symplectic Euler's sub-step, the energy grows by
//! `1 + (hω)²` per sub-step and the blow-up check eventually resets the body.
//!
//! # Tool contact
//! The tool's penalty spring can be far stiffer than the tissue's springs on light nodes
//! (300 N/m on milligram nodes), so it is never part of the sub-step bound (the cost per step
//! must not jump when the tool touches):
//! - explicit integrators: at every force evaluation the normal component of the force on each of
//!   the three contact nodes is replaced by its linearised backward-Euler value for the sub-step
//!   `h` (`f_n → (f_n − h K v_n) / (1 + h² K / m)`, `K = w² dF/dd` for barycentric weight `w`).
//!   Along the normal the node then behaves like a spring-damper with `h²K'/m < 1` and
//!   `hc'/m < 1`, inside every explicit method's stability region, and the static equilibrium is
//!   unchanged (`v = 0`, `f_n = 0` is still a fixed point);
//! - implicit Euler: the exact contact Jacobian `dF/dd · (w wᵀ) ⊗ (n nᵀ)` (rank one, positive
//!   semi-definite) is added to the system matrix over the three nodes of the touched triangle;
//!   they are joined by mesh edges, so the sparsity pattern already has their blocks.
//!
//! The god-object's press with the linear law comes as a contact patch over the tool's
//! footprint ([`crate::patch`]) instead of the anchor's one point; then the tool acts through
//! the patch alone, as hard unilateral constraints:
//! - explicit integrators: after every sub-step without the tool, the points' gaps are linear
//!   in their forces through the sub-step's compliance `h² M⁻¹` (lumped, diagonal), and the
//!   complementarity problem's forces move the nodes by `h² M⁻¹ C λ` and change their
//!   velocities by `h M⁻¹ C λ` (`explicit::ExplicitPatch`); the report is the last sub-step's;
//! - implicit Euler: the same with the step's factor of `A` (`implicit.rs`).
//!
//! Either way the report carries the proxy where the patch balanced, which the god-object rests
//! at. The [`ContactReport`] of a point contact is evaluated on the positions at the end of the
//! step, the same surface the haptic loop renders against.
//!
//! # Implicit Euler: matrix and solver
//! `K(x)` is assembled per spring from `k [u uᵀ + max(0, 1 − L/l) (I − u uᵀ)]` (`u` the unit
//! spring direction, `l` its length, `L` its rest length): the axial term plus the geometric term,
//! *filtered* (Choi & Ko 2002) so a compressed spring contributes no negative stiffness. With
//! that, `K` is positive semi-definite and `A = M + hγI + h²K` is symmetric positive definite.
//! Fixed nodes are eliminated by dropping their rows and columns (their velocity is zero), which
//! keeps `A` symmetric. `A`'s lower triangle is stored in compressed columns with a fixed pattern
//! (3×3 blocks per free node and per spring between free nodes) whose value slots are
//! precomputed, so assembly writes in place.
//!
//! The system is solved with faer's sparse Cholesky (`LLᵀ`) through the crate's sparse SPD
//! solver (`solve/sparse.rs`): the symbolic analysis (AMD ordering, elimination tree,
//! supernodal structure) runs once per body, and each step refactorises numerically into the
//! same factor buffer with a preallocated workspace.
//!
//! Why this solver: measured against a warm-started Jacobi-preconditioned conjugate gradient
//! (same matrix and right-hand side, relative residual 1e-8) on the shipped meshes with their
//! scene parameters (gravity on the cylinder), the tool pressed 1 mm into the top of each body,
//! release build, one core of the 2-core Xeon CI machine, medians over 100–180 steps:
//!
//! | mesh (k N/m, ρ kg/m³, dt s) | free dofs | entries of `A` (lower) | `LLᵀ` supernodal: factor + solve | `LLᵀ` simplicial | PCG |
//! |---|---|---|---|---|---|
//! | liver (2.7, 10, 0.01) | 1578 | 26 178 | 1.09 + 0.10 ms | 4.81 + 0.15 ms | 2.89 ms (86 it.) |
//! | spleen (1.8, 10, 0.01) | 672 | 10 938 | 0.33 + 0.03 ms | 1.06 + 0.04 ms | 1.52 ms (112 it.) |
//! | stomach (2.2, 10, 0.01) | 873 | 14 256 | 0.45 + 0.05 ms | 1.47 + 0.06 ms | 1.74 ms (96 it.) |
//! | pancreas (1.5, 10, 0.01) | 657 | 10 350 | 0.24 + 0.03 ms | 0.62 + 0.03 ms | 1.62 ms (133 it.) |
//! | cylinder (700, 120, 0.02) | 714 | 13 047 | 0.45 + 0.04 ms | 1.77 + 0.06 ms | 1.60 ms (103 it.) |
//!
//! Assembly adds 30–80 µs. The direct solve is 2.5–6× faster on every organ mesh, its cost does
//! not depend on conditioning (light nodes under the stiff tool need ~100 CG iterations) nor on
//! a tolerance, and it is exact; the supernodal variant is forced because faer's automatic choice
//! picks the simplicial one for the smaller meshes, 3–4× slower here. (PCG only wins on heavy,
//! well-conditioned bodies, e.g. the thesis' beam with 0.1 kg nodes: 9 iterations, 0.36 ms
//! against 1.17 ms.)
//!
//! # Real-time properties
//! `step` allocates nothing after the first step: every buffer is owned by the body and sized
//! at construction. Non-finite values or a node faster than [`RUNAWAY_SPEED`] reset the body to
//! rest and return the [`BlowUp`] cause. Stepping is deterministic bit for bit (sequential
//! loops in a fixed order, a fixed fill-reducing ordering, no parallelism).

mod explicit;
mod forces;
mod implicit;

use crate::contact::{add, dot, norm, scale, sub};
use crate::interaction::{BlowUp, ContactReport, ContactSpring, ToolContact, RUNAWAY_SPEED};
use crate::mesh::TetMesh;

use forces::{Network, Spring};
use implicit::ImplicitSolver;

/// Parameters of a mass-spring body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MsdParameters {
    /// Spring stiffness, N/m (every edge the same, as in the thesis).
    pub stiffness: f64,
    /// How nodal masses are found.
    pub mass: NodeMass,
    /// Viscous damping γ per node, N·s/m (eq. 4.2).
    pub damping: f64,
    /// Time step the body advances by per step, s.
    pub dt: f64,
    /// Time integration scheme.
    pub integrator: Integrator,
}

/// Nodal masses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NodeMass {
    /// Lumped from density (kg/m³): each tetrahedron gives a quarter of its mass to each node.
    Density(f64),
    /// Every node has this mass, kg (thesis ch. 3).
    PerNode(f64),
}

/// Time integration scheme (see the [module docs](self) for each one's order, stability limit
/// and cost); a scene's `[body.msd] integrator` (`"explicit-euler"`, `"symplectic-euler"`,
/// `"verlet"`, `"rk4"`, `"implicit-euler"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Integrator {
    /// Forward Euler: position and velocity both advanced from the old state.
    ExplicitEuler,
    /// Semi-implicit Euler: velocity first, then position with the new velocity.
    #[default]
    SymplecticEuler,
    /// Velocity Verlet (positions identical to Störmer–Verlet), damping handled symmetrically.
    Verlet,
    /// Classic fourth-order Runge–Kutta.
    Rk4,
    /// Linearised backward Euler with a sparse direct solve.
    ImplicitEuler,
}

impl Integrator {
    /// Every integrator, in the order of the thesis' study (plus implicit Euler).
    pub const ALL: [Integrator; 5] = [
        Integrator::ExplicitEuler,
        Integrator::SymplecticEuler,
        Integrator::Verlet,
        Integrator::Rk4,
        Integrator::ImplicitEuler,
    ];

    /// Global order of accuracy.
    pub fn order(self) -> u32 {
        match self {
            Integrator::ExplicitEuler | Integrator::SymplecticEuler | Integrator::ImplicitEuler => {
                1
            }
            Integrator::Verlet => 2,
            Integrator::Rk4 => 4,
        }
    }

    /// Largest stable `h ω` for an undamped linear spring: `Some(0.0)` for explicit Euler (never
    /// stable without damping), `None` for implicit Euler (unconditionally stable).
    pub fn stability_limit(self) -> Option<f64> {
        match self {
            Integrator::ExplicitEuler => Some(0.0),
            Integrator::SymplecticEuler | Integrator::Verlet => Some(2.0),
            Integrator::Rk4 => Some(2.0 * std::f64::consts::SQRT_2),
            Integrator::ImplicitEuler => None,
        }
    }

    /// Whether the scheme is explicit (no linear solve).
    pub fn is_explicit(self) -> bool {
        self != Integrator::ImplicitEuler
    }
}

/// How a step of `dt` is split into sub-steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SubstepPolicy {
    /// As many sub-steps as the integrator's stability bound requires (1 for implicit Euler).
    #[default]
    Auto,
    /// Exactly this many sub-steps (0 is taken as 1); `Fixed(1)` is the raw integrator.
    Fixed(usize),
}

/// Upper bound on automatic sub-steps per step: beyond it a body is too stiff for its
/// integrator at this `dt`, and the blow-up check takes over.
const MAX_SUBSTEPS: usize = 100_000;

/// Per-step scratch of the explicit integrators. Sized at construction (the RK4 stage buffers
/// only for RK4); never reallocated.
#[derive(Debug, Clone, Default)]
struct Scratch {
    /// Filled by `Network::conservative_forces` (+ contact) at every force evaluation; read by
    /// the integrator's update loop right after. Verlet keeps in it the position-only force at
    /// the end of a sub-step for the next sub-step's first half-kick.
    force: Vec<[f64; 3]>,
    /// Verlet: `force` plus the contact load, filled before each half-kick and read by it (the
    /// contact part depends on velocity, so it cannot stay in the cached `force`).
    total: Vec<[f64; 3]>,
    /// RK4: stage positions and velocities, filled from `x`, `v` and the previous stage's
    /// derivative, read by the next force evaluation.
    xs: Vec<[f64; 3]>,
    vs: Vec<[f64; 3]>,
    /// RK4: weighted sums `k1 + 2k2 + 2k3 + k4` of the position and velocity derivatives,
    /// accumulated stage by stage, read by the final update.
    acc_x: Vec<[f64; 3]>,
    acc_v: Vec<[f64; 3]>,
}

/// A mass-spring body.
#[derive(Debug, Clone)]
pub struct MassSpring {
    params: MsdParameters,
    policy: SubstepPolicy,
    /// Sub-steps per step, from `policy`.
    substeps: usize,
    /// Sub-steps per step the automatic stability bound asks for (kept for policy changes).
    auto_substeps: usize,
    /// Springs, masses, rest shape: fixed after construction.
    net: Network,
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    stepper: Stepper,
}

/// How a body advances, chosen once from its integrator.
#[derive(Debug, Clone)]
enum Stepper {
    /// One of the explicit integrators and its buffers.
    Explicit {
        integrate: explicit::Integrate,
        scratch: Scratch,
        patch: Box<explicit::ExplicitPatch>,
    },
    /// The implicit Euler system and its factorisation.
    Implicit(Box<ImplicitSolver>),
}

impl MassSpring {
    /// The last step's patch solve, for the reports of its tools (presses and grabs).
    pub(crate) fn patch_solve(&mut self) -> &mut crate::patch::PatchSolve {
        match &mut self.stepper {
            Stepper::Implicit(solver) => &mut solver.patch,
            Stepper::Explicit { patch, .. } => &mut patch.solve,
        }
    }

    /// The last step's contact patch problem (its forces and the factor of its active set);
    /// meaningful only when the step's report came from a patch (it has a proxy). For the
    /// reports of a patch's other tools ([`crate::patch::report`]).
    pub fn patch_solution(&mut self) -> &mut crate::patch::Lcp {
        match &mut self.stepper {
            Stepper::Implicit(solver) => solver.patch_solution(),
            Stepper::Explicit { patch, .. } => patch.solution(),
        }
    }

    /// Builds the model on `mesh` (rest shape = the mesh's nodes; fixed = `mesh.fixed`).
    pub fn new(mesh: &TetMesh, params: MsdParameters) -> MassSpring {
        let n = mesh.nodes.len();
        let mut mass = vec![0.0; n];
        match params.mass {
            NodeMass::PerNode(m) => mass.iter_mut().for_each(|x| *x = m),
            NodeMass::Density(rho) => {
                for (i, t) in mesh.tets.iter().enumerate() {
                    let share = rho * mesh.tet_volume(i) / 4.0;
                    for &k in t {
                        mass[k as usize] += share;
                    }
                }
            }
        }
        MassSpring::build(mesh.nodes.clone(), mesh.edges(), mass, &mesh.fixed, params)
    }

    /// Builds a body from an explicit spring network instead of a tetrahedral mesh (thesis ch. 3
    /// style, and 1-DOF test systems): `nodes` is the rest shape, `springs` the node pairs
    /// (order and repeats do not matter), `fixed` the nodes that never move. There are no
    /// volumes, so [`NodeMass::Density`] gives massless nodes, which never move either: use
    /// [`NodeMass::PerNode`].
    ///
    /// # Panics
    /// If a spring or fixed node index is out of range, or a spring joins a node to itself.
    pub fn from_springs(
        nodes: Vec<[f64; 3]>,
        springs: &[[u32; 2]],
        fixed: &[u32],
        params: MsdParameters,
    ) -> MassSpring {
        let n = nodes.len();
        let mut edges: Vec<[u32; 2]> = springs
            .iter()
            .map(|&[a, b]| {
                assert!(
                    (a as usize) < n && (b as usize) < n && a != b,
                    "bad spring [{a}, {b}] for {n} nodes"
                );
                [a.min(b), a.max(b)]
            })
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let m = match params.mass {
            NodeMass::PerNode(m) => m,
            NodeMass::Density(_) => 0.0,
        };
        MassSpring::build(nodes, edges, vec![m; n], fixed, params)
    }

    /// Common construction: `edges` sorted, unique, `[lo, hi]`.
    fn build(
        nodes: Vec<[f64; 3]>,
        edges: Vec<[u32; 2]>,
        mass: Vec<f64>,
        fixed: &[u32],
        params: MsdParameters,
    ) -> MassSpring {
        let n = nodes.len();
        let mut inv_mass: Vec<f64> = mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        for &f in fixed {
            assert!(
                (f as usize) < n,
                "fixed node {f} out of range for {n} nodes"
            );
            inv_mass[f as usize] = 0.0;
        }
        let springs: Vec<Spring> = edges
            .into_iter()
            .map(|[a, b]| Spring {
                a,
                b,
                rest: norm(sub(nodes[b as usize], nodes[a as usize])),
            })
            .collect();
        let net = Network {
            springs,
            stiffness: params.stiffness,
            damping: params.damping,
            mass,
            inv_mass,
            rest: nodes.clone(),
        };
        let auto_substeps = auto_substeps(&params, &net);
        let zero = || vec![[0.0; 3]; n];
        let explicit = |integrate: explicit::Integrate, scratch| Stepper::Explicit {
            integrate,
            scratch,
            patch: Box::new(explicit::ExplicitPatch::new()),
        };
        let with_force = || Scratch {
            force: zero(),
            ..Scratch::default()
        };
        let stepper = match params.integrator {
            Integrator::ExplicitEuler => explicit(explicit::explicit_euler, with_force()),
            Integrator::SymplecticEuler => explicit(explicit::symplectic_euler, with_force()),
            Integrator::Verlet => explicit(
                explicit::verlet,
                Scratch {
                    total: zero(),
                    ..with_force()
                },
            ),
            Integrator::Rk4 => explicit(
                explicit::rk4,
                Scratch {
                    xs: zero(),
                    vs: zero(),
                    acc_x: zero(),
                    acc_v: zero(),
                    ..with_force()
                },
            ),
            Integrator::ImplicitEuler => Stepper::Implicit(Box::new(ImplicitSolver::new(&net))),
        };
        MassSpring {
            params,
            policy: SubstepPolicy::Auto,
            substeps: auto_substeps,
            auto_substeps,
            net,
            x: nodes,
            v: zero(),
            stepper,
        }
    }

    /// Chooses how steps are split into sub-steps (default [`SubstepPolicy::Auto`]).
    pub fn set_substep_policy(&mut self, policy: SubstepPolicy) {
        self.policy = policy;
        self.substeps = match policy {
            SubstepPolicy::Auto => self.auto_substeps,
            SubstepPolicy::Fixed(n) => n.max(1),
        };
    }

    /// Builder form of [`set_substep_policy`](Self::set_substep_policy).
    #[must_use]
    pub fn with_substep_policy(mut self, policy: SubstepPolicy) -> MassSpring {
        self.set_substep_policy(policy);
        self
    }

    /// The current sub-step policy.
    pub fn substep_policy(&self) -> SubstepPolicy {
        self.policy
    }

    /// The body's parameters.
    pub fn params(&self) -> &MsdParameters {
        &self.params
    }
    /// The integrator in use.
    pub fn integrator(&self) -> Integrator {
        self.params.integrator
    }
    /// Node positions, m.
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }
    /// Node velocities, m/s.
    pub fn velocities(&self) -> &[[f64; 3]] {
        &self.v
    }
    /// Nodal masses, kg.
    pub fn masses(&self) -> &[f64] {
        &self.net.mass
    }
    /// The body's time step, s.
    pub fn dt(&self) -> f64 {
        self.params.dt
    }
    /// Sub-steps per step (from the [`SubstepPolicy`]).
    pub fn substeps(&self) -> usize {
        self.substeps
    }
    /// Springs (edges).
    pub fn spring_count(&self) -> usize {
        self.net.springs.len()
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.net.mass)
            .map(|(v, m)| 0.5 * m * dot(*v, *v))
            .sum()
    }

    /// Elastic energy stored in the springs, `Σ ½ k (l − L)²`, J.
    pub fn elastic_energy(&self) -> f64 {
        self.net.elastic_energy(&self.x)
    }

    /// Largest nodal speed, m/s.
    pub fn max_speed(&self) -> f64 {
        self.v.iter().map(|v| norm(*v)).fold(0.0, f64::max)
    }

    /// `K u`: the springs' stiffness at rest applied to a displacement field `u` (m, one per
    /// node), N. At rest every spring is slack-free and unstretched, so only its axial stiffness
    /// acts: a spring `a–b` with rest direction `e` adds `k e eᵀ (u_a − u_b)` to `a` and the
    /// opposite to `b`. For reduced models built on this one (`crate::lop`). Allocates.
    ///
    /// # Panics
    /// If `u` does not have one entry per node.
    pub fn rest_stiffness_product(&self, u: &[[f64; 3]]) -> Vec<[f64; 3]> {
        assert_eq!(u.len(), self.x.len(), "one displacement per node");
        let mut out = vec![[0.0; 3]; u.len()];
        let k = self.net.stiffness;
        for s in &self.net.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let d = sub(self.net.rest[b], self.net.rest[a]);
            let l = norm(d);
            if !(l > 0.0) {
                continue;
            }
            let e = scale(d, 1.0 / l);
            let f = scale(e, k * dot(e, sub(u[a], u[b])));
            out[a] = add(out[a], f);
            out[b] = sub(out[b], f);
        }
        out
    }

    /// Whether node `i` never moves (fixed, or massless).
    pub fn is_held(&self, i: usize) -> bool {
        !(self.net.inv_mass[i] > 0.0)
    }

    /// Back to the rest shape, at rest.
    pub fn reset(&mut self) {
        self.x.copy_from_slice(&self.net.rest);
        self.v.iter_mut().for_each(|v| *v = [0.0; 3]);
    }

    /// Sets positions (m) and velocities (m/s) of every node that can move; fixed and massless
    /// nodes stay at rest where they are. For state transfer between models and for tests.
    ///
    /// # Panics
    /// If either slice's length differs from the node count.
    pub fn set_state(&mut self, positions: &[[f64; 3]], velocities: &[[f64; 3]]) {
        assert_eq!(positions.len(), self.x.len(), "positions: one per node");
        assert_eq!(velocities.len(), self.v.len(), "velocities: one per node");
        for i in 0..self.x.len() {
            if self.net.inv_mass[i] > 0.0 {
                self.x[i] = positions[i];
                self.v[i] = velocities[i];
            }
        }
    }

    /// Advances by `dt` under `gravity` (m/s²), the nodal loads `external` (N, one per node;
    /// missing entries count as zero) and the tool. On a blow-up the body is reset to rest and
    /// the cause returned; nothing non-finite ever stays in the state. Allocation-free.
    pub fn step(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
    ) -> Result<ContactReport, BlowUp> {
        self.step_colliding(gravity, external, contact, &[])
    }

    /// [`MassSpring::step`] with organ-to-organ contact springs: implicit in the implicit
    /// integrator (their stiffness joins the system matrix, like the tool's), normal-implicit in
    /// the explicit ones (see [`ContactSpring`]).
    pub fn step_colliding(
        &mut self,
        gravity: [f64; 3],
        external: &[[f64; 3]],
        contact: Option<&ToolContact<'_>>,
        springs: &[ContactSpring],
    ) -> Result<ContactReport, BlowUp> {
        let h = self.params.dt / self.substeps as f64;
        let loads = forces::Loads {
            gravity,
            external,
            contact,
            springs,
        };
        let state = explicit::State {
            x: &mut self.x,
            v: &mut self.v,
        };
        match &mut self.stepper {
            Stepper::Explicit {
                integrate,
                scratch,
                patch,
            } => match contact.and_then(|c| c.patch) {
                // The tool acts through its patch alone, after every sub-step.
                Some(p) => {
                    let free = forces::Loads {
                        contact: None,
                        ..loads
                    };
                    patch.step(
                        *integrate,
                        &self.net,
                        state,
                        scratch,
                        &free,
                        &p,
                        h,
                        self.substeps,
                    );
                }
                None => integrate(&self.net, state, scratch, &loads, h, self.substeps),
            },
            Stepper::Implicit(solver) => {
                let solved =
                    (0..self.substeps).all(|_| solver.step(&self.net, state.x, state.v, &loads, h));
                if !solved {
                    self.reset();
                    return Err(BlowUp::NonFinite);
                }
            }
        }
        self.check()?;
        if contact.is_some_and(|c| c.patch.is_some()) {
            let report = match &self.stepper {
                Stepper::Implicit(solver) => solver.patch_report(),
                Stepper::Explicit { patch, .. } => patch.report,
            };
            return Ok(report.unwrap_or_default());
        }
        Ok(contact.map_or_else(ContactReport::default, |c| {
            forces::touch(c, &self.x).map_or_else(ContactReport::default, |t| ContactReport {
                force_on_tissue: t.on_tissue,
                depth: t.depth,
                proxy: None,
                response: None,
            })
        }))
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
            Some(c) => {
                self.reset();
                Err(c)
            }
            None => Ok(()),
        }
    }
}

/// Sub-steps per step the integrator's stability bound requires (see the module docs).
fn auto_substeps(params: &MsdParameters, net: &Network) -> usize {
    let limits = match params.integrator {
        Integrator::ImplicitEuler => return 1,
        Integrator::ExplicitEuler => None,
        Integrator::SymplecticEuler | Integrator::Verlet => Some((2.0, 2.0)),
        Integrator::Rk4 => Some((2.0 * std::f64::consts::SQRT_2, 2.785)),
    };
    let mut ksum = vec![0.0; net.mass.len()];
    for s in &net.springs {
        ksum[s.a as usize] += params.stiffness;
        ksum[s.b as usize] += params.stiffness;
    }
    let gamma = params.damping;
    let mut h_max = f64::INFINITY;
    for (k, &w) in ksum.iter().zip(&net.inv_mass) {
        if w == 0.0 {
            continue;
        }
        let omega2 = 4.0 * k * w;
        let c = gamma * w;
        let h = match limits {
            Some((l_omega, l_c)) => {
                let mut h = f64::INFINITY;
                if omega2 > 0.0 {
                    h = h.min(l_omega / omega2.sqrt());
                }
                if c > 0.0 {
                    h = h.min(l_c / c);
                }
                h
            }
            None if c > 0.0 => {
                let mut h = 2.0 / c;
                if omega2 > 0.0 {
                    h = h.min(c / omega2);
                }
                h
            }
            // Undamped explicit Euler: nothing is stable; take symplectic Euler's step.
            None if omega2 > 0.0 => 2.0 / omega2.sqrt(),
            None => f64::INFINITY,
        };
        h_max = h_max.min(0.5 * h);
    }
    if !h_max.is_finite() || !(params.dt > 0.0) {
        return 1;
    }
    ((params.dt / h_max).ceil() as usize).clamp(1, MAX_SUBSTEPS)
}
