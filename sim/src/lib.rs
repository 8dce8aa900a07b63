//! `lop-sim`: the pure, deterministic physics of lop. No IPC, no clocks: the daemon adapts
//! devices, shared memory and configuration to the types here, and the same inputs always give
//! the same outputs, bit for bit. Threads only where a caller asks for them (issue 27): a
//! touched FEM body's element loops on a [`parallel::WorkerPool`], and its factorisations on a
//! factor thread under [`fem::RefactorPolicy::Background`] — both keep that promise (the same
//! numbers for any thread count and any thread speed).
//!
//! The modules, from the ground up:
//! - [`mesh`]: tetrahedral meshes, their readers (TetGen, Gmsh, legacy VTK) and validation with
//!   located errors, the surface and its quality figures.
//! - [`msd`]: the mass-spring-damper model, five integrators (explicit, symplectic, Verlet,
//!   RK4, implicit Euler).
//! - [`fem`]: linear tetrahedral FEM, linear and corotational, implicit, with its preconditioned
//!   CG, direct solves and statics.
//! - [`gc`]: Green coordinates of a cage and the binding of a mesh to it.
//! - [`lop`]: the levels of precision: the cage model that stands in for an untouched body and
//!   the controller that switches a body between it and its precise model.
//! - [`model`]: the `Model` enum a body runs now (mass-spring, FEM or cage).
//! - [`interaction`]: what passes between the world and a model's step — the tool's contact and
//!   the god-object's anchor, organ contact springs, the contact report, blow-ups. A leaf: the
//!   models import it, never `model`.
//! - [`patch`]: the tool as a contact patch — the points of the surface the tool's sphere
//!   covers, and the complementarity problem that presses them, balanced by the tool spring.
//! - [`grasp`]: tools holding tissue — several grabs on one body with presses beside them
//!   (bilateral springs eliminated from the patch's problem), and a grasper's jaw footprint.
//! - [`contact`]: tool-to-surface geometry (the tool sphere, closest points, force laws).
//! - [`haptic`]: the god-object over a set of surfaces (what the 1 kHz loop runs) and its
//!   offline probe over a world.
//! - [`collide`]: organ-to-organ collision detection and its contact springs.
//! - [`heat`]: heat diffusion, cautery and burns.
//! - [`world`]: the scene — bodies on their own time steps, collision, heat — and its one round
//!   ([`world::World::round`]) that every caller runs.
//! - [`parallel`]: the worker pool of the touched body's step, and why its results do not
//!   depend on the number of threads.
//! - [`control`]: run-time changes to a world (swap a body's models, reset, hold time).
//! - `solve` (internal): the one sparse SPD solver (faer; symbolic once, numeric refactor into
//!   reused buffers) behind FEM, implicit mass-spring, heat and the cage's compliance, and a
//!   small dense SPD solve through nalgebra.
//! - `vec3` (internal): small vector helpers.

// Range checks are written `!(x > 0.0)` on purpose: NaN must fail them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod collide;
pub mod contact;
pub mod control;
pub mod cut;
pub mod fem;
pub mod gc;
pub mod grasp;
pub mod haptic;
pub mod heat;
pub mod interaction;
pub mod lop;
pub mod mesh;
pub mod model;
pub mod msd;
pub mod parallel;
pub mod patch;
mod solve;
mod vec3;
pub mod world;
