"""Writes one tetrahedral mesh and its boundary surface in every format meshio offers that lop
reads, for sim/tests/mesh/mesh_meshio.rs: lop must read each file back to the counts, volume and
area computed here with numpy (independently of lop).

usage: python3 meshio_write.py <out dir>

The mesh is a 4x3x2 grid of boxes, each split into 6 tetrahedra around its main diagonal
(a conforming Kuhn subdivision), scaled and shifted so that coordinates are not round numbers.
Prints `<key> <value>` lines: the reference values, then `file <name> <kind>` for each file
written (kind: volume, volume32, surface, surface32 for single precision, refused).
"""

import itertools
import os
import sys

import meshio
import numpy as np

out = sys.argv[1]
os.makedirs(out, exist_ok=True)

NX, NY, NZ = 4, 3, 2
H = np.array([0.011, 0.0073, 0.0129])
ORIGIN = np.array([0.1, -0.2, 0.035])


def node(i, j, k):
    return (k * (NY + 1) + j) * (NX + 1) + i


points = np.array(
    [
        ORIGIN + H * np.array([i, j, k])
        for k in range(NZ + 1)
        for j in range(NY + 1)
        for i in range(NX + 1)
    ],
    dtype=np.float64,
)

# Kuhn: the 6 paths from corner 000 to 111 along the unit steps.
tets = []
for i, j, k in itertools.product(range(NX), range(NY), range(NZ)):
    for perm in itertools.permutations(range(3)):
        c = [0, 0, 0]
        path = [tuple(c)]
        for axis in perm:
            c[axis] += 1
            path.append(tuple(c))
        tets.append([node(i + a, j + b, k + d) for a, b, d in path])


def signed6(t):
    a, b, c, d = points[t]
    return np.dot(b - a, np.cross(c - a, d - a))


# Half of the Kuhn tetrahedra are mirror images: orient them all positively, as lop requires
# one orientation throughout.
tets = np.array([t if signed6(t) > 0 else [t[0], t[2], t[1], t[3]] for t in tets], dtype=np.int64)


volume = float(sum(abs(signed6(t)) for t in tets) / 6.0)

# Boundary: faces of exactly one tetrahedron, wound outwards.
faces = {}
for t in tets:
    a, b, c, d = t
    for f in ([a, c, b], [a, b, d], [a, d, c], [b, c, d]):
        key = tuple(sorted(f))
        faces[key] = None if key in faces else f
tris = np.array([f for f in faces.values() if f is not None], dtype=np.int64)
used = np.unique(tris)
remap = -np.ones(len(points), dtype=np.int64)
remap[used] = np.arange(len(used))
surf_points = points[used]
surf_tris = remap[tris]
area = float(
    sum(
        np.linalg.norm(np.cross(q[1] - q[0], q[2] - q[0])) / 2.0
        for q in surf_points[surf_tris]
    )
)

volume_mesh = meshio.Mesh(points, [("tetra", tets)])
# Float32 points and Int32 ids: other DataArray types than meshio's defaults.
volume_mesh32 = meshio.Mesh(points.astype(np.float32), [("tetra", tets.astype(np.int32))])
surface = meshio.Mesh(surf_points, [("triangle", surf_tris)])

written = {}


def write(name, mesh, kind, **kwargs):
    path = os.path.join(out, name)
    meshio.write(path, mesh, **kwargs)
    written[name] = kind


write("vol-ascii.vtu", volume_mesh, "volume", binary=False)
write("vol-base64.vtu", volume_mesh, "volume", binary=True, compression=None)
write("vol-zlib.vtu", volume_mesh, "volume")
write("vol-base64-u64.vtu", volume_mesh, "volume", binary=True, compression=None, header_type="UInt64")
write("vol-zlib-u64.vtu", volume_mesh, "volume", header_type="UInt64")
write("vol-zlib-f32-i32.vtu", volume_mesh32, "volume32")
write("vol-ascii-51.vtk", volume_mesh, "volume", binary=False)
write("vol-binary-51.vtk", volume_mesh, "volume", binary=True)
write("vol-ascii-42.vtk", volume_mesh, "volume", binary=False, file_format="vtk42")
write("vol-binary-42.vtk", volume_mesh, "volume", binary=True, file_format="vtk42")
write("vol-binary-f32-42.vtk", volume_mesh32, "volume32", binary=True, file_format="vtk42")
write("surf-ascii.stl", surface, "surface", binary=False)
write("surf-binary.stl", surface, "surface32", binary=True)
write("surf.obj", surface, "surface")
write("surf-ascii.ply", surface, "surface", binary=False)
write("surf-binary.ply", surface, "surface", binary=True)
# meshio writes triangle surfaces as unstructured grids of VTK_TRIANGLE cells.
write("surf-ascii.vtu", surface, "surface", binary=False)
write("surf-zlib.vtu", surface, "surface")
write("surf-binary-51.vtk", surface, "surface", binary=True)
write("surf-ascii-42.vtk", surface, "surface", binary=False, file_format="vtk42")
# Compressors other than zlib are refused by lop.
write("vol-lzma.vtu", volume_mesh, "refused", compression="lzma")

print("meshio", meshio.__version__)
print("points", len(points))
print("tets", len(tets))
print("volume", repr(volume))
print("surface_points", len(surf_points))
print("triangles", len(surf_tris))
print("area", repr(area))
for name, kind in written.items():
    print("file", name, kind)
