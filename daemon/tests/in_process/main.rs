//! Tests of the daemon's library in the test process (the closed loop on simulated time, the
//! control decoder, one world round, the organs' collisions, the local model's faults on the
//! real haptic loop, two tools on the real deformation loop), one module per former test file,
//! linked into one test binary (`cargo test -p lop-daemon --test in_process`): one build and
//! link of the dependencies instead of one per file. Each test here on iceoryx2
//! (`local_model_faults`, `two_tools`) has a service prefix of its own.

#[path = "../common/mod.rs"]
mod common;

mod closed_loop;
mod fuzz_control;
mod local_model_faults;
mod one_round;
mod organs_collision;
mod two_tools;
