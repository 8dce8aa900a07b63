#!/usr/bin/env python3
"""A third-party renderer's first step: read lop's scene from shared memory, in Python.

Opens PREFIX/scene/topology, PREFIX/scene/frame and PREFIX/tool read-only with the `iceoryx2`
package from PyPI (exactly the version lopd uses: 0.10.0; `pip install iceoryx2==0.10.0`), maps
the payloads with ctypes structures that mirror docs/ipc.md (and ipc/include/lop_ipc.h), and
prints a few frames with each tool's contact, then the newest state of each tool. No lop code is
linked or imported.

    python3 examples/python/consumer.py --prefix lop --frames 5

Rules it follows (docs/ipc.md, "Rules for clients"): open, never create; retry while the daemon
starts; refuse another CONTRACT_VERSION; use frames only with the topology id they name.
The binding reports a slice payload's length in bytes, not elements: the node count comes from
the frame header and is checked against the byte length.
"""

import argparse
import ctypes
import math
import sys
import time

import iceoryx2 as iox2

CONTRACT_VERSION = 10
MAX_BODIES = 16
MAX_TOOLS = 4
NO_CONTACT = 0xFFFFFFFF
BODY_NAME_LEN = 32
# uint32 words per render vertex in the topology payload: 4 node indices, 4 float32 weights.
RENDER_VERTEX_WORDS = 8
MODELS = {0: "GC", 1: "MSD", 2: "FEM"}


class BodyFrame(ctypes.Structure):
    _fields_ = [
        ("aabb_min", ctypes.c_float * 3),
        ("aabb_max", ctypes.c_float * 3),
        ("kinetic_energy", ctypes.c_float),
        ("max_speed", ctypes.c_float),
        ("step_ns", ctypes.c_uint32),
        ("resets", ctypes.c_uint32),
        ("model", ctypes.c_uint8),
        ("state", ctypes.c_uint8),
        ("_pad", ctypes.c_uint8 * 2),
        ("switches", ctypes.c_uint32),
        ("period_us", ctypes.c_uint32),
        ("real_time_factor", ctypes.c_float),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::BodyFrame"


class ToolState(ctypes.Structure):
    _fields_ = [
        ("contract_version", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("sequence", ctypes.c_uint64),
        ("stamp_ns", ctypes.c_uint64),
        ("device_position", ctypes.c_double * 3),
        ("proxy_position", ctypes.c_double * 3),
        ("force", ctypes.c_double * 3),
        ("tool_radius", ctypes.c_double),
        ("contact_barycentric", ctypes.c_double * 3),
        ("buttons", ctypes.c_uint32),
        ("contact_body", ctypes.c_int32),
        ("contact_triangle", ctypes.c_uint32),
        ("tool", ctypes.c_uint32),
        ("topology_id", ctypes.c_uint64),
        ("tool_stiffness", ctypes.c_double),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::ToolState"


class ContactFrame(ctypes.Structure):
    _fields_ = [
        ("proxy", ctypes.c_double * 3),
        ("force", ctypes.c_double * 3),
        ("device", ctypes.c_double * 3),
        ("stiffness", ctypes.c_double * 9),
        ("drift", ctypes.c_double * 3),
        ("horizon", ctypes.c_double),
        ("body", ctypes.c_uint32),
        ("local", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::ContactFrame"


class FrameHeader(ctypes.Structure):
    _fields_ = [
        ("contract_version", ctypes.c_uint32),
        ("body_count", ctypes.c_uint32),
        ("topology_id", ctypes.c_uint64),
        ("sequence", ctypes.c_uint64),
        ("sim_time", ctypes.c_double),
        ("publish_ns", ctypes.c_uint64),
        ("tool_stamp_ns", ctypes.c_uint64),
        ("tool_read_ns", ctypes.c_uint64),
        ("step_ns", ctypes.c_uint64),
        ("node_count", ctypes.c_uint32),
        ("_pad", ctypes.c_uint32),
        ("bodies", BodyFrame * MAX_BODIES),
        ("tool_count", ctypes.c_uint32),
        ("_pad2", ctypes.c_uint32),
        ("contacts", ContactFrame * MAX_TOOLS),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::FrameHeader"


class NodeSample(ctypes.Structure):
    _fields_ = [
        ("position", ctypes.c_float * 3),
        ("temperature", ctypes.c_float),
        ("flags", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::NodeSample"


class BodyTopology(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_uint8 * BODY_NAME_LEN),
        ("node_offset", ctypes.c_uint32),
        ("node_count", ctypes.c_uint32),
        ("triangle_offset", ctypes.c_uint32),
        ("triangle_count", ctypes.c_uint32),
        ("tet_offset", ctypes.c_uint32),
        ("tet_count", ctypes.c_uint32),
        ("color", ctypes.c_float * 3),
        ("importance", ctypes.c_uint8),
        ("_pad", ctypes.c_uint8 * 3),
        ("render_vertex_offset", ctypes.c_uint32),
        ("render_vertex_count", ctypes.c_uint32),
        ("render_triangle_offset", ctypes.c_uint32),
        ("render_triangle_count", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::BodyTopology"

    def name_str(self) -> str:
        return bytes(self.name).split(b"\0", 1)[0].decode("utf-8", "replace")


class TopologyHeader(ctypes.Structure):
    _fields_ = [
        ("contract_version", ctypes.c_uint32),
        ("body_count", ctypes.c_uint32),
        ("topology_id", ctypes.c_uint64),
        ("node_count", ctypes.c_uint32),
        ("triangle_count", ctypes.c_uint32),
        ("tet_count", ctypes.c_uint32),
        ("render_triangle_count", ctypes.c_uint32),
        ("render_vertex_count", ctypes.c_uint32),
        ("_pad", ctypes.c_uint32),
        ("bodies", BodyTopology * MAX_BODIES),
    ]

    @staticmethod
    def type_name() -> str:
        return "lop::TopologyHeader"


# The sizes every reader must agree on (docs/ipc.md).
assert ctypes.sizeof(ToolState) == 160 and ctypes.alignment(ToolState) == 8
assert ctypes.sizeof(ContactFrame) == 184
assert ctypes.sizeof(FrameHeader) == 1712 and ctypes.alignment(FrameHeader) == 8
assert FrameHeader.contacts.offset == 976
assert ctypes.sizeof(NodeSample) == 20
assert ctypes.sizeof(TopologyHeader) == 1448


def open_retry(node, name, payload, header, timeout, required=True):
    """Opens an existing service (never creates one), retrying while lopd starts. `header` None:
    the service has no user header (Rust's `()`). Not `required`: None if it does not appear."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            builder = node.service_builder(iox2.ServiceName.new(name)).publish_subscribe(payload)
            if header is not None:
                builder = builder.user_header(header)
            return builder.open()
        except Exception as e:  # the binding raises its own *OpenError types
            if time.monotonic() > deadline:
                if not required:
                    return None
                sys.exit(f"consumer: cannot open {name!r} within {timeout} s: {e}")
            time.sleep(0.05)


def receive(subscriber, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sample = subscriber.receive()
        if sample is not None:
            return sample
        time.sleep(0.002)
    sys.exit(f"consumer: no {what} within {timeout} s")


def contacts_text(h, bodies):
    """Each tool's contact patch in a frame: the body it pressed, where, and whether the frame
    carries its local model."""
    out = []
    for t in range(min(h.tool_count, MAX_TOOLS)):
        c = h.contacts[t]
        if c.body == NO_CONTACT:
            out.append(f"tool {t}: no contact")
            continue
        name = bodies[c.body].name_str() if c.body < len(bodies) else f"body {c.body}"
        out.append(
            f"tool {t}: {name} at ({c.proxy[0]:.4f}, {c.proxy[1]:.4f}, {c.proxy[2]:.4f}) m"
            + (", local model" if c.local == 1 else "")
        )
    return "; ".join(out) if out else "no tools"


def newest_tool_states(node, prefix, timeout):
    """The newest state of each tool (by ToolState.tool) received within `timeout`; empty when
    no haptic process publishes."""
    service = open_retry(node, f"{prefix}/tool", ToolState, None, timeout, required=False)
    if service is None:
        return {}
    subscriber = service.subscriber_builder().create()
    newest = {}
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sample = subscriber.receive()
        if sample is None:
            if newest:
                break
            time.sleep(0.002)
            continue
        s = sample.payload().contents
        if s.contract_version == CONTRACT_VERSION and s.tool < MAX_TOOLS:
            newest[s.tool] = ToolState.from_buffer_copy(s)
        del sample
    return newest


def element_count(slice_, element_type, expected):
    """The binding's slice length is in bytes; accept elements too, in case that changes."""
    n = slice_.len()
    if n == expected * ctypes.sizeof(element_type):
        return expected
    if n == expected:
        return expected
    sys.exit(f"consumer: payload length {n} fits neither {expected} elements nor their bytes")


def read_topology(topo):
    """A topology sample's header, render vertices and bodies (copied out of the sample)."""
    th = TopologyHeader.from_buffer_copy(topo.user_header().contents)
    if th.contract_version != CONTRACT_VERSION:
        sys.exit(f"consumer: lopd speaks contract {th.contract_version}, this reader {CONTRACT_VERSION}")
    render_start = 3 * th.triangle_count + 4 * th.tet_count + 3 * th.render_triangle_count
    indices = element_count(
        topo.payload(), ctypes.c_uint32, render_start + RENDER_VERTEX_WORDS * th.render_vertex_count
    )
    words = (ctypes.c_uint32 * indices).from_address(topo.payload().as_ptr())
    # Render surfaces: each vertex follows four nodes by fixed weights (float32 bits).
    render = []
    for v in range(th.render_vertex_count):
        w = words[render_start + RENDER_VERTEX_WORDS * v : render_start + RENDER_VERTEX_WORDS * (v + 1)]
        weights = [ctypes.c_float.from_buffer_copy(ctypes.c_uint32(x)).value for x in w[4:]]
        render.append((list(w[:4]), weights))
    bodies = [th.bodies[i] for i in range(th.body_count)]
    print(
        f"topology {th.topology_id:#x}: {th.node_count} nodes, {th.triangle_count} triangles, "
        f"{th.tet_count} tets, {th.render_vertex_count} render vertices, {indices} indices; bodies "
        + ", ".join(f"{b.name_str()}[{b.node_offset}+{b.node_count}]" for b in bodies)
    )
    del words
    return th, render, bodies


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--prefix", default="lop")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--timeout", type=float, default=30.0)
    args = ap.parse_args()

    iox2.set_log_level(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)

    topo_service = open_retry(
        node, f"{args.prefix}/scene/topology", iox2.Slice[ctypes.c_uint32], TopologyHeader, args.timeout
    )
    topo_sub = topo_service.subscriber_builder().create()
    topo = receive(topo_sub, args.timeout, "topology")
    th, render, bodies = read_topology(topo)
    del topo

    frame_service = open_retry(
        node, f"{args.prefix}/scene/frame", iox2.Slice[NodeSample], FrameHeader, args.timeout
    )
    frame_sub = frame_service.subscriber_builder().create()
    got = 0
    all_finite = True
    while got < args.frames:
        sample = receive(frame_sub, args.timeout, "frame")
        h = sample.user_header().contents
        if h.contract_version != CONTRACT_VERSION:
            continue
        if h.topology_id != th.topology_id:
            # Another topology (a cut, or a restarted daemon): read it before drawing its
            # frames; frames of a topology not read yet are skipped.
            topo = topo_sub.receive()
            while topo is not None:
                th, render, bodies = read_topology(topo)
                del topo
                topo = topo_sub.receive()
            if h.topology_id != th.topology_id:
                del sample
                continue
        n = element_count(sample.payload(), NodeSample, h.node_count)
        nodes = (NodeSample * n).from_address(sample.payload().as_ptr())
        # A render vertex is drawn at the weighted sum of its nodes' positions.
        placed = [
            [sum(wk * nodes[k].position[d] for k, wk in zip(ks, ws)) for d in range(3)]
            for ks, ws in render
        ]
        finite = all(math.isfinite(c) for s in nodes for c in s.position) and all(
            math.isfinite(c) for p in placed for c in p
        )
        all_finite &= finite
        first = nodes[bodies[0].node_offset]
        models = " ".join(
            f"{b.name_str()}:{MODELS.get(h.bodies[i].model, '?')}" for i, b in enumerate(bodies)
        )
        print(
            f"frame {h.sequence}: t {h.sim_time:.3f} s, {n} nodes, finite {finite}, "
            f"{bodies[0].name_str()} node 0 at ({first.position[0]:.4f}, {first.position[1]:.4f}, "
            f"{first.position[2]:.4f}) m {first.temperature:.1f} C; {models}; "
            + contacts_text(h, bodies)
        )
        got += 1
        del sample
    tools = newest_tool_states(node, args.prefix, min(args.timeout, 5.0))
    if not tools:
        print("tool states: none (no haptic process publishes)")
    for t, s in sorted(tools.items()):
        body = bodies[s.contact_body].name_str() if 0 <= s.contact_body < len(bodies) else "none"
        force = math.sqrt(sum(c * c for c in s.force))
        print(
            f"tool {t}: tick {s.sequence}, device at ({s.device_position[0]:.4f}, "
            f"{s.device_position[1]:.4f}, {s.device_position[2]:.4f}) m, force {force:.3f} N, "
            f"touching {body}"
        )
    print(
        f"OK frames={got} nodes={th.node_count} bodies={th.body_count} "
        f"render_vertices={th.render_vertex_count} finite={all_finite}"
    )


if __name__ == "__main__":
    main()
