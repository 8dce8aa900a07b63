//! Heat and burns (thesis §5.3): electrocautery heats the touched point, heat diffuses through
//! the organ, leaves to the air at its surface and crosses into organs that touch; tissue that
//! gets hotter than its coagulation temperature is burned. Units: °C, W, J, SI otherwise.
//!
//! # Model
//!
//! The heat equation with a source, `ρc ∂T/∂t = ∇·(k∇T) + q` — eq. 5.4, `∂T/∂t = α∇²T` with
//! the diffusivity `α = k/(ρc)`, written so that energy has units — with per-body conductivity
//! `k` (W/m/K), specific heat `c` (J/kg/K) and density `ρ` (kg/m³), and a convective (Robin)
//! condition `−k ∂T/∂n = h (T − T_air)` on the surface (`h` in W/m²/K; `h = 0` insulates).
//!
//! The thesis' update (eq. 5.5) weights neighbours by squared edge lengths and omits κ on the
//! neighbour sum: heat is neither conserved nor measured in consistent units, and it is stable
//! only for small κ. It is replaced here by the standard finite-element discretisation.
//!
//! # Discretisation
//!
//! Linear tetrahedra (the same elements and gradients as [`crate::fem`]), on the mesh's rest
//! geometry (deformations of a few millimetres do not matter to heat):
//!
//! - **Conductance** `K_ij = Σₑ k Vₑ ∇Nᵢ·∇Nⱼ`, W/K: weights from geometry, symmetric positive
//!   semi-definite, and every row sums to zero (`Σᵢ ∇Nᵢ = 0` in each element), so conduction
//!   only moves heat around.
//! - **Capacity** lumped, `Cᵢ = Σₑ ρc Vₑ/4`, J/K.
//! - **Air**: a lumped Robin term, `Hᵢ = h Aᵢ` with `Aᵢ` a third of the area of each surface
//!   triangle at node `i`; the node loses `Hᵢ (Tᵢ − T_air)` W. `Σ Hᵢ = h A` exactly.
//! - **Sources** `Qᵢ`, W: [`HeatBody::heat_point`] spreads the cautery power over the touched
//!   triangle's nodes by the contact point's barycentric weights.
//!
//! **Backward Euler**, solved for the increment:
//!
//! ```text
//! (C/Δt + K + H) ΔT = Q + H (T_air − T) − K T,      T⁺ = T + ΔT
//! ```
//!
//! - *Conservative.* Summing the rows (`1ᵀK = 0`): `Σ Cᵢ T⁺ᵢ = Σ Cᵢ Tᵢ + Δt ΣQᵢ −
//!   Δt Σ Hᵢ (T⁺ᵢ − T_air)`. With the air off, heat content changes by exactly the injected
//!   energy, up to round-off; [`HeatReport`] returns both terms of the balance.
//! - *Unconditionally stable.* The matrix is symmetric positive definite for any `Δt > 0`; the
//!   `C`-weighted spread of temperatures never grows. A huge step jumps to the steady state.
//! - *Maximum principle: only on non-obtuse meshes.* On a tetrahedron with an obtuse dihedral
//!   angle `K` has a positive off-diagonal entry (`K_ij = −(k/6) Σ lₑ cot θₑ` over the edges
//!   opposite `ij`), so `C/Δt + K + H` is not an M-matrix and a step can under- or overshoot
//!   near such elements (boundedly: the spread still shrinks). On the shipped liver, a 30 K
//!   pulse at one node makes neighbours dip below the base temperature by 3e-3 K at
//!   `Δt` = 0.01 s, 0.3 K at 1 s and 2 K at 100 s (`tests/heat.rs`). On meshes without obtuse
//!   angles (e.g. Kuhn-split boxes, whose tetrahedra are orthoschemes) no new extremum can
//!   appear. Turning `K` into an M-matrix by moving positive off-diagonals onto the diagonal
//!   was tried and rejected: it over-diffuses the shipped beam's slowest mode by 36 %.
//! - *Factorised once.* The matrix depends only on the geometry, `Δt` and `h`: faer's sparse
//!   Cholesky factorises it when the body is built or those change (`set_dt`, `set_air`);
//!   a step is one sparse product `K T` and two triangular solves, with no allocation.
//!   Measured (release, one core, default parameters): liver (555 nodes, 1706 tets) built and
//!   factorised in 1.8 ms, 44 µs per step; cylinder (260 nodes, 991 tets) 0.9 ms, 15 µs.
//!   First-order accurate in time (relative error `λΔt/2` on a mode decaying at rate `λ`),
//!   second order in space: on a bar the slowest mode's rate is off by `(πh/L)²/12` (0.8 % at
//!   10 cells), on the shipped unstructured beam by 0.26 %.
//!
//! # Organs that touch
//!
//! [`HeatWorld`] steps several bodies with one `Δt` and a list of [`Link`]s between node pairs
//! (from collision detection: surface vertices of two organs within a distance). A link of
//! conductance `G` (W/K; [`HeatWorld::contact_link`] takes a contact coefficient in W/m²/K times
//! the nodes' surface area) is applied by operator splitting before the bodies' implicit steps,
//! each link by the exact solution of its two-node equation over `Δt`:
//!
//! ```text
//! d = T_a − T_b,   μ = C_a C_b / (C_a + C_b),   q = μ d (1 − exp(−G Δt / μ)),
//! T_a −= q / C_a,   T_b += q / C_b
//! ```
//!
//! This conserves energy exactly and never lets a pair pass its common mean, at any `Δt`, so the
//! split step stays unconditionally stable; it is first order in time like the bodies' steps.
//! Links are applied one after the other (a node in several links sees the others' results:
//! deterministic, order-dependent at first order in `Δt`). A linked surface node keeps its air
//! exchange (the factorised matrix does not change with contacts): a slight overestimate of the
//! cooling of touching surfaces. A node's contact area is its whole surface share, so nodes on
//! the rim of a contact patch also count the surface around the patch (on a coarse mesh, up to
//! about twice the patch's conductance; less as the mesh is refined).
//!
//! # Burns
//!
//! A node whose temperature ends a step (or is set) above the body's coagulation temperature
//! is burned until [`HeatBody::reset`]: [`HeatBody::burned`] for viewers, and
//! [`HeatBody::stiffness_factors`] (`burn_stiffening` where burned, else 1) for a deformation
//! model that wants coagulated tissue stiffer. The heat model itself does not change when
//! tissue burns.
//!
//! # Resolution
//!
//! The cautery heats the mesh's nodes, each of which stands for about a quarter of the volume
//! of its tetrahedra: on a coarse organ mesh 20 W warms a node by a few kelvin per second, not
//! the hundreds of degrees of a real 1 mm electrode contact. Burns therefore appear at the
//! resolution of the mesh, after a longer press than in reality.
//!
//! # Defaults
//!
//! [`HeatParameters::default`]: liver-like tissue (`k` 0.52 W/m/K, `c` 3540 J/kg/K,
//! `ρ` 1060 kg/m³: typical literature values, e.g. the IT'IS tissue database), body at 37 °C,
//! air at 22 °C with natural convection `h` = 10 W/m²/K, coagulation at 60 °C.

mod body;
mod system;
mod world;

pub use body::{HeatBody, HeatError, HeatParameters, HeatReport, ABSOLUTE_ZERO, MAX_TEMPERATURE};
pub use world::{HeatWorld, HeatWorldReport, Link};
