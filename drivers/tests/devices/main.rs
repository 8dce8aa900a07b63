//! lop-drivers' device tests, one module per former test file, linked into one test binary
//! (`cargo test -p lop-drivers --test devices`): one build and link of the dependencies instead
//! of one per file.
//!
//! The counting allocator counts only armed threads, and the allocation tests here read the
//! counts of their own thread (`alloc::this_thread`, `alloc::largest_on_this_thread`), so the
//! modules' tests running in parallel cannot disturb them. `openhaptics_standin.rs` keeps a
//! binary of its own: it sets environment variables and reads the process-wide totals.

use lop_test_support::alloc::Counting;

#[global_allocator]
static A: Counting = Counting::armed_threads();

mod device_spec;
mod fuzz_drivers;
mod hand_device;
mod mock_device;
mod recording;
mod rt_alloc;
mod script_parse;
