//! `lopd`, the lop daemon: the supervisor (`lopd run`), the 1 kHz haptic process
//! (`lopd haptic`) and the deformation process (`lopd deform`), plus small tools
//! (`lopd mesh info`, `lopd mesh tetrahedralize`, `lopd scene new`).
//!
//! The binary (`main.rs`) is glue: it parses the command line and calls into these modules.

use std::sync::atomic::AtomicBool;

pub mod control;
pub mod ctl;
pub mod deform;
pub mod doctor;
pub mod haptic;
pub mod haptic_process;
pub mod mesher;
pub mod record;
pub mod remote;
pub mod rt;
pub mod scene_new;
pub mod servo;
pub use lop_ipc::signals;
pub mod simulate;
pub mod status;
pub mod supervisor;
pub mod tetrahedralize;

/// Set once `mlockall` succeeded in this process.
pub static MEMORY_LOCKED: AtomicBool = AtomicBool::new(false);
