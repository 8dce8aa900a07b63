//! lop-view's tests of the server, its access rules and its wire, one module per former test
//! file, linked into one test binary (`cargo test -p lop-view --test viewer`): one build and
//! link of the dependencies instead of one per file. Every daemon and viewer a test starts has
//! a service prefix of its own (`unique_prefix`) and a port the system picked.
//!
//! Two keep binaries of their own: `browser.rs`, whose screenshots are sensitive to a loaded
//! machine, and `flood.rs`, which holds a thousand connections open in the test process (near
//! the open-file limit where it cannot be raised) and bounds the time the page takes to come.

#[path = "../common/mod.rs"]
mod common;

mod access;
mod frame_wire;
mod fuzz_wire;
mod run_view;
mod websocket;
