//! Helpers shared by the workspace's tests and the bench (never part of a product binary):
//!
//! - [`alloc`]: a counting global allocator for the "allocates nothing" tests;
//! - [`fuzz`]: the committed-corpus fuzzing of the readers and decoders: seeds, a deterministic
//!   mutator;
//! - [`rng`]: the one seeded random generator;
//! - [`standin`]: building a stand-in vendor library for a driver's tests;
//! - [`fixtures`]: paths to the shipped assets and scenes, fresh temporary directories, the unit
//!   cube's corners;
//! - [`vec3`]: the small `[f64; 3]` arithmetic the tests check geometry with.
//!
//! It depends on no workspace crate, so any crate's tests can use it without a cycle.

pub mod alloc;
pub mod fixtures;
pub mod fuzz;
pub mod rng;
pub mod standin;
pub mod vec3;
