//! The frame message carries the newest state of each tool, told apart by `ToolState::tool`:
//! one record per tool with a state, in tool order, whatever order the states came in; a
//! newer state of a tool replaces its older one; a state naming a tool beyond `MAX_TOOLS` is
//! dropped; the bodies and nodes follow the tools' records.

use lop_client::*;
use lop_view::wire::{
    frame_binary, LatestTools, FRAME_BODY_BYTES, FRAME_HEADER_BYTES, FRAME_TOOL_BYTES, KIND_FRAME,
};

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

fn state(tool: u32, x: f64, flags: u32) -> ToolState {
    ToolState {
        contract_version: CONTRACT_VERSION,
        tool,
        flags,
        device_position: [x, 0.0, 0.0],
        proxy_position: [x, 0.5, 0.0],
        tool_radius: 0.004,
        force: [0.0, 1.5, 0.0],
        ..Default::default()
    }
}

fn frame() -> Frame {
    let mut header = FrameHeader {
        contract_version: CONTRACT_VERSION,
        body_count: 1,
        node_count: 3,
        sim_time: 0.25,
        ..Default::default()
    };
    header.bodies[0].period_us = 1000;
    Frame {
        header,
        nodes: (0..3)
            .map(|i| NodeSample {
                position: [i as f32, 0.0, 0.0],
                temperature: 37.0,
                flags: 0,
            })
            .collect(),
        received_ns: 0,
    }
}

#[test]
fn a_frame_without_tool_states_has_no_tool_records() {
    let b = frame_binary(&frame(), None, &LatestTools::default());
    assert_eq!(u32_at(&b, 0), KIND_FRAME);
    assert_eq!((u32_at(&b, 4), u32_at(&b, 8), u32_at(&b, 12)), (3, 1, 0));
    assert_eq!(f32_at(&b, 16), 0.25);
    // The body's period follows the header at once.
    assert_eq!(f32_at(&b, FRAME_HEADER_BYTES + 28), 1.0);
    assert_eq!(b.len(), FRAME_HEADER_BYTES + FRAME_BODY_BYTES + 3 * 16 + 4);
}

#[test]
fn each_tool_keeps_its_newest_state_in_tool_order() {
    let mut tools = LatestTools::default();
    assert!(tools.update(&state(1, 0.1, TOOL_FLAG_CONTACT)));
    assert!(tools.update(&state(0, 0.2, 0)));
    assert!(tools.update(&state(0, 0.3, TOOL_FLAG_GRAB)));
    assert!(!tools.update(&state(MAX_TOOLS as u32, 0.4, 0)));
    let b = frame_binary(&frame(), None, &tools);
    assert_eq!(u32_at(&b, 12), 2, "tool count");
    let rec = |k: usize| FRAME_HEADER_BYTES + k * FRAME_TOOL_BYTES;
    // Tool 0, its newer state.
    assert_eq!(u32_at(&b, rec(0)), 0);
    assert_eq!(u32_at(&b, rec(0) + 4), TOOL_FLAG_GRAB);
    assert_eq!(f32_at(&b, rec(0) + 8), 0.3);
    // Tool 1.
    assert_eq!(u32_at(&b, rec(1)), 1);
    assert_eq!(u32_at(&b, rec(1) + 4), TOOL_FLAG_CONTACT);
    assert_eq!(
        (f32_at(&b, rec(1) + 8), f32_at(&b, rec(1) + 24)),
        (0.1, 0.5),
        "device x, proxy y"
    );
    assert_eq!(f32_at(&b, rec(1) + 32), 0.004, "radius");
    assert_eq!(f32_at(&b, rec(1) + 40), 1.5, "force y");
    // The body after the tools.
    assert_eq!(f32_at(&b, rec(2) + 28), 1.0);
    assert_eq!(
        b.len(),
        FRAME_HEADER_BYTES + 2 * FRAME_TOOL_BYTES + FRAME_BODY_BYTES + 3 * 16 + 4
    );
}
