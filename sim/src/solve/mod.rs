//! The linear solvers of the crate, in one place.
//!
//! - [`sparse`]: a fixed-pattern sparse SPD matrix with its faer Cholesky factor — symbolic
//!   factorisation once, numeric refactorisation into reused buffers, solves in place with
//!   preallocated scratch (allocation-free after set-up). The FEM (`fem/system.rs`, which adds
//!   its own packed supernodal solves on top), the implicit mass-spring step
//!   (`msd/implicit.rs`), the heat bodies (`heat/system.rs`) and the GC compliance
//!   (`lop/compliance.rs`) build on it.
//! - [`dense`]: small dense SPD solves through nalgebra's Cholesky decomposition.
//! - [`lcp`]: a linear complementarity problem with an SPD matrix, by principal pivoting (the
//!   tool's contact patch, `patch.rs`).

pub(crate) mod dense;
pub(crate) mod lcp;
pub(crate) mod sparse;
