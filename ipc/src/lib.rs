//! `lop-ipc`: the shared-memory contract between `lopd`'s processes and any renderer.
//!
//! Everything that crosses a process boundary is defined here and nowhere else:
//! - [`types`]: `#[repr(C)]`, heap-free payloads with language-neutral type names and a
//!   [`CONTRACT_VERSION`] field, so a C, C++ or Python reader can map them without our code;
//! - [`services`]: the service names under a configurable prefix, the quality of service each
//!   service is created with, and thin helpers that create (daemon side) or open (client side)
//!   them;
//! - [`control`]: the request–response control service `PREFIX/control` (get and set body
//!   parameters, pin and release, reset, pause and resume);
//! - [`clock`]: the one clock every timestamp in a payload uses (`CLOCK_MONOTONIC`, ns), so
//!   latencies can be computed across processes;
//! - [`signals`]: the stop flag set by SIGINT/SIGTERM/SIGHUP and the parent-death signal, for
//!   every process that holds services and must release them on its way out.
//!
//! The rules a client must follow (attach read-only, never the blackboard, retry `open`) are in
//! the docs of [`services`].

pub mod clock;
pub mod control;
pub mod limits;
pub mod services;
pub mod signals;
pub mod types;
pub mod view_token;

pub use control::*;
pub use services::{ServiceNames, SERVICE_PREFIX_DEFAULT};
pub use types::*;

/// The iceoryx2 version lop is built with (the workspace pins it exactly). Every process
/// sharing a service runs the same version: the Python binding (`scripts/setup.sh`) and the
/// Zenoh link tunnel (`lopd run --remote`) are checked against it.
pub const ICEORYX2_VERSION: &str = "0.10.0";

/// Version of the payload layouts (2: `BodyFrame::switches`; 3: `NodeSample::flags` with
/// burned tissue, `TOOL_FLAG_GRAB` / `TOOL_FLAG_HEAT`; 4: `ToolState::tool_stiffness`;
/// 5: `FrameHeader::contact_proxy` / `contact_body`;
/// 6: `HapticTelemetry::window_frame_age_contact` / `total_frame_age_contact`;
/// 7: the patch's local model, `FrameHeader::contact_force` … `contact_local`;
/// 8: render surfaces in the topology, `BodyTopology::render_*`,
/// `TopologyHeader::render_triangle_count` / `render_vertex_count`;
/// 9: each body's pace, `BodyFrame::period_us` / `real_time_factor`;
/// 10: several tools: `ToolState::tool`, `FrameHeader::tool_count` / `contacts`
/// ([`ContactFrame`], in place of the `contact_*` fields), a tool blackboard entry per tool).
/// Bumped whenever a type in [`types`] changes shape or meaning; every payload carries it so a
/// reader can refuse data it does not understand.
pub const CONTRACT_VERSION: u32 = 10;

#[cfg(test)]
mod version_tests {
    #[test]
    fn the_iceoryx2_version_is_the_workspace_pin() {
        let manifest =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.toml"))
                .expect("workspace Cargo.toml");
        let line = manifest
            .lines()
            .find(|l| l.starts_with("iceoryx2 ="))
            .expect("iceoryx2 in the workspace dependencies");
        assert_eq!(line, format!("iceoryx2 = \"={}\"", super::ICEORYX2_VERSION));
    }
}
