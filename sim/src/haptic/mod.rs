//! Tool–tissue contact for the haptic loop (thesis §5.2): closest-point queries on the deforming
//! surfaces, the god-object proxy and the force law.
//!
//! - [`SurfaceSet`]: every body's surface over one node array, updated from each new frame;
//!   closest points by the thesis' greedy vertex walk (Algorithm 1), warm-started from the last
//!   answer and checked against a bounding-volume hierarchy so a walk stuck in a local minimum
//!   never gives a wrong answer.
//! - [`GodObject`]: the proxy that stays on the surface while the device penetrates.
//! - [`LocalModel`]: the frame's linearised contact, so the force follows the hand between
//!   frames; [`PassivityController`]: keeps the coupling from generating energy.
//! - [`hand_force`]: the thesis' `F = k d² N` (eq. 5.2) or a linear spring `F = k d N`, with
//!   optional damping, from the proxy–device gap.
//!
//! The same code runs in the haptic process (on the newest frame) and offline (`lopd simulate`,
//! benchmarks), so what the hand feels and what the tissue receives are computed one way.

mod god;
mod local;
mod offline;
mod passivity;
mod pipeline;
pub mod safety;
mod surface;
mod sweep;
pub mod workspace;

pub use god::{hand_force, law_magnitude, Anchor, GodObject, GodState};
pub use local::{contact_force, FreeMotion, LocalModel};
pub use offline::{WorldProbe, WorldSurfaces};
pub use passivity::{PassivityController, RESET_AFTER_S};
pub use pipeline::{
    ContactSurfaces, DeviceReading, HapticPipeline, PipelineSettings, Stage, TickOutput,
    WORKSPACE_SLACK_MM,
};
pub use safety::ForceSafety;
pub use surface::{Closest, QueryStats, SurfaceSet};
pub use sweep::{sweep_sphere_triangle, Impact};
