//! The C header `ipc/include/lop_ipc.h` mirrors every payload: a C program compiled with the
//! system's `cc` prints the size, alignment and every field offset of each struct, and they must
//! equal Rust's. (The header's own `_Static_assert`s fail the compile first if it drifts.)

use std::collections::BTreeMap;
use std::mem::{align_of, offset_of, size_of};
use std::path::Path;
use std::process::Command;

use lop_ipc::*;

macro_rules! layout {
    ($out:ident, $c:ident; $( $ty:ident { $($f:ident),* $(,)? } )*) => {
        $(
            $out.insert(format!("{}.size", stringify!($ty)), size_of::<$ty>());
            $out.insert(format!("{}.align", stringify!($ty)), align_of::<$ty>());
            $c.push_str(&format!(
                "  printf(\"{0}.size %zu\\n{0}.align %zu\\n\", sizeof(lop_{0}), _Alignof(lop_{0}));\n",
                stringify!($ty)
            ));
            $(
                $out.insert(format!("{}.{}", stringify!($ty), stringify!($f)), offset_of!($ty, $f));
                $c.push_str(&format!(
                    "  printf(\"{0}.{1} %zu\\n\", offsetof(lop_{0}, {1}));\n",
                    stringify!($ty), stringify!($f)
                ));
            )*
        )*
    };
}

#[test]
fn c_header_matches_the_rust_layouts() {
    let mut rust = BTreeMap::new();
    let mut body = String::new();
    layout!(rust, body;
        ToolState { contract_version, flags, sequence, stamp_ns, device_position, proxy_position,
            force, tool_radius, contact_barycentric, buttons, contact_body, contact_triangle,
            tool, topology_id, tool_stiffness }
        BodyFrame { aabb_min, aabb_max, kinetic_energy, max_speed, step_ns, resets, model, state,
            _pad, switches, period_us, real_time_factor }
        ContactFrame { proxy, force, device, stiffness, drift, horizon, body, local }
        FrameHeader { contract_version, body_count, topology_id, sequence, sim_time, publish_ns,
            tool_stamp_ns, tool_read_ns, step_ns, node_count, _pad, bodies, tool_count, _pad2,
            contacts }
        NodeSample { position, temperature, flags }
        BodyTopology { name, node_offset, node_count, triangle_offset, triangle_count,
            tet_offset, tet_count, color, importance, _pad, render_vertex_offset,
            render_vertex_count, render_triangle_offset, render_triangle_count }
        TopologyHeader { contract_version, body_count, topology_id, node_count, triangle_count,
            tet_count, render_triangle_count, render_vertex_count, _pad, bodies }
        Percentiles { count, p50, p99, p999, max }
        HapticTelemetry { contract_version, rt_flags, stamp_ns, ticks, overruns, stale_ticks,
            device_faults, rate_hz, force_norm, window_jitter, window_compute, window_frame_age,
            total_jitter, total_compute, total_frame_age, pinned_core, _pad,
            window_frame_age_contact, total_frame_age_contact }
        ControlRequest { contract_version, op, body_index, model, body, key, value }
        ControlParam { key, value, flags, _pad }
        ControlResponse { contract_version, status, body_index, pin, model, paused, _pad0,
            param_count, _pad1, body, message, params }
    );
    // Constants a C reader relies on.
    body.push_str("  printf(\"CONTRACT_VERSION %u\\n\", LOP_CONTRACT_VERSION);\n");
    rust.insert("CONTRACT_VERSION".into(), CONTRACT_VERSION as usize);
    body.push_str("  printf(\"MAX_BODIES %d\\n\", LOP_MAX_BODIES);\n");
    rust.insert("MAX_BODIES".into(), MAX_BODIES);
    body.push_str("  printf(\"MAX_TOOLS %d\\n\", LOP_MAX_TOOLS);\n");
    rust.insert("MAX_TOOLS".into(), MAX_TOOLS);
    body.push_str("  printf(\"NO_CONTACT %u\\n\", LOP_NO_CONTACT);\n");
    rust.insert("NO_CONTACT".into(), NO_CONTACT as usize);
    body.push_str("  printf(\"MAX_SUBSCRIBERS %d\\n\", LOP_MAX_SUBSCRIBERS);\n");
    rust.insert("MAX_SUBSCRIBERS".into(), services::MAX_SUBSCRIBERS);
    body.push_str("  printf(\"CONTROL_OP_RESUME %u\\n\", LOP_CONTROL_OP_RESUME);\n");
    rust.insert("CONTROL_OP_RESUME".into(), CONTROL_OP_RESUME as usize);
    body.push_str("  printf(\"CONTROL_STATUS_FAILED %u\\n\", LOP_CONTROL_STATUS_FAILED);\n");
    rust.insert(
        "CONTROL_STATUS_FAILED".into(),
        CONTROL_STATUS_FAILED as usize,
    );
    body.push_str("  printf(\"NODE_FLAG_BURNED %u\\n\", LOP_NODE_FLAG_BURNED);\n");
    rust.insert("NODE_FLAG_BURNED".into(), NODE_FLAG_BURNED as usize);
    body.push_str("  printf(\"TOOL_FLAG_HEAT %u\\n\", LOP_TOOL_FLAG_HEAT);\n");
    rust.insert("TOOL_FLAG_HEAT".into(), TOOL_FLAG_HEAT as usize);
    body.push_str("  printf(\"TOOL_FLAG_LOCAL_MODEL %u\\n\", LOP_TOOL_FLAG_LOCAL_MODEL);\n");
    rust.insert(
        "TOOL_FLAG_LOCAL_MODEL".into(),
        TOOL_FLAG_LOCAL_MODEL as usize,
    );

    let include = Path::new(env!("CARGO_MANIFEST_DIR")).join("include");
    let dir = std::env::temp_dir().join(format!("lop-c-header-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let src = dir.join("layout.c");
    std::fs::write(
        &src,
        format!("#include <stdio.h>\n#include \"lop_ipc.h\"\nint main(void) {{\n{body}  return 0;\n}}\n"),
    )
    .unwrap();
    let exe = dir.join("layout");
    let cc = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-I"])
        .arg(&include)
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("run cc (gcc is part of the build machine)");
    assert!(
        cc.status.success(),
        "cc failed:\n{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let out = Command::new(&exe).output().expect("run the layout program");
    let c: BTreeMap<String, usize> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let (k, v) = l.split_once(' ').unwrap();
            (k.to_string(), v.parse().unwrap())
        })
        .collect();
    assert_eq!(c.len(), rust.len());
    let diff: Vec<String> = rust
        .iter()
        .filter(|(k, v)| c.get(*k) != Some(v))
        .map(|(k, v)| format!("{k}: Rust {v}, C {:?}", c.get(k)))
        .collect();
    assert!(
        diff.is_empty(),
        "C header drifted from the Rust layout:\n{}",
        diff.join("\n")
    );
    assert!(rust.len() > 100, "{} entries compared", rust.len());
    let _ = std::fs::remove_dir_all(&dir);
}
