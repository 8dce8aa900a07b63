//! Guards the wire layout of every payload: a renderer in C, C++ or Python maps these bytes by
//! offset, so any change here must bump `CONTRACT_VERSION` and update `docs/ipc.md`.
//! The numbers below are the contract; they were derived by hand from the `#[repr(C)]` rules
//! (every padding byte is an explicit `_pad` field, so there is no implicit padding anywhere).

use std::mem::{align_of, offset_of, size_of};

use iceoryx2::prelude::ZeroCopySend;
use lop_ipc::*;

#[test]
fn contract_version_is_ten() {
    assert_eq!(CONTRACT_VERSION, 10);
}

#[test]
fn tool_state_layout() {
    assert_eq!(size_of::<ToolState>(), 160);
    assert_eq!(align_of::<ToolState>(), 8);
    assert_eq!(offset_of!(ToolState, contract_version), 0);
    assert_eq!(offset_of!(ToolState, flags), 4);
    assert_eq!(offset_of!(ToolState, sequence), 8);
    assert_eq!(offset_of!(ToolState, stamp_ns), 16);
    assert_eq!(offset_of!(ToolState, device_position), 24);
    assert_eq!(offset_of!(ToolState, proxy_position), 48);
    assert_eq!(offset_of!(ToolState, force), 72);
    assert_eq!(offset_of!(ToolState, tool_radius), 96);
    assert_eq!(offset_of!(ToolState, contact_barycentric), 104);
    assert_eq!(offset_of!(ToolState, buttons), 128);
    assert_eq!(offset_of!(ToolState, contact_body), 132);
    assert_eq!(offset_of!(ToolState, contact_triangle), 136);
    assert_eq!(offset_of!(ToolState, tool), 140);
    assert_eq!(offset_of!(ToolState, topology_id), 144);
    assert_eq!(offset_of!(ToolState, tool_stiffness), 152);
}

#[test]
fn frame_layout() {
    assert_eq!(size_of::<BodyFrame>(), 56);
    assert_eq!(align_of::<BodyFrame>(), 4);
    assert_eq!(offset_of!(BodyFrame, aabb_min), 0);
    assert_eq!(offset_of!(BodyFrame, aabb_max), 12);
    assert_eq!(offset_of!(BodyFrame, kinetic_energy), 24);
    assert_eq!(offset_of!(BodyFrame, max_speed), 28);
    assert_eq!(offset_of!(BodyFrame, step_ns), 32);
    assert_eq!(offset_of!(BodyFrame, resets), 36);
    assert_eq!(offset_of!(BodyFrame, model), 40);
    assert_eq!(offset_of!(BodyFrame, state), 41);
    assert_eq!(offset_of!(BodyFrame, switches), 44);
    assert_eq!(offset_of!(BodyFrame, period_us), 48);
    assert_eq!(offset_of!(BodyFrame, real_time_factor), 52);

    assert_eq!(MAX_TOOLS, 4);
    assert_eq!(size_of::<ContactFrame>(), 184);
    assert_eq!(align_of::<ContactFrame>(), 8);
    assert_eq!(offset_of!(ContactFrame, proxy), 0);
    assert_eq!(offset_of!(ContactFrame, force), 24);
    assert_eq!(offset_of!(ContactFrame, device), 48);
    assert_eq!(offset_of!(ContactFrame, stiffness), 72);
    assert_eq!(offset_of!(ContactFrame, drift), 144);
    assert_eq!(offset_of!(ContactFrame, horizon), 168);
    assert_eq!(offset_of!(ContactFrame, body), 176);
    assert_eq!(offset_of!(ContactFrame, local), 180);

    assert_eq!(
        size_of::<FrameHeader>(),
        80 + 56 * MAX_BODIES + 184 * MAX_TOOLS
    );
    assert_eq!(size_of::<FrameHeader>(), 1712);
    assert_eq!(align_of::<FrameHeader>(), 8);
    assert_eq!(offset_of!(FrameHeader, contract_version), 0);
    assert_eq!(offset_of!(FrameHeader, body_count), 4);
    assert_eq!(offset_of!(FrameHeader, topology_id), 8);
    assert_eq!(offset_of!(FrameHeader, sequence), 16);
    assert_eq!(offset_of!(FrameHeader, sim_time), 24);
    assert_eq!(offset_of!(FrameHeader, publish_ns), 32);
    assert_eq!(offset_of!(FrameHeader, tool_stamp_ns), 40);
    assert_eq!(offset_of!(FrameHeader, tool_read_ns), 48);
    assert_eq!(offset_of!(FrameHeader, step_ns), 56);
    assert_eq!(offset_of!(FrameHeader, node_count), 64);
    assert_eq!(offset_of!(FrameHeader, _pad), 68);
    assert_eq!(offset_of!(FrameHeader, bodies), 72);
    assert_eq!(offset_of!(FrameHeader, tool_count), 72 + 56 * MAX_BODIES);
    assert_eq!(offset_of!(FrameHeader, _pad2), 76 + 56 * MAX_BODIES);
    assert_eq!(offset_of!(FrameHeader, contacts), 80 + 56 * MAX_BODIES);
    assert_eq!(offset_of!(FrameHeader, contacts), 976);

    assert_eq!(size_of::<NodeSample>(), 20);
    assert_eq!(align_of::<NodeSample>(), 4);
    assert_eq!(offset_of!(NodeSample, temperature), 12);
    assert_eq!(offset_of!(NodeSample, flags), 16);
}

#[test]
fn a_default_frame_has_no_tool_and_no_contact() {
    let h = FrameHeader::default();
    assert_eq!(h.tool_count, 0);
    assert!(h.contacts.iter().all(|c| *c == ContactFrame::default()));
    assert_eq!(ContactFrame::default().body, NO_CONTACT);
    assert_eq!(ContactFrame::default().local, 0);
    // Only the first `tool_count` contacts are the frame's.
    assert!(h.contact(0).is_none());
    let h = FrameHeader { tool_count: 1, ..h };
    assert_eq!(h.contact(0), Some(&h.contacts[0]));
    assert!(h.contact(1).is_none());
    assert!(h.contact(MAX_TOOLS).is_none());
}

#[test]
fn tool_blackboard_keys_are_the_tool_indices() {
    assert_eq!(services::tool_latest_key(0), 0);
    assert_eq!(
        services::tool_latest_key(MAX_TOOLS - 1),
        MAX_TOOLS as u32 - 1
    );
}

#[test]
fn topology_layout() {
    assert_eq!(size_of::<BodyTopology>(), 88);
    assert_eq!(align_of::<BodyTopology>(), 4);
    assert_eq!(offset_of!(BodyTopology, name), 0);
    assert_eq!(offset_of!(BodyTopology, node_offset), 32);
    assert_eq!(offset_of!(BodyTopology, node_count), 36);
    assert_eq!(offset_of!(BodyTopology, triangle_offset), 40);
    assert_eq!(offset_of!(BodyTopology, triangle_count), 44);
    assert_eq!(offset_of!(BodyTopology, tet_offset), 48);
    assert_eq!(offset_of!(BodyTopology, tet_count), 52);
    assert_eq!(offset_of!(BodyTopology, color), 56);
    assert_eq!(offset_of!(BodyTopology, importance), 68);
    assert_eq!(offset_of!(BodyTopology, render_vertex_offset), 72);
    assert_eq!(offset_of!(BodyTopology, render_vertex_count), 76);
    assert_eq!(offset_of!(BodyTopology, render_triangle_offset), 80);
    assert_eq!(offset_of!(BodyTopology, render_triangle_count), 84);

    assert_eq!(size_of::<TopologyHeader>(), 40 + 88 * MAX_BODIES);
    assert_eq!(offset_of!(TopologyHeader, topology_id), 8);
    assert_eq!(offset_of!(TopologyHeader, node_count), 16);
    assert_eq!(offset_of!(TopologyHeader, triangle_count), 20);
    assert_eq!(offset_of!(TopologyHeader, tet_count), 24);
    assert_eq!(offset_of!(TopologyHeader, render_triangle_count), 28);
    assert_eq!(offset_of!(TopologyHeader, render_vertex_count), 32);
    assert_eq!(offset_of!(TopologyHeader, bodies), 40);
}

#[test]
fn telemetry_layout() {
    assert_eq!(size_of::<Percentiles>(), 40);
    assert_eq!(size_of::<HapticTelemetry>(), 64 + 6 * 40 + 8 + 2 * 40);
    assert_eq!(align_of::<HapticTelemetry>(), 8);
    assert_eq!(offset_of!(HapticTelemetry, stamp_ns), 8);
    assert_eq!(offset_of!(HapticTelemetry, ticks), 16);
    assert_eq!(offset_of!(HapticTelemetry, overruns), 24);
    assert_eq!(offset_of!(HapticTelemetry, stale_ticks), 32);
    assert_eq!(offset_of!(HapticTelemetry, device_faults), 40);
    assert_eq!(offset_of!(HapticTelemetry, rate_hz), 48);
    assert_eq!(offset_of!(HapticTelemetry, force_norm), 56);
    assert_eq!(offset_of!(HapticTelemetry, window_jitter), 64);
    assert_eq!(offset_of!(HapticTelemetry, total_frame_age), 64 + 5 * 40);
    assert_eq!(offset_of!(HapticTelemetry, pinned_core), 304);
    assert_eq!(offset_of!(HapticTelemetry, window_frame_age_contact), 312);
    assert_eq!(offset_of!(HapticTelemetry, total_frame_age_contact), 352);
}

#[test]
fn type_names_are_language_neutral() {
    // SAFETY: type_name only returns a static string.
    unsafe {
        assert_eq!(ToolState::type_name(), "lop::ToolState");
        assert_eq!(FrameHeader::type_name(), "lop::FrameHeader");
        assert_eq!(ContactFrame::type_name(), "lop::ContactFrame");
        assert_eq!(NodeSample::type_name(), "lop::NodeSample");
        assert_eq!(TopologyHeader::type_name(), "lop::TopologyHeader");
        assert_eq!(HapticTelemetry::type_name(), "lop::HapticTelemetry");
    }
}

#[test]
fn body_names_round_trip_and_truncate_at_char_boundary() {
    let mut b = BodyTopology::default();
    b.set_name("liver");
    assert_eq!(b.name_str(), "liver");
    let long = "é".repeat(20); // 40 bytes
    b.set_name(&long);
    assert_eq!(b.name_str(), "é".repeat(16));
}

#[test]
fn prefixes_are_checked() {
    assert!(ServiceNames::new("lop").is_ok());
    assert!(ServiceNames::new("rig-2/test_x").is_ok());
    for bad in ["", "/lop", "lop/", "lo p", "lop!"] {
        assert!(ServiceNames::new(bad).is_err(), "{bad:?}");
    }
    let n = ServiceNames::new("t1").unwrap();
    assert_eq!(n.frame, "t1/scene/frame");
}

#[test]
fn control_layout() {
    assert_eq!(size_of::<ControlRequest>(), 88);
    assert_eq!(align_of::<ControlRequest>(), 8);
    assert_eq!(offset_of!(ControlRequest, body_index), 8);
    assert_eq!(offset_of!(ControlRequest, model), 12);
    assert_eq!(offset_of!(ControlRequest, body), 16);
    assert_eq!(offset_of!(ControlRequest, key), 48);
    assert_eq!(offset_of!(ControlRequest, value), 80);
    assert_eq!(size_of::<ControlParam>(), 48);
    assert_eq!(offset_of!(ControlParam, value), 32);
    assert_eq!(offset_of!(ControlParam, flags), 40);
    assert_eq!(size_of::<ControlResponse>(), 184 + 48 * CONTROL_MAX_PARAMS);
    assert_eq!(align_of::<ControlResponse>(), 8);
    assert_eq!(offset_of!(ControlResponse, pin), 12);
    assert_eq!(offset_of!(ControlResponse, param_count), 16);
    assert_eq!(offset_of!(ControlResponse, body), 24);
    assert_eq!(offset_of!(ControlResponse, message), 56);
    assert_eq!(offset_of!(ControlResponse, params), 184);
    // SAFETY: type_name only returns a static string.
    unsafe {
        assert_eq!(ControlRequest::type_name(), "lop::ControlRequest");
        assert_eq!(ControlResponse::type_name(), "lop::ControlResponse");
    }
    let r = ControlRequest::set("liver", "fem.young", 300.0);
    assert_eq!(
        (r.body_str(), r.key_str(), r.value),
        ("liver", "fem.young", 300.0)
    );
    assert_eq!(r.contract_version, CONTRACT_VERSION);
}
