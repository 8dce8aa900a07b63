"""fTetWild through PyPI pytetwild, for `lopd mesh tetrahedralize --mesher ftetwild`
(daemon/src/mesher/ftetwild.rs writes the surface and reads the result back).

usage: python3 ftetwild.py SURFACE_TXT EDGE EPSILON OUT_BASE

SURFACE_TXT: `<#vertices> <#triangles>`, then x y z per vertex, then a b c per triangle
(0-based). EDGE: the target edge length, in the surface's units. EPSILON: the envelope, as a
fraction of the bounding box diagonal. Writes OUT_BASE.node and OUT_BASE.ele (TetGen format,
numbered from 0) and prints `tets <n>`.
"""

import sys

import numpy as np
import pytetwild

surface, edge, epsilon, out = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
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
    num_threads=1,
)
with open(out + ".node", "w") as f:
    f.write(f"{len(points)} 3 0 0\n")
    for i, p in enumerate(points):
        f.write(f"{i} {float(p[0])!r} {float(p[1])!r} {float(p[2])!r}\n")
with open(out + ".ele", "w") as f:
    f.write(f"{len(tets)} 4 0\n")
    for i, t in enumerate(tets):
        f.write(f"{i} {t[0]} {t[1]} {t[2]} {t[3]}\n")
print("tets", len(tets))
