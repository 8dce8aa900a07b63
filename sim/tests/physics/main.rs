//! lop-sim's physics tests, one module per former test file, linked into one test binary
//! (`cargo test -p lop-sim --test physics`): one build and link of the dependencies instead of
//! one per file.
//!
//! The counting allocator counts only armed threads, and every allocation test here reads the
//! count of its own thread (`alloc::this_thread`), so the modules' tests running in parallel
//! threads cannot disturb one another's counts. A test that needs the process-wide totals, or
//! `Counting::every_thread`, keeps a binary of its own (`fem_alloc.rs`).

use lop_test_support::alloc::Counting;

#[global_allocator]
static A: Counting = Counting::armed_threads();

#[path = "../common/mod.rs"]
mod common;

mod collide;
mod collision_response;
mod cut;
mod fem_background;
mod fem_contact;
mod fem_dynamics;
mod fem_ordering;
mod fem_threads;
mod fem_validation;
mod gc;
mod grasp;
mod haptic;
mod heat;
mod interaction;
mod local_model;
mod lop;
mod lop_alloc;
mod msd_alloc;
mod msd_integrators;
mod msd_world;
mod patch;
mod pinch;
