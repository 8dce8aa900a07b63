//! Levels of precision (thesis ch. 4): a body runs as a cheap Green-coordinates cage
//! ([`CageModel`]) while nothing touches it, switches to its precise model (FEM if important,
//! mass-spring otherwise) when the tool does, and back once it has settled ([`PrecisionController`]).
//!
//! # The cage model
//!
//! The body's nodes are bound once to a closed cage around them ([`crate::gc`]): each node keeps
//! its φ (per cage vertex) and ψ (per cage triangle), and a step re-evaluates
//! `x = Σ φᵢ vᵢ' + Σ ψⱼ sⱼ n(tⱼ')` for the cage's new vertices. The cage is the thesis' padded
//! bounding box or the same box subdivided ([`CageShape`]). Fixed nodes never move, whatever
//! the cage does.
//!
//! What moves the cage ([`CageDynamics`]):
//!
//! - **Mass-spring** (the thesis' way, §4.3): springs between the cage vertices with the GC
//!   parameters of Tables 6.1/6.2 (stiffness, density, damping), tuned by hand. Loads on nodes
//!   reach the cage vertices weighted by the nodes' φ (thesis §6.3.4.1). A cage vertex is fixed
//!   when it carries a fixed node's largest weight. Every pair of cage vertices is a spring
//!   (a triangle-edge shell folds flat at no cost).
//! - **Projected** (beyond the thesis; the default): nothing is tuned. With `q` the cage-vertex
//!   displacements and `G = ∂x/∂q` at rest (3N × 3V; zero rows on fixed nodes), the node motions
//!   the cage can make are `u = G q`, and the cage obeys
//!
//!   ```text
//!   M_r q̈ + D_r q̇ + K_r q = Gᵀ f,    M_r = GᵀMG,  D_r = GᵀDG,  K_r = M_r C_r⁻¹ M_r,
//!   C_r = (MG)ᵀ K⁻¹ (MG)
//!   ```
//!
//!   with the precise model's own lumped masses, damping (`αM` for FEM, `γI` for mass-spring)
//!   and rest stiffness `K`, the fixed nodes held exactly (their rows of `G` are zero). The
//!   stiffness is matched to the body's *compliance* (`compliance.rs`): the cage's static
//!   response to a load is the mass-weighted best fit of the precise model's response to the
//!   same load smoothed onto the cage (same total force and moment). The plain Galerkin
//!   restriction `K_r = GᵀKG` ([`CageDynamics::Galerkin`], kept for comparison) is the best fit
//!   in the energy norm instead, which *locks*: a cage that cannot bend exactly like the body
//!   is stiffer than it, by 2–5× on the shipped bodies. Measured by `lop-bench lop` (Part 3):
//!   the projected cage's error against the FEM is at the best-fit bound on the liver (box
//!   0.66 %, fitted 0.48 % of the smallest dimension, where Galerkin gave 2.6 % and 2.0 %).
//!   `K` is assembled from the precise model's `u ↦ K u` by probing (a distance-2 colouring of
//!   the nodes, three products per colour) and factorised once, sparse; a body with no fixed
//!   node has no compliance and gets the Galerkin stiffness. It is integrated with the FEM's
//!   implicit scheme (eq. 4.20) in dense 3V × 3V matrices folded at set-up: per step a few
//!   small matrix–vector products, plus `Gᵀ f` when there are loads. The tool and organ
//!   contacts join the step implicitly (their stiffness projected onto the cage, a dense
//!   3V × 3V solve in contact steps only): a cage as soft as its body would ring under an
//!   explicit 300 N/m tool.
//!
//! # The tool's contact patch on a cage
//!
//! The god-object's press with the linear law comes as a contact patch over the tool's
//! footprint ([`crate::patch`]). The projected (and Galerkin) cage resolves it in its implicit
//! step: a point's position after the step is linearised as `x + G d`, its column in the cage's
//! unknowns is `c_j = Gᵀ (n_j` spread over its nodes with their weights`)`, the step's
//! compliance is `A⁻¹`, and the complementarity problem's forces add `A⁻¹ C λ` to the
//! increment; the report carries the proxy the god-object rests at, so the hand feels what the
//! cage receives. When organ contact springs act in the same step they are resolved first
//! (their stiffness joins `A`) and the patch is solved with the factor of that same matrix, so
//! the two meet as in one linear system (the springs' active set is the one at the start of
//! the step, as without a patch).
//!
//! Decision: the thesis' mass-spring cage keeps the anchor's one-point press. Its loads reach
//! the cage vertices explicitly through φ and its own step is a separate mass-spring body on
//! the cage vertices, so there is no step compliance from nodes to cage to build the patch's
//! problem on; it is the hand-tuned comparison model, not the one a touched body runs (that
//! switches to its precise model, which resolves the patch).
//!
//! - **Under gravity** ([`CageModel::from_precise_under`], what `lopd` builds): a corotational
//!   FEM body is first solved to its static equilibrium under the scene's gravity, and the
//!   projected cage is linearised about *that* shape, with the FEM's tangent stiffness there
//!   (central differences of its elastic forces, probed like `K`) in `C_r`, and a constant
//!   correction that makes the equilibrium the cage's own. A soft, tall body carrying its own
//!   weight is much softer sideways than at rest — the Table 6.1 cylinder bends 2.3× farther
//!   under the same side load — and a cage built on the rest stiffness misses it (cylinder,
//!   `lop-bench lop` Part 3: 3.4 % of the diameter about rest, 1.2 % about the equilibrium).
//!
//! # Switching without a pop
//!
//! - Cage → precise: the precise model takes the cage's exact node positions and velocities; the
//!   displayed shape does not jump at all.
//! - Precise → cage: the cage is fitted to the precise shape (mass-weighted least squares, and
//!   likewise the velocities). What the cage cannot represent (the residual) is kept as an
//!   offset that fades linearly to zero over [`LopPolicy::blend`], so the first cage frame shows
//!   exactly the precise shape and every later frame moves by at most `residual · dt / blend`
//!   more than the cage itself. The residual is reported with each switch ([`Switch`]).
//!   With projected dynamics the cage also adopts the fitted shape as its equilibrium under the
//!   current gravity (a constant static correction `A⁻¹(K_r q* − Gᵀ M g)` added to each
//!   increment), so a body that settled under gravity as FEM stays where FEM put it instead of
//!   drifting to the cage's own, slightly different sag. Loads that come later (collisions)
//!   act on top of it; a reset or a start from rest has no correction.
//!
//! # Speed
//!
//! A step is a few small dense products (`3V × 6V` for the dynamics, in double precision) and
//! one pass over the nodes' coefficients (`N × (V + T)`, single precision: it computes
//! displacements, not positions, so 24 bits are far more than enough), both compiled for AVX2
//! and FMA when the CPU has them. `lop-bench lop` measures it against the FEM step.

mod cage_dynamics;
mod cage_model;
mod compliance;
mod controller;
mod kernel;

pub(crate) use cage_model::Prestress;
pub use cage_model::{
    build_cage, fitted_cells, CageDynamics, CageModel, CageModelError, CageShape, CageSprings,
    Damping, GcParameters, PreciseOperators, MAX_FITTED_VERTICES,
};
pub use controller::{LopPolicy, PrecisionController, StartLevel, Switch, SwitchReason};
