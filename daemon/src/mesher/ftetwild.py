"""fTetWild through PyPI pytetwild, for `lopd mesh tetrahedralize --mesher ftetwild`
(daemon/src/mesher/ftetwild.rs writes the surface and reads the result back).

usage: python3 ftetwild.py SURFACE_TXT EDGE EPSILON OUT_BASE volume|surface

SURFACE_TXT: `<#vertices> <#triangles>`, then x y z per vertex, then a b c per triangle
(0-based). EDGE: the target edge length, in the surface's units. EPSILON: the envelope, as a
fraction of the bounding box diagonal. `volume`: optimised tetrahedra, written as
OUT_BASE.node and OUT_BASE.ele (TetGen format, numbered from 0). `surface` (the repair):
fTetWild optimised only to a loose energy (seconds, not a minute: only the boundary is
wanted), whose boundary is written outward-wound as OUT_BASE.obj. Prints `tets <n>`.
"""

import sys

import numpy as np
import pytetwild

surface, edge, epsilon, out, mode = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4], sys.argv[5]
with open(surface) as f:
    nv, nf = map(int, f.readline().split())
    data = np.loadtxt(f, ndmin=2) if nv + nf else np.zeros((0, 3))
vertices = np.ascontiguousarray(data[:nv, :3], dtype=np.float64)
faces = np.ascontiguousarray(data[nv : nv + nf, :3], dtype=np.int32)
# One thread: the machine's other core belongs to the haptic loop.
points, tets = pytetwild.tetrahedralize(
    vertices,
    faces,
    edge_length_abs=edge,
    epsilon=epsilon,
    optimize=True,
    # The repair wants the boundary, not good tetrahedra: a looser stop (fTetWild's default
    # energy is 10) takes seconds instead of a minute.
    stop_energy=10.0 if mode == "volume" else 100.0,
    num_threads=1,
)
print("tets", len(tets))
if mode == "surface":
    # The faces of one tetrahedron only, wound away from its fourth corner.
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    flip = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) < 0
    t = tets.copy()
    t[flip] = t[flip][:, [0, 2, 1, 3]]
    faces = np.concatenate([t[:, [0, 2, 1]], t[:, [0, 1, 3]], t[:, [0, 3, 2]], t[:, [1, 2, 3]]])
    _, inverse, count = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    boundary = faces[count[inverse.ravel()] == 1]
    used, boundary = np.unique(boundary, return_inverse=True)
    boundary = boundary.reshape(-1, 3)
    with open(out + ".obj", "w") as f:
        f.write("# fTetWild's boundary\n")
        for p in points[used]:
            f.write(f"v {float(p[0])!r} {float(p[1])!r} {float(p[2])!r}\n")
        for x, y, z in boundary:
            f.write(f"f {x + 1} {y + 1} {z + 1}\n")
    sys.exit(0)
with open(out + ".node", "w") as f:
    f.write(f"{len(points)} 3 0 0\n")
    for i, p in enumerate(points):
        f.write(f"{i} {float(p[0])!r} {float(p[1])!r} {float(p[2])!r}\n")
with open(out + ".ele", "w") as f:
    f.write(f"{len(tets)} 4 0\n")
    for i, t in enumerate(tets):
        f.write(f"{i} {t[0]} {t[1]} {t[2]} {t[3]}\n")
