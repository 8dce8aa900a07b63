"""Built organ surfaces for the meshing figures (docs/benchmarks.md, "Meshing"), as binary
STL in millimetres:

  liver.stl           a 20 cm two-lobed liver-like surface, 2,562 vertices, 5,120 triangles
  ellipsoid.stl       12 x 8 x 6 cm, 1,280 triangles
  kidney.stl          an 11 cm bean with a hilum, 1,280 triangles
  liver_crossing.stl  the liver and a lobe overlapping it, in one file: crossing triangles
  liver_holes.stl     the liver with the triangles around 3 vertices removed (3 holes)

usage: python3 scripts/mesh_surfaces.py OUT_DIR   (needs numpy)
"""
import os
import struct
import sys

import numpy as np

out = sys.argv[1]
os.makedirs(out, exist_ok=True)

def icosphere(level):
    t = (1 + 5 ** 0.5) / 2
    v = [[-1,t,0],[1,t,0],[-1,-t,0],[1,-t,0],[0,-1,t],[0,1,t],[0,-1,-t],[0,1,-t],[t,0,-1],[t,0,1],[-t,0,-1],[-t,0,1]]
    f = [[0,11,5],[0,5,1],[0,1,7],[0,7,10],[0,10,11],[1,5,9],[5,11,4],[11,10,2],[10,7,6],[7,1,8],
         [3,9,4],[3,4,2],[3,2,6],[3,6,8],[3,8,9],[4,9,5],[2,4,11],[6,2,10],[8,6,7],[9,8,1]]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(level):
        cache = {}
        def mid(a, b):
            k = (min(a, b), max(a, b))
            if k not in cache:
                m = v[a] + v[b]; v.append(m / np.linalg.norm(m)); cache[k] = len(v) - 1
            return cache[k]
        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    return np.array(v), np.array(f)

def write_stl(name, v, f):
    with open(os.path.join(out, name), 'wb') as fh:
        fh.write(b'lop test surface'.ljust(80, b' '))
        fh.write(struct.pack('<I', len(f)))
        for t in f:
            a, b, c = v[t]
            n = np.cross(b - a, c - a); n = n / (np.linalg.norm(n) or 1)
            fh.write(struct.pack('<12fH', *n, *a, *b, *c, 0))

def liver(u):
    x, y, z = u[:, 0], u[:, 1], u[:, 2]
    # Two lobes (a big right one, a smaller left one), flattened, with a dome on top.
    r = 1 + 0.18 * np.cos(2 * np.arctan2(y, x)) * (1 - z ** 2) + 0.08 * np.sin(3 * np.arctan2(y, x) + 0.5) * (1 - z ** 2)
    p = u * r[:, None] * np.array([100.0, 70.0, 45.0])
    p[:, 2] += 12 * (1 - (p[:, 0] / 110) ** 2) * (p[:, 2] > 0)   # dome
    p[:, 2] -= 0.25 * p[:, 0] * (p[:, 0] < 0) * 0.5                # left lobe tapers
    return p

def kidney(u):
    p = u * np.array([55.0, 30.0, 25.0])
    # Bend into a bean: pull the middle of one side in (the hilum).
    p[:, 1] -= 14 * np.exp(-(p[:, 0] / 25) ** 2) * (p[:, 1] > -5) * np.clip((p[:, 1] + 5) / 35, 0, 1)
    p[:, 1] += 0.004 * p[:, 0] ** 2 - 6
    return p

v4, f4 = icosphere(4)  # 2562 vertices, 5120 triangles
v3, f3 = icosphere(3)  # 642, 1280
write_stl('liver.stl', liver(v4), f4)
write_stl('ellipsoid.stl', v3 * np.array([60.0, 40.0, 30.0]), f3)
write_stl('kidney.stl', kidney(v3), f3)

# Crossing triangles: a caudate-like lobe segmented apart, overlapping the liver, saved in the
# same file (two closed sheets crossing along a loop).
lobe = v3 * np.array([35.0, 30.0, 28.0]) + np.array([60.0, 30.0, 20.0])
write_stl('liver_crossing.stl', np.concatenate([liver(v4), lobe]),
          np.concatenate([f4, f3 + len(v4)]))
# Holes: remove triangles around 3 vertices.
rng = np.random.default_rng(7)
hv = rng.choice(len(v4), 3, replace=False)
keep = [t for t in f4 if not set(t.tolist()) & set(hv.tolist())]
write_stl('liver_holes.stl', liver(v4), np.array(keep))
for h in hv:
    print('hole at', liver(v4)[h])
