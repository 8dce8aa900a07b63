//! `lop-sim`: the pure, deterministic physics of lop.
//!
//! Meshes and mesh I/O ([`mesh`]), the mass-spring model ([`msd`]), Green-coordinate cages
//! ([`gc`]), tool-to-surface geometry ([`contact`]), what passes between the world and a model's
//! step ([`interaction`]) and the scene that steps them ([`world`]).
//! No threads, no IPC, no clocks: the daemon adapts devices, shared memory and configuration to
//! the types here, and the same inputs always give the same outputs, bit for bit.

// Range checks are written `!(x > 0.0)` on purpose: NaN must fail them.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod collide;
pub mod contact;
pub mod control;
pub mod fem;
pub mod gc;
pub mod haptic;
pub mod heat;
pub mod interaction;
pub mod lop;
pub mod mesh;
pub mod model;
pub mod msd;
mod solve;
mod vec3;
pub mod world;
