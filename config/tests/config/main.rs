//! lop-config's tests, one module per former test file, linked into one test binary
//! (`cargo test -p lop-config --test config`): one build and link of the dependencies instead
//! of one per file.
//!
//! The counting allocator counts only armed threads; `fuzz_config`'s bounded-memory checks read
//! the largest allocation of their own thread (`alloc::largest_on_this_thread`), so the other
//! modules' tests running in parallel cannot disturb them.

use lop_test_support::alloc::Counting;

#[global_allocator]
static A: Counting = Counting::armed_threads();

#[path = "../common/mod.rs"]
mod common;

mod api;
mod base;
mod errors;
mod fix_selectors;
mod fuzz_config;
mod shipped;
mod tissue_library;
mod tools;
