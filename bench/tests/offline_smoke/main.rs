//! Smoke tests of the offline `lop-bench` commands (`haptics`, `interaction`, `lop`, `models`,
//! `timings`, each `--quick`), one module per former test file, linked into one test binary
//! (`cargo test -p lop-bench --test offline_smoke`): one build and link of the dependencies
//! instead of one per file. None has a wall-clock bound, and each writes into a folder of its
//! own (the generated meshes' shared cache is safe for concurrent runs).
//!
//! The smoke tests of the real pipeline (`latency_smoke.rs`, `soak_smoke.rs`) keep binaries of
//! their own: they run against the wall clock and must not share the machine with another
//! test of the same binary.

#[path = "../common/mod.rs"]
mod common;

mod haptics_smoke;
mod interaction_smoke;
mod lop_smoke;
mod models_smoke;
mod timings_smoke;
