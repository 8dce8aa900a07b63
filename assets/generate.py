#!/usr/bin/env python3
"""Regenerate lop's shipped tetrahedral meshes (assets/meshes/*).

Plain Python 3 (standard library only) plus the `tetgen` binary (Debian package
`tetgen`, 1.5.0).  Run from anywhere:

    python3 assets/generate.py            # regenerate everything, validate, print counts
    python3 assets/generate.py --check    # build + validate in a temp dir, compare with the
                                          # committed files, write nothing

For every mesh the script
  1. builds a closed, watertight, outward (counter-clockwise seen from outside) triangulated
     surface analytically and checks it (every edge shared by exactly two triangles with
     opposite directions, Euler characteristic 2, positive enclosed volume, no
     self-intersection);
  2. for the organs, places them in one shared abdomen frame so neighbours touch with a
     ~1 mm gap, and proves that no two organs overlap;
  3. writes the surface as a TetGen `.smesh` and runs `tetgen -pq<ratio>/<angle>a<vol>YQ`
     (`-Y` keeps the surface exactly as built: no Steiner points on the boundary, so the
     fixed faces stay exactly planar and the organ gaps stay exactly as checked);
  4. keeps `<name>.node`, `<name>.ele`, `<name>.face` (TetGen's own numbering, from 1) and
     writes `<name>.bnd` (fixed nodes, same numbering);
  5. validates the result (tet orientation, degeneracy, dihedral angles, closed boundary equal
     to the input surface) and checks the counts against the thesis' targets.

Everything is deterministic: no randomness, fixed input coordinates, TetGen is deterministic
for a given input and switch string.

Coordinates (metres).  The organ meshes are already in the shared "abdomen" scene frame:
  +x = patient's left  (image right when the camera looks at the patient's front),
  +y = up = cranial (towards the head),
  +z = anterior (towards the camera / the surgeon).
This frame is right-handed.  "Back side" of an organ = posterior = its smallest z.
"""

import math
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
OUT_DIR = os.path.join(HERE, "meshes")
README = os.path.join(HERE, "README.md")
TETGEN = shutil.which("tetgen") or "/usr/bin/tetgen"


def fail(msg):
    sys.stderr.write("generate.py: ERROR: " + msg + "\n")
    sys.exit(1)


# ----------------------------------------------------------------------------------------
# Small vector helpers (tuples of 3 floats)
# ----------------------------------------------------------------------------------------


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    return math.sqrt(dot(a, a))


def unit(a):
    n = norm(a)
    return (a[0] / n, a[1] / n, a[2] / n)


def orient3d(a, b, c, d):
    """6 x signed volume of tet abcd; > 0 when d is on the side abc's CCW normal points to."""
    return dot(cross(sub(b, a), sub(c, a)), sub(d, a))


def frame(long_axis, toward):
    """Right-handed orthonormal frame (ex, ey, ez) with ex along long_axis and ez as close as
    possible to `toward` (Gram-Schmidt)."""
    ex = unit(long_axis)
    ez = unit(sub(toward, mul(ex, dot(toward, ex))))
    ey = cross(ez, ex)
    return ex, ey, ez


def to_world(p, fr, origin):
    ex, ey, ez = fr
    return (
        origin[0] + p[0] * ex[0] + p[1] * ey[0] + p[2] * ez[0],
        origin[1] + p[0] * ex[1] + p[1] * ey[1] + p[2] * ez[1],
        origin[2] + p[0] * ex[2] + p[1] * ey[2] + p[2] * ez[2],
    )


# ----------------------------------------------------------------------------------------
# Closed triangulated surfaces
# ----------------------------------------------------------------------------------------


class Surface:
    """A closed triangle surface: verts = list of (x, y, z), tris = list of (i, j, k), 0-based,
    counter-clockwise seen from outside."""

    def __init__(self, verts, tris):
        self.verts = verts
        self.tris = tris

    def translated(self, t):
        return Surface([add(v, t) for v in self.verts], list(self.tris))

    def bbox(self):
        lo = tuple(min(v[i] for v in self.verts) for i in range(3))
        hi = tuple(max(v[i] for v in self.verts) for i in range(3))
        return lo, hi

    def volume(self):
        return sum(orient3d((0.0, 0.0, 0.0), *[self.verts[i] for i in t]) for t in self.tris) / 6.0

    def edges(self):
        es = set()
        for a, b, c in self.tris:
            for u, v in ((a, b), (b, c), (c, a)):
                es.add((min(u, v), max(u, v)))
        return sorted(es)


def check_closed_surface(name, s):
    """Watertight + consistently oriented + outward + genus 0 + no degenerate triangles."""
    directed = {}
    for t, (a, b, c) in enumerate(s.tris):
        if len({a, b, c}) != 3:
            fail(f"{name}: triangle {t} repeats a vertex")
        for u, v in ((a, b), (b, c), (c, a)):
            if (u, v) in directed:
                fail(f"{name}: directed edge {u}->{v} used twice (inconsistent winding)")
            directed[(u, v)] = t
    for (u, v) in directed:
        if (v, u) not in directed:
            fail(f"{name}: edge {u}-{v} has one triangle only (surface not closed)")
    used = {i for t in s.tris for i in t}
    if len(used) != len(s.verts):
        fail(f"{name}: {len(s.verts) - len(used)} unused surface vertices")
    V, E, F = len(s.verts), len(directed) // 2, len(s.tris)
    if V - E + F != 2:
        fail(f"{name}: Euler characteristic {V - E + F} != 2")
    if s.volume() <= 0:
        fail(f"{name}: enclosed volume {s.volume()} <= 0 (inward winding)")
    min_angle = 180.0
    normals = []
    for a, b, c in s.tris:
        p = [s.verts[a], s.verts[b], s.verts[c]]
        n = cross(sub(p[1], p[0]), sub(p[2], p[0]))
        if norm(n) <= 1e-12:
            fail(f"{name}: degenerate triangle {(a, b, c)}")
        normals.append(unit(n))
        min_angle = min(min_angle, min(triangle_angles(*p)))
    if min_angle < 15.0:
        fail(f"{name}: a surface triangle has a {min_angle:.1f} degree angle (< 15)")
    # a fold (neighbouring triangles turning by more than 90 degrees) means a bad surface map
    for (u, v), t in directed.items():
        if u < v and dot(normals[t], normals[directed[(v, u)]]) < 0.0:
            fail(f"{name}: surface folds over at edge {u}-{v}")
    inter = self_intersections(s)
    if inter:
        fail(f"{name}: surface self-intersects ({inter} edge/triangle crossings)")
    return min_angle


def triangle_angles(a, b, c):
    out = []
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):
        u, v = sub(q, p), sub(r, p)
        cosv = dot(u, v) / (norm(u) * norm(v))
        out.append(math.degrees(math.acos(max(-1.0, min(1.0, cosv)))))
    return out


def box_lattice_surface(nx, ny, nz, point):
    """Boundary of an nx x ny x nz lattice, mapped by point(i, j, k) -> (x, y, z). Each
    boundary quad is split along its shorter (mapped) diagonal.  Outward for a map that
    preserves orientation."""
    n = (nx, ny, nz)
    index = {}
    verts = []

    def vid(ijk):
        if ijk not in index:
            index[ijk] = len(verts)
            verts.append(point(*ijk))
        return index[ijk]

    tris = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3  # e_b x e_c = e_a
        for side in (0, n[a]):
            for i in range(n[b]):
                for j in range(n[c]):
                    q = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        ijk = [0, 0, 0]
                        ijk[a], ijk[b], ijk[c] = side, i + di, j + dj
                        q.append(vid(tuple(ijk)))
                    if side == 0:  # outward normal is -e_a: reverse the quad
                        q = [q[0], q[3], q[2], q[1]]
                    d02 = norm(sub(verts[q[0]], verts[q[2]]))
                    d13 = norm(sub(verts[q[1]], verts[q[3]]))
                    if d02 <= d13 + 1e-12:
                        tris += [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
                    else:
                        tris += [(q[0], q[1], q[3]), (q[1], q[2], q[3])]
    return Surface(verts, tris)


def zip_rings(ring_a, ring_b, ang_a, ang_b):
    """Triangulate the band between two closed rings of vertex ids (angles increasing, within
    one turn) by always advancing the ring whose next vertex comes first in angle.
    Orientation is fixed by the caller."""
    na, nb = len(ring_a), len(ring_b)
    ia = ib = 0
    tris = []
    while ia < na or ib < nb:
        a0, a1 = ring_a[ia % na], ring_a[(ia + 1) % na]
        b0, b1 = ring_b[ib % nb], ring_b[(ib + 1) % nb]
        next_a = ang_a[(ia + 1) % na] + (2 * math.pi if ia + 1 >= na else 0.0)
        next_b = ang_b[(ib + 1) % nb] + (2 * math.pi if ib + 1 >= nb else 0.0)
        if ib >= nb or (ia < na and next_a <= next_b):
            tris.append((a0, a1, b0))
            ia += 1
        else:
            tris.append((a0, b1, b0))
            ib += 1
    return tris


def orient_outward(tris, verts, outward):
    """Flip the triangles of a band whose normals point against outward(centroid)."""
    out = []
    for t in tris:
        p = [verts[i] for i in t]
        n = cross(sub(p[1], p[0]), sub(p[2], p[0]))
        cen = mul(add(add(p[0], p[1]), p[2]), 1.0 / 3.0)
        out.append(t if dot(n, outward(cen)) > 0 else (t[0], t[2], t[1]))
    return out


def cylinder_surface(radius, height, n_around, n_rings, n_inner, inner_radius):
    """Upright (+y) cylinder, base at y = 0 centred on the y axis.  n_rings rings of
    n_around vertices on the side (every other ring rotated by half a step, which gives
    near-equilateral side triangles), each cap = outer ring + an inner ring of n_inner
    vertices (rotated by half a step against the outer ring) + a centre vertex."""
    verts, tris = [], []
    rings, angs = [], []
    step = 2 * math.pi / n_around
    for r in range(n_rings):
        y = height * r / (n_rings - 1)
        off = 0.5 * step if r % 2 else 0.0
        ids, aa = [], []
        for k in range(n_around):
            a = off + k * step
            ids.append(len(verts))
            aa.append(a)
            verts.append((radius * math.cos(a), y, radius * math.sin(a)))
        rings.append(ids)
        angs.append(aa)

    def radial(c):
        return (c[0], 0.0, c[2])

    for r in range(n_rings - 1):
        tris += orient_outward(zip_rings(rings[r], rings[r + 1], angs[r], angs[r + 1]),
                               verts, radial)
    for y, outer, oang, sign in ((0.0, rings[0], angs[0], -1.0),
                                 (height, rings[-1], angs[-1], 1.0)):
        istep = 2 * math.pi / n_inner
        inner, iang = [], []
        for k in range(n_inner):
            a = oang[0] + 0.5 * istep + k * istep
            inner.append(len(verts))
            iang.append(a)
            verts.append((inner_radius * math.cos(a), y, inner_radius * math.sin(a)))
        centre = len(verts)
        verts.append((0.0, y, 0.0))
        cap = zip_rings(outer, inner, oang, iang)
        cap += [(inner[k], inner[(k + 1) % n_inner], centre) for k in range(n_inner)]
        tris += orient_outward(cap, verts, lambda c, s=sign: (0.0, s, 0.0))
    return Surface(verts, tris)


# ----------------------------------------------------------------------------------------
# Organ shapes: star-shaped radial bodies, then injective analytic deformations
# ----------------------------------------------------------------------------------------


def smoothstep(e0, e1, x):
    t = max(0.0, min(1.0, (x - e0) / (e1 - e0)))
    return t * t * (3 - 2 * t)


def sphere_dir(i, j, k, n):
    """Lattice point on the boundary of [0,n0]x[0,n1]x[0,n2] -> unit direction, using the
    equal-angle (tan) warp of the cube-sphere so cells are close to uniform on the sphere."""
    w = [math.tan((2.0 * v / n[a] - 1.0) * math.pi / 4.0) for a, v in enumerate((i, j, k))]
    return unit(tuple(w))


def superball(d, e):
    """Point of |x|^e + |y|^e + |z|^e = 1 in direction d (unit)."""
    s = sum(abs(c) ** e for c in d) ** (1.0 / e)
    return mul(d, 1.0 / s)


def bend(p, radius, plane_axis=1):
    """Bend the x axis into a circular arc of the given radius whose centre is at
    +radius along `plane_axis` (1 = y, 2 = z).  Lengths along x are kept on the centre line;
    injective while |coordinate along plane_axis| < radius and |x| < pi * radius."""
    x = p[0]
    q = p[plane_axis]
    phi = x / radius
    nx = (radius - q) * math.sin(phi)
    nq = radius - (radius - q) * math.cos(phi)
    out = [nx, p[1], p[2]]
    out[plane_axis] = nq
    return tuple(out)


def organ_surface(kx, ky, kz, shape, fr, origin, smooth_iters=30):
    """Cube-sphere lattice (kx, ky, kz) -> unit directions d -> shape(d) -> scene frame.
    Afterwards the vertices are relaxed *within the analytic surface* (each vertex's
    direction d is moved so that shape(d) approaches the area-weighted centroid of its
    neighbouring triangles), which evens out the triangles that the bends and tapers
    stretch.  The surface itself does not change, only where its vertices sit on it."""
    n = (kx, ky, kz)
    dirs = {}

    def point(i, j, k):
        d = sphere_dir(i, j, k, n)
        dirs[len(dirs)] = d  # box_lattice_surface creates vertices in order
        return shape(d)

    s = box_lattice_surface(kx, ky, kz, point)
    d = [dirs[i] for i in range(len(s.verts))]
    s = relax_on_surface(s, d, shape, smooth_iters)
    return Surface([to_world(p, fr, origin) for p in s.verts], s.tris)


def relax_on_surface(s, dirs, shape, iters, step=0.5, h=1e-5):
    vt = [[] for _ in s.verts]  # triangles around each vertex
    for t, tri in enumerate(s.tris):
        for i in tri:
            vt[i].append(t)
    pos = list(s.verts)
    for _ in range(iters):
        new_dirs = []
        for i, d in enumerate(dirs):
            acc, area = (0.0, 0.0, 0.0), 0.0
            for t in vt[i]:
                a, b, c = [pos[j] for j in s.tris[t]]
                w = norm(cross(sub(b, a), sub(c, a)))
                acc = add(acc, mul(add(add(a, b), c), w / 3.0))
                area += w
            target = mul(acc, 1.0 / area)
            # Gauss-Newton step on the sphere's tangent plane towards the target
            helper = (1.0, 0.0, 0.0) if abs(d[0]) < 0.9 else (0.0, 1.0, 0.0)
            t1 = unit(cross(d, helper))
            t2 = cross(d, t1)
            f0 = pos[i]
            j1 = mul(sub(shape(unit(add(d, mul(t1, h)))), f0), 1.0 / h)
            j2 = mul(sub(shape(unit(add(d, mul(t2, h)))), f0), 1.0 / h)
            r = sub(target, f0)
            a11, a12, a22 = dot(j1, j1), dot(j1, j2), dot(j2, j2)
            b1, b2 = dot(j1, r), dot(j2, r)
            det = a11 * a22 - a12 * a12
            x1 = (a22 * b1 - a12 * b2) / det
            x2 = (a11 * b2 - a12 * b1) / det
            new_dirs.append(unit(add(d, add(mul(t1, step * x1), mul(t2, step * x2)))))
        dirs = new_dirs
        pos = [shape(d) for d in dirs]
    return Surface(pos, s.tris)


def liver_shape(d):
    # Local axes = scene axes (x patient's left, y up, z anterior). A big, somewhat boxy
    # lobe (right lobe, -x) tapering into a thin left lobe (+x): the inferior border rises
    # towards the left and the dome (superior surface) stays nearly level.
    p = superball(d, 2.6)
    x, y, z = p[0] * 0.100, p[1] * 0.085, p[2] * 0.056
    t = (p[0] + 1.0) / 2.0  # 0 = right edge, 1 = left tip
    f = 1.0 - 0.62 * t ** 1.3  # vertical thickness factor
    y = y * f + 0.5 * (1.0 - f) * 0.085  # keep the dome up, lift the inferior border
    z = z * (1.0 - 0.35 * t)
    # dome: the superior surface bulges up in the middle, the right lobe hangs lower
    y += 0.012 * (1.0 - p[0] * p[0]) - 0.010 * (1.0 - t)
    return (x, y, z)


def spleen_shape(d):
    # Local: x = long axis (11 cm), y = width (7 cm), z = thickness (4 cm); bent about y
    # with the centre of curvature on the local +z side (concave visceral face at +z).
    p = superball(d, 2.2)
    x, y, z = p[0] * 0.055, p[1] * 0.035, p[2] * 0.021
    z *= 1.0 - 0.25 * smoothstep(-0.055, 0.055, x)  # lower pole a little thinner
    return bend((x, y, z), 0.085, plane_axis=2)


def stomach_shape(d):
    # Local: x = axis of the sack, from pylorus (-x) to fundus (+x); y = in the bend plane;
    # z = depth.  Fat fundus/body, narrow antrum/pylorus; bent into a J (U, then rotated).
    p = superball(d, 2.4)
    s = p[0]
    w = smoothstep(-0.9, 0.4, s)  # 0 at pylorus end, 1 from the body to the fundus
    ry = 0.016 + 0.020 * w
    rz = 0.016 + 0.019 * w
    x, y, z = s * 0.095, p[1] * ry, p[2] * rz
    q = bend((x, y, z), 0.068, plane_axis=1)  # U opening upwards (+y)
    a = math.radians(32.0)  # rotate CCW about z: the fundus end (+x) rises
    c, sn = math.cos(a), math.sin(a)
    return (c * q[0] - sn * q[1], sn * q[0] + c * q[1], q[2])


def pancreas_shape(d):
    # Local: x = long axis from head (-x, patient's right, thick) to tail (+x, thin);
    # gently bent so the tail curves up towards the spleen.
    p = superball(d, 2.3)
    s = p[0]
    w = smoothstep(-0.7, 1.0, s)  # 0 = head, 1 = tail
    ry = 0.021 - 0.010 * w
    rz = 0.015 - 0.006 * w
    x, y, z = s * 0.086, p[1] * ry, p[2] * rz
    return bend((x, y, z), 0.22, plane_axis=1)


# ----------------------------------------------------------------------------------------
# Geometric queries: spatial hash, distances, intersections, inside test
# ----------------------------------------------------------------------------------------


class TriGrid:
    """Uniform grid of a surface's triangles for local queries."""

    def __init__(self, s, cell=0.006):
        self.s = s
        self.cell = cell
        self.cells = {}
        for t, tri in enumerate(s.tris):
            p = [s.verts[i] for i in tri]
            lo = [min(q[a] for q in p) for a in range(3)]
            hi = [max(q[a] for q in p) for a in range(3)]
            for key in self._keys(lo, hi):
                self.cells.setdefault(key, []).append(t)

    def _keys(self, lo, hi):
        c = self.cell
        r = [range(math.floor(lo[a] / c), math.floor(hi[a] / c) + 1) for a in range(3)]
        return [(i, j, k) for i in r[0] for j in r[1] for k in r[2]]

    def near(self, lo, hi):
        """Triangles whose cells overlap the box [lo, hi]."""
        out = set()
        for key in self._keys(lo, hi):
            out.update(self.cells.get(key, ()))
        return out


def closest_on_triangle(p, a, b, c):
    """Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab, ac, ap = sub(b, a), sub(c, a), sub(p, a)
    d1, d2 = dot(ab, ap), dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return a
    bp = sub(p, b)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return add(a, mul(ab, d1 / (d1 - d3)))
    cp = sub(p, c)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return add(a, mul(ac, d2 / (d2 - d6)))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        return add(b, mul(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))))
    den = 1.0 / (va + vb + vc)
    return add(a, add(mul(ab, vb * den), mul(ac, vc * den)))


def segment_segment_dist(p1, q1, p2, q2):
    """Distance between segments p1q1 and p2q2 (Ericson 5.1.9)."""
    d1, d2, r = sub(q1, p1), sub(q2, p2), sub(p1, p2)
    a, e, f = dot(d1, d1), dot(d2, d2), dot(d2, r)
    c = dot(d1, r)
    b = dot(d1, d2)
    den = a * e - b * b
    s = max(0.0, min(1.0, (b * f - c * e) / den)) if den > 1e-30 else 0.0
    t = (b * s + f) / e
    if t < 0:
        t, s = 0.0, max(0.0, min(1.0, -c / a))
    elif t > 1:
        t, s = 1.0, max(0.0, min(1.0, (b - c) / a))
    return norm(sub(add(p1, mul(d1, s)), add(p2, mul(d2, t))))


def segment_hits_triangle(p, q, a, b, c, eps=1e-12):
    """True if segment pq touches triangle abc (inclusive, conservative)."""
    d = sub(q, p)
    e1, e2 = sub(b, a), sub(c, a)
    h = cross(d, e2)
    det = dot(e1, h)
    if abs(det) < 1e-20:
        # parallel: coplanar only if p lies in the plane; treat coplanar overlap as a hit
        nrm = cross(e1, e2)
        if abs(dot(nrm, sub(p, a))) > 1e-15:
            return False
        return (norm(sub(closest_on_triangle(p, a, b, c), p)) < 1e-9 or
                norm(sub(closest_on_triangle(q, a, b, c), q)) < 1e-9)
    inv = 1.0 / det
    sv = sub(p, a)
    u = dot(sv, h) * inv
    if u < -eps or u > 1 + eps:
        return False
    qv = cross(sv, e1)
    v = dot(d, qv) * inv
    if v < -eps or u + v > 1 + eps:
        return False
    t = dot(e2, qv) * inv
    return -eps <= t <= 1 + eps


def self_intersections(s):
    grid = TriGrid(s, cell=max(1e-3, mean_edge(s) * 1.5))
    count = 0
    for u, v in s.edges():
        p, q = s.verts[u], s.verts[v]
        lo = [min(p[a], q[a]) for a in range(3)]
        hi = [max(p[a], q[a]) for a in range(3)]
        for t in grid.near(lo, hi):
            tri = s.tris[t]
            if u in tri or v in tri:
                continue
            if segment_hits_triangle(p, q, *[s.verts[i] for i in tri]):
                count += 1
    return count


def mean_edge(s):
    es = s.edges()
    return sum(norm(sub(s.verts[u], s.verts[v])) for u, v in es) / len(es)


def winding_number(p, s):
    """Generalised winding number of closed surface s around point p (1 inside, 0 outside)."""
    total = 0.0
    for i, j, k in s.tris:
        a, b, c = sub(s.verts[i], p), sub(s.verts[j], p), sub(s.verts[k], p)
        la, lb, lc = norm(a), norm(b), norm(c)
        num = dot(a, cross(b, c))
        den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
        total += 2.0 * math.atan2(num, den)
    return total / (4.0 * math.pi)


def point_surface_dist(p, s, grid, radius):
    """Distance from p to surface s, clamped to `radius` (returns radius if nothing closer)."""
    lo = [p[a] - radius for a in range(3)]
    hi = [p[a] + radius for a in range(3)]
    best = radius
    for t in grid.near(lo, hi):
        a, b, c = [s.verts[i] for i in s.tris[t]]
        dd = norm(sub(closest_on_triangle(p, a, b, c), p))
        if dd < best:
            best = dd
    return best


def surface_gap(s1, g1, s2, g2, radius, shift2=(0.0, 0.0, 0.0)):
    """min over vertex/triangle pairs in both directions, with s2 translated by shift2; the
    result is clamped to `radius`.  s1's grid g1, s2's grid g2 (built for the unshifted s2)."""
    best = radius
    lo1, hi1 = s1.bbox()
    lo2, hi2 = s2.bbox()
    lo2, hi2 = add(lo2, shift2), add(hi2, shift2)
    for v in s2.verts:
        p = add(v, shift2)
        if any(p[a] < lo1[a] - best or p[a] > hi1[a] + best for a in range(3)):
            continue
        best = min(best, point_surface_dist(p, s1, g1, best))
    neg = mul(shift2, -1.0)
    for v in s1.verts:
        if any(v[a] < lo2[a] - best or v[a] > hi2[a] + best for a in range(3)):
            continue
        best = min(best, point_surface_dist(add(v, neg), s2, g2, best))
    return best


def exact_gap(s1, s2, radius=0.02):
    """Exact minimum distance between two disjoint closed triangle surfaces (vertex-triangle
    both ways and edge-edge), clamped to radius."""
    g1, g2 = TriGrid(s1), TriGrid(s2)
    best = surface_gap(s1, g1, s2, g2, radius)
    lo2, hi2 = s2.bbox()
    for u, v in s1.edges():
        p, q = s1.verts[u], s1.verts[v]
        lo = [min(p[a], q[a]) - best for a in range(3)]
        hi = [max(p[a], q[a]) + best for a in range(3)]
        if any(hi[a] < lo2[a] or lo[a] > hi2[a] for a in range(3)):
            continue
        for t in g2.near(lo, hi):
            tri = s2.tris[t]
            for x, y in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                d = segment_segment_dist(p, q, s2.verts[x], s2.verts[y])
                if d < best:
                    best = d
    return best


def crossings(s1, s2):
    """Number of (edge of one surface, triangle of the other) pairs that touch."""
    count = 0
    for sa, sb in ((s1, s2), (s2, s1)):
        g = TriGrid(sb)
        lo_b, hi_b = sb.bbox()
        for u, v in sa.edges():
            p, q = sa.verts[u], sa.verts[v]
            lo = [min(p[a], q[a]) for a in range(3)]
            hi = [max(p[a], q[a]) for a in range(3)]
            if any(hi[a] < lo_b[a] or lo[a] > hi_b[a] for a in range(3)):
                continue
            for t in g.near(lo, hi):
                if segment_hits_triangle(p, q, *[sb.verts[i] for i in sb.tris[t]]):
                    count += 1
    return count


def vertices_inside(s1, s2):
    """Vertices of s1 strictly inside s2 (winding number > 1/2)."""
    lo, hi = s2.bbox()
    out = []
    for i, v in enumerate(s1.verts):
        if any(v[a] <= lo[a] or v[a] >= hi[a] for a in range(3)):
            continue
        if winding_number(v, s2) > 0.5:
            out.append(i)
    return out


# ----------------------------------------------------------------------------------------
# TetGen
# ----------------------------------------------------------------------------------------


def write_smesh(path, s):
    with open(path, "w") as f:
        f.write(f"{len(s.verts)} 3 0 0\n")
        for i, v in enumerate(s.verts):
            f.write(f"{i + 1} {v[0]:.9f} {v[1]:.9f} {v[2]:.9f}\n")
        f.write(f"{len(s.tris)} 0\n")
        for a, b, c in s.tris:
            f.write(f"3 {a + 1} {b + 1} {c + 1}\n")
        f.write("0\n0\n")


def read_table(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if line:
                rows.append(line.split())
    return rows


def run_tetgen(name, s, switches, workdir):
    """Tetrahedralise s with `tetgen -<switches>`; returns (nodes, tets, faces) with TetGen's
    1-based ids, and copies the kept files to the output directory later."""
    base = os.path.join(workdir, name)
    write_smesh(base + ".smesh", s)
    cmd = [TETGEN, "-" + switches, name + ".smesh"]
    res = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True)
    if res.returncode != 0:
        fail(f"{name}: {' '.join(cmd)} failed ({res.returncode}):\n{res.stdout}\n{res.stderr}")
    out = {}
    for ext in ("node", "ele", "face"):
        out[ext] = base + ".1." + ext
        if not os.path.exists(out[ext]):
            fail(f"{name}: tetgen produced no .{ext}")
    rows = read_table(out["node"])
    nn = int(rows[0][0])
    nodes = {int(r[0]): (float(r[1]), float(r[2]), float(r[3])) for r in rows[1:1 + nn]}
    rows = read_table(out["ele"])
    ne = int(rows[0][0])
    tets = [tuple(int(x) for x in r[1:5]) for r in rows[1:1 + ne]]
    rows = read_table(out["face"])
    nf = int(rows[0][0])
    faces = [tuple(int(x) for x in r[1:4]) for r in rows[1:1 + nf]]
    if len(nodes) != nn or len(tets) != ne or len(faces) != nf:
        fail(f"{name}: truncated tetgen output")
    return nodes, tets, faces, out


def dihedral_angles(p):
    """The six dihedral angles (degrees) of tet p[0..3]."""
    out = []
    for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)):
        k, m = [q for q in range(4) if q not in (i, j)]
        e = unit(sub(p[j], p[i]))
        u = sub(p[k], p[i])
        v = sub(p[m], p[i])
        u = sub(u, mul(e, dot(u, e)))
        v = sub(v, mul(e, dot(v, e)))
        c = dot(u, v) / (norm(u) * norm(v))
        out.append(math.degrees(math.acos(max(-1.0, min(1.0, c)))))
    return out


def validate_tets(name, s, nodes, tets, faces):
    """Checks the volume mesh; returns a dict of statistics."""
    ids = set(nodes)
    if ids != set(range(1, len(nodes) + 1)):
        fail(f"{name}: node ids are not 1..N")
    used = {i for t in tets for i in t}
    if used != ids:
        fail(f"{name}: {len(ids - used)} nodes belong to no tetrahedron")
    vols = []
    min_dih, max_dih = 180.0, 0.0
    for t in tets:
        p = [nodes[i] for i in t]
        vols.append(orient3d(*p) / 6.0)
        d = dihedral_angles(p)
        min_dih, max_dih = min(min_dih, min(d)), max(max_dih, max(d))
    positive = sum(1 for v in vols if v > 0)
    if positive not in (0, len(vols)):
        fail(f"{name}: mixed tetrahedron orientation ({positive} of {len(vols)} positive)")
    sign = 1.0 if positive else -1.0
    mean = sum(abs(v) for v in vols) / len(vols)
    vmin = min(abs(v) for v in vols)
    if vmin < 1e-4 * mean:
        fail(f"{name}: degenerate tetrahedron (volume {vmin:.3e} vs mean {mean:.3e})")
    total = sum(abs(v) for v in vols)
    if abs(total - s.volume()) > 1e-6 * s.volume():
        fail(f"{name}: tets fill {total:.9e} m^3 but the surface encloses {s.volume():.9e}")
    # boundary of the tet complex: faces that belong to one tet only
    count = {}
    for t in tets:
        for f in ((t[0], t[1], t[2]), (t[0], t[1], t[3]), (t[0], t[2], t[3]), (t[1], t[2], t[3])):
            key = tuple(sorted(f))
            count[key] = count.get(key, 0) + 1
    if any(c > 2 for c in count.values()):
        fail(f"{name}: a face is shared by more than two tetrahedra")
    boundary = {k for k, c in count.items() if c == 1}
    face_set = {tuple(sorted(f)) for f in faces}
    if boundary != face_set or len(face_set) != len(faces):
        fail(f"{name}: .face differs from the boundary of the tetrahedra")
    # -Y: the boundary must be exactly the input surface (same points, same triangles)
    surf_ids = sorted({i for f in faces for i in f})
    if len(surf_ids) != len(s.verts):
        fail(f"{name}: {len(surf_ids)} boundary nodes but the input surface has {len(s.verts)}")
    for i, v in enumerate(s.verts):
        if norm(sub(nodes[i + 1], v)) > 1e-8:
            fail(f"{name}: tetgen moved input vertex {i + 1}")
    in_tris = {tuple(sorted((a + 1, b + 1, c + 1))) for a, b, c in s.tris}
    if in_tris != face_set:
        fail(f"{name}: tetgen changed the surface triangulation")
    # closed + consistently oriented boundary; orientation of .face relative to the solid
    directed = set()
    for a, b, c in faces:
        for e in ((a, b), (b, c), (c, a)):
            if e in directed:
                fail(f"{name}: .face not consistently oriented")
            directed.add(e)
    if any((b, a) not in directed for a, b in directed):
        fail(f"{name}: .face boundary not closed")
    fvol = sum(orient3d((0.0, 0.0, 0.0), *[nodes[i] for i in f]) for f in faces) / 6.0
    return {
        "tet_sign": "positive" if sign > 0 else "negative",
        "face_winding": "outward" if fvol > 0 else "inward",
        "min_dihedral": min_dih,
        "max_dihedral": max_dih,
        "vol_ratio": vmin / mean,
        "surface_nodes": len(surf_ids),
    }


# ----------------------------------------------------------------------------------------
# Organ placement in the shared abdomen frame
# ----------------------------------------------------------------------------------------

CONTACT_GAP = 0.001  # target gap between touching organs (m)
SEARCH_RADIUS = 0.010  # distance queries are clamped here (m)


def slide_into_contact(name, mover, placed, direction, gap=CONTACT_GAP, max_travel=0.15):
    """Translate `mover` along `direction` (conservative advancement) until its vertex/triangle
    distance to the nearest already placed surface equals `gap`.  Each step is no longer than
    the current vertex/triangle clearance minus `gap`, so the surfaces do not jump through
    each other on the way; check_organ_layout verifies the final layout exactly."""
    d = unit(direction)
    gm = TriGrid(mover)
    t = 0.0
    for _ in range(1000):
        shift = mul(d, t)
        g = min(surface_gap(s, gs, mover, gm, SEARCH_RADIUS, shift) for s, gs in placed)
        if g < gap - 1e-7:
            fail(f"{name}: starts {g * 1e3:.2f} mm from a placed organ (< gap); move it away")
        if g - gap < 2e-6:
            break
        t += g - gap
        if t > max_travel:
            fail(f"{name}: slid {t:.3f} m along {direction} without touching anything")
    else:
        fail(f"{name}: contact search did not converge")
    t = math.floor(t * 1e6) / 1e6  # whole micrometres: stable, and rounding away from contact
    return mover.translated(mul(d, t)), mul(d, t)


# ----------------------------------------------------------------------------------------
# The meshes
# ----------------------------------------------------------------------------------------

IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

# Organs, in placement order.  grid = cube-sphere subdivisions (surface triangles =
# 4 (kx ky + ky kz + kz kx)); frame/origin = where the local shape goes in the scene;
# slide = direction along which the organ is pushed from `origin` until it is CONTACT_GAP
# from the organs placed before it (None: stays where it is).
ORGANS = [
    dict(name="liver", grid=(12, 8, 7), shape=liver_shape, frame=IDENTITY,
         origin=(-0.070, 0.060, 0.0), slide=None),
    dict(name="stomach", grid=(10, 6, 5), shape=stomach_shape, frame=IDENTITY,
         origin=(0.075, -0.010, 0.0), slide=(-1.0, 0.5, 0.0)),
    dict(name="spleen", grid=(8, 6, 4), shape=spleen_shape,
         frame=frame((0.35, 1.0, -0.25), (-1.0, 0.0, 0.6)),
         origin=(0.170, 0.030, -0.050), slide=(-1.0, 0.0, 0.4)),
    dict(name="pancreas", grid=(14, 4, 3), shape=pancreas_shape,
         frame=frame((1.0, 0.12, 0.0), (0.0, 0.0, 1.0)),
         origin=(0.010, -0.090, -0.050), slide=(0.0, 1.0, 0.3)),
]


# Render surfaces: the same analytic organ sampled finer than its mesh's boundary, written as
# <name>.render.obj for the scene to draw the organ by (each vertex follows the tetrahedron it
# lies in).  Only organs that stay where their origin puts them (slide None).
RENDER_GRIDS = {"liver": (24, 16, 14)}


def write_obj(path, s, comment):
    with open(path, "w") as f:
        f.write(f"# {comment}\n")
        for p in s.verts:
            f.write(f"v {p[0]!r} {p[1]!r} {p[2]!r}\n")
        for t in s.tris:
            f.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")


# Pairs that must touch (gap <= 2 mm).  The stomach touches all three others, as in the
# thesis (section 6.3: "the stomach is near all the other organs").
CONTACTS = [("liver", "stomach"), ("stomach", "spleen"), ("stomach", "pancreas"),
            ("spleen", "pancreas")]


def build_organs(verbose=True):
    """Builds, checks and places the organ surfaces; returns {name: Surface} in scene frame."""
    placed = []
    out = {}
    for o in ORGANS:
        s = organ_surface(*o["grid"], o["shape"], o["frame"], o["origin"])
        check_closed_surface(o["name"], s)
        if o["slide"] is not None:
            s, t = slide_into_contact(o["name"], s, placed, o["slide"])
            if verbose:
                print(f"  {o['name']}: slid {norm(t) * 1e3:.1f} mm along {o['slide']}")
        placed.append((s, TriGrid(s)))
        out[o["name"]] = s
    return out


def check_organ_layout(surfaces, verbose=True):
    """No organ overlaps another (no vertex inside another organ, no edge crossing another
    organ's triangle, every pair >= 0.5 mm apart) and every pair in CONTACTS is <= 2 mm
    apart.  Returns {(a, b): exact minimum distance}."""
    names = list(surfaces)
    gaps = {}
    for ia, a in enumerate(names):
        for b in names[ia + 1:]:
            sa, sb = surfaces[a], surfaces[b]
            ins_ab, ins_ba = vertices_inside(sa, sb), vertices_inside(sb, sa)
            if ins_ab or ins_ba:
                fail(f"{a}/{b} overlap: {len(ins_ab)} {a} vertices inside {b}, "
                     f"{len(ins_ba)} {b} vertices inside {a}")
            x = crossings(sa, sb)
            if x:
                fail(f"{a}/{b} surfaces intersect ({x} edge/triangle crossings)")
            g = exact_gap(sa, sb, radius=0.25)
            if g < 0.0005:
                fail(f"{a}/{b} are only {g * 1e3:.3f} mm apart (< 0.5 mm)")
            gaps[(a, b)] = g
    for a, b in CONTACTS:
        g = gaps[(a, b)] if (a, b) in gaps else gaps[(b, a)]
        if g > 0.002:
            fail(f"{a} and {b} should touch but are {g * 1e3:.2f} mm apart (> 2 mm)")
    if verbose:
        for (a, b), g in gaps.items():
            print(f"  gap {a:8s} - {b:8s}: {g * 1e3:.3f} mm")
    return gaps


def fixed_by_plane(axis, value, tol=1e-9):
    """All nodes on the plane coordinate[axis] == value; returns (ids, .bnd comment)."""
    def rule(nodes, surface_ids):
        ids = [i for i in sorted(nodes) if abs(nodes[i][axis] - value) <= tol]
        return ids, f"fixed: {what} {'xyz'[axis]} = {value:g}"
    what = {0: "wall face", 1: "base"}[axis]
    return rule


def fixed_posterior_patch(depth):
    """Surface nodes within `depth` of the organ's most posterior point (smallest z), standing
    for the ligaments that hold the organ; returns (ids, .bnd comment)."""
    def rule(nodes, surface_ids):
        zmin = min(nodes[i][2] for i in surface_ids)
        ids = [i for i in sorted(surface_ids) if nodes[i][2] <= zmin + depth]
        return ids, (f"fixed: posterior patch (ligaments): surface nodes with "
                     f"z <= min z + {depth * 1e3:g} mm = {zmin + depth:.5f} m")
    return rule


# name -> tetgen switches, targets from the thesis, fixed-node rule
# Switches: -p piecewise-linear complex, -q<ratio>/<min dihedral> quality, -a<vol> max
# tet volume (m^3), -Y keep the boundary exactly as given, -Q quiet.
MESHES = {
    "beam": dict(switches="pq1.6/12YQ", targets=dict(nodes=604, tets=1750),
                 fixed=fixed_by_plane(0, 0.0)),
    "cylinder": dict(switches="pq1.4/12a6e-7YQ",
                     targets=dict(nodes=252, tets=939, faces=336),
                     fixed=fixed_by_plane(1, 0.0)),
    "liver": dict(switches="pq2/10YQ", targets=dict(nodes=504, tets=1578, faces=1004),
                  fixed=fixed_posterior_patch(0.004)),
    "spleen": dict(switches="pq2/10YQ", targets=dict(nodes=218, tets=661, faces=432),
                   fixed=fixed_posterior_patch(0.005)),
    "stomach": dict(switches="pq2/10YQ", targets=dict(nodes=291, tets=890, faces=578),
                    fixed=fixed_posterior_patch(0.005)),
    "pancreas": dict(switches="pq2/10YQ", targets=dict(nodes=229, tets=657, faces=454),
                     fixed=fixed_posterior_patch(0.001)),
}


def build_surfaces(verbose=True):
    surfaces = {
        # 0.40 x 0.10 x 0.10 bar, x = 0 is the wall; 22 x 5 x 5 surface cells
        "beam": box_lattice_surface(
            22, 5, 5, lambda i, j, k: (0.4 * i / 22, 0.1 * j / 5 - 0.05, 0.1 * k / 5 - 0.05)),
        # r = 0.03, h = 0.12, 14 around x 11 rings, caps with an inner ring of 7 + centre
        "cylinder": cylinder_surface(0.03, 0.12, 14, 11, 7, 0.016),
    }
    for n in ("beam", "cylinder"):
        check_closed_surface(n, surfaces[n])
    if verbose:
        print("placing organs:")
    organs = build_organs(verbose)
    if verbose:
        print("checking organ layout:")
    gaps = check_organ_layout(organs, verbose)
    surfaces.update(organs)
    return surfaces, gaps


def write_bnd(path, comment, ids, name):
    with open(path, "w") as f:
        f.write(f"# {comment}\n")
        f.write(f"# {len(ids)} node ids, numbered as in {name}.node (first node = 1)\n")
        f.write(f"{len(ids)}\n")
        for i in ids:
            f.write(f"{i}\n")


def tetgen_version():
    try:
        r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "tetgen"],
                           capture_output=True, text=True)
        if r.returncode == 0 and r.stdout.strip():
            return "TetGen " + r.stdout.strip() + " (Debian package tetgen)"
    except OSError:
        pass
    return "TetGen (version unknown)"


def generate(out_dir, verbose=True):
    if not os.path.exists(TETGEN):
        fail("tetgen not found: apt-get install tetgen")
    surfaces, gaps = build_surfaces(verbose)
    os.makedirs(out_dir, exist_ok=True)
    rows = []
    problems = []
    with tempfile.TemporaryDirectory() as work:
        for name, spec in MESHES.items():
            s = surfaces[name]
            nodes, tets, faces, files = run_tetgen(name, s, spec["switches"], work)
            st = validate_tets(name, s, nodes, tets, faces)
            surface_ids = sorted({i for f in faces for i in f})
            fixed, comment = spec["fixed"](nodes, surface_ids)
            if not fixed:
                fail(f"{name}: no fixed nodes")
            for ext in ("node", "ele", "face"):
                shutil.copyfile(files[ext], os.path.join(out_dir, f"{name}.{ext}"))
            write_bnd(os.path.join(out_dir, f"{name}.bnd"), comment, fixed, name)
            lo, hi = s.bbox()
            counts = dict(nodes=len(nodes), tets=len(tets), faces=len(faces))
            for k, target in spec["targets"].items():
                dev = counts[k] / target - 1.0
                if abs(dev) > 0.25:
                    problems.append(f"{name}: {k} = {counts[k]}, target {target} ({dev:+.0%})")
            rows.append(dict(name=name, counts=counts, targets=spec["targets"],
                             fixed=len(fixed), stats=st, lo=lo, hi=hi,
                             switches=spec["switches"]))
    for name, grid in RENDER_GRIDS.items():
        o = next(o for o in ORGANS if o["name"] == name)
        assert o["slide"] is None, name
        s = organ_surface(*grid, o["shape"], o["frame"], o["origin"])
        check_closed_surface(f"{name} (render)", s)
        write_obj(os.path.join(out_dir, f"{name}.render.obj"), s,
                  f"{name}: render surface, the organ's analytic shape on a {grid} cube-sphere "
                  f"lattice ({len(s.verts)} vertices, {len(s.tris)} triangles), scene frame, m")
    return rows, gaps, problems


def fmt_count(row, key):
    c = row["counts"][key]
    t = row["targets"].get(key)
    return f"{c} ({t}, {c / t - 1:+.0%})" if t else f"{c}"


def count_table(rows):
    lines = [
        "| mesh | nodes (thesis, dev.) | tets (thesis, dev.) | surface triangles (thesis, dev.) "
        "| fixed nodes | size x × y × z (m) | min/max dihedral | tetgen switches |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        size = " × ".join(f"{r['hi'][a] - r['lo'][a]:.3f}" for a in range(3))
        pct = 100.0 * r["fixed"] / r["counts"]["nodes"]
        lines.append(
            f"| {r['name']} | {fmt_count(r, 'nodes')} | {fmt_count(r, 'tets')} | "
            f"{fmt_count(r, 'faces')} | {r['fixed']} ({pct:.1f} %) | {size} | "
            f"{r['stats']['min_dihedral']:.1f}° / {r['stats']['max_dihedral']:.1f}° | "
            f"`-{r['switches']}` |")
    return "\n".join(lines)


def placement_table(rows, gaps):
    lines = ["| organ | x range (m) | y range (m) | z range (m) |", "|---|---|---|---|"]
    for r in rows:
        if r["name"] in ("beam", "cylinder"):
            continue
        rng = [f"{r['lo'][a]:+.3f} … {r['hi'][a]:+.3f}" for a in range(3)]
        lines.append(f"| {r['name']} | " + " | ".join(rng) + " |")
    lines += ["", "| pair | minimum distance |", "|---|---|"]
    for (a, b), g in gaps.items():
        lines.append(f"| {a} – {b} | {g * 1e3:.2f} mm |")
    return "\n".join(lines)


def update_readme(rows, gaps):
    begin, end = "<!-- generated:begin -->", "<!-- generated:end -->"
    if not os.path.exists(README):
        print("note: assets/README.md missing, tables not written")
        return
    text = open(README).read()
    if begin not in text or end not in text:
        print("note: assets/README.md has no generated-section markers, tables not written")
        return
    body = (f"{begin}\n<!-- written by assets/generate.py; do not edit by hand -->\n\n"
            f"Generated with {tetgen_version()}.\n\n{count_table(rows)}\n\n"
            f"{placement_table(rows, gaps)}\n{end}")
    new = text[:text.index(begin)] + body + text[text.index(end) + len(end):]
    if new != text:
        with open(README, "w") as f:
            f.write(new)


def main(argv):
    if "--check" in argv:
        with tempfile.TemporaryDirectory() as tmp:
            rows, gaps, problems = generate(tmp)
            report(rows, problems)
            names = sorted(set(os.listdir(tmp)) | set(os.listdir(OUT_DIR)))
            stale = [f for f in names
                     if not same_file(os.path.join(tmp, f), os.path.join(OUT_DIR, f))]
        if stale:
            fail("regenerated files differ from assets/meshes: " + ", ".join(stale))
        print("check: assets/meshes is up to date")
    else:
        rows, gaps, problems = generate(OUT_DIR)
        report(rows, problems)
        update_readme(rows, gaps)
        print(f"wrote {len(rows)} meshes to {os.path.relpath(OUT_DIR)}")


def same_file(a, b):
    if not (os.path.exists(a) and os.path.exists(b)):
        return False
    with open(a, "rb") as fa, open(b, "rb") as fb:
        return fa.read() == fb.read()


def report(rows, problems):
    print()
    print(count_table(rows))
    print()
    for r in rows:
        st = r["stats"]
        print(f"  {r['name']}: tets {st['tet_sign']}ly oriented, .face wound {st['face_winding']},"
              f" smallest tet {st['vol_ratio']:.3f} x mean volume")
    if problems:
        fail("counts far from the thesis' targets:\n  " + "\n  ".join(problems))


if __name__ == "__main__":
    main(sys.argv[1:])
