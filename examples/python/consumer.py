#!/usr/bin/env python3
"""A third-party renderer's first step: read lop's scene from shared memory, in Python.

Opens PREFIX/scene/topology and PREFIX/scene/frame read-only with the `iceoryx2` package from
PyPI (exactly the version lopd uses: 0.10.0; `pip install iceoryx2==0.10.0`), maps the payloads
with ctypes structures that mirror docs/ipc.md (and ipc/include/lop_ipc.h), and prints a few
frames. No lop code is linked or imported.

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

CONTRACT_VERSION = 9
MAX_BODIES = 16
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
        ("contact_proxy", ctypes.c_double * 3),
        ("contact_body", ctypes.c_uint32),
        ("_pad2", ctypes.c_uint32),
        ("contact_force", ctypes.c_double * 3),
        ("contact_device", ctypes.c_double * 3),
        ("contact_stiffness", ctypes.c_double * 9),
        ("contact_drift", ctypes.c_double * 3),
        ("contact_horizon", ctypes.c_double),
        ("contact_local", ctypes.c_uint32),
        ("_pad3", ctypes.c_uint32),
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
assert ctypes.sizeof(FrameHeader) == 1160 and ctypes.alignment(FrameHeader) == 8
assert ctypes.sizeof(NodeSample) == 20
assert ctypes.sizeof(TopologyHeader) == 1448


def open_retry(node, name, payload, header, timeout):
    """Opens an existing service (never creates one), retrying while lopd starts."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return (
                node.service_builder(iox2.ServiceName.new(name))
                .publish_subscribe(payload)
                .user_header(header)
                .open()
            )
        except Exception as e:  # the binding raises its own *OpenError types
            if time.monotonic() > deadline:
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


def element_count(slice_, element_type, expected):
    """The binding's slice length is in bytes; accept elements too, in case that changes."""
    n = slice_.len()
    if n == expected * ctypes.sizeof(element_type):
        return expected
    if n == expected:
        return expected
    sys.exit(f"consumer: payload length {n} fits neither {expected} elements nor their bytes")


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
    th = topo.user_header().contents
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

    frame_service = open_retry(
        node, f"{args.prefix}/scene/frame", iox2.Slice[NodeSample], FrameHeader, args.timeout
    )
    frame_sub = frame_service.subscriber_builder().create()
    got = 0
    all_finite = True
    while got < args.frames:
        sample = receive(frame_sub, args.timeout, "frame")
        h = sample.user_header().contents
        if h.contract_version != CONTRACT_VERSION or h.topology_id != th.topology_id:
            continue  # another topology: a renderer would re-read the topology here
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
            f"{first.position[2]:.4f}) m {first.temperature:.1f} C; {models}"
        )
        got += 1
        del sample
    print(
        f"OK frames={got} nodes={th.node_count} bodies={th.body_count} "
        f"render_vertices={th.render_vertex_count} finite={all_finite}"
    )


if __name__ == "__main__":
    main()
