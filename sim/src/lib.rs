//! `lop-sim`: the pure, deterministic physics of lop.
//!
//! Meshes and mesh I/O, deformation models, tool contact. No threads, no IPC, no clocks: the
//! daemon adapts devices, shared memory and configuration to the types here.

pub mod mesh;
