//! Tests of `lopd`'s commands through the binary (its command line, `deploy/`, `doctor`,
//! record and replay, `simulate`, `mesh tetrahedralize`), one module per former test file,
//! linked into one test binary (`cargo test -p lop-daemon --test commands`): one build and
//! link of the dependencies instead of one per file. Every scratch folder and service prefix
//! carries its module's name, and no assertion here bounds the wall clock.
//!
//! Binaries of their own: the allocation tests (`rt_alloc.rs`, `rt_alloc_servo.rs`: they read
//! the process-wide counts), and the two that run `lopd run` live, whose felt force depends on
//! the deformation process keeping up with the wall clock (`hand_device.rs`, `own_organ.rs`).

#[path = "../lopd_cli/mod.rs"]
mod lopd_cli;
#[path = "../../../drivers/standin-hd/testing.rs"]
mod standin;

mod cli;
mod deploy_files;
mod doctor;
mod record_replay;
mod simulate;
mod tetrahedralize;
