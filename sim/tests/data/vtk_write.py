"""Writes one triangle surface with VTK's own writers, in every layout lop reads, for
sim/tests/mesh/mesh_vtk_writers.rs: lop must read each file back to the counts and the area that
VTK itself computes (vtkMassProperties).

usage: python3 vtk_write.py <out dir>

The surface is a vtkSphereSource of 100 x 52 (5,002 points, 10,000 triangles: the size of the
surface in issue 28), stretched and shifted so that coordinates are not round numbers; once
in single precision (VTK's default) and once in double. Prints `<key> <value>` lines, then
`file <name> <kind>` for each file written (kind: surface, surface32 for single precision,
quads for the cube whose quadrilaterals lop splits in two, refused).
"""

import os
import sys

import vtk

out = sys.argv[1]
os.makedirs(out, exist_ok=True)
print("vtk", vtk.vtkVersion.GetVTKVersion())


def sphere(double):
    s = vtk.vtkSphereSource()
    s.SetThetaResolution(100)
    s.SetPhiResolution(52)
    s.SetRadius(0.0731)
    if double:
        s.SetOutputPointsPrecision(vtk.vtkAlgorithm.DOUBLE_PRECISION)
    t = vtk.vtkTransform()
    t.Translate(0.013, -0.021, 0.0047)
    t.Scale(1.3, 0.9, 0.7)
    f = vtk.vtkTransformFilter()
    f.SetTransform(t)
    f.SetInputConnection(s.GetOutputPort())
    if double:
        f.SetOutputPointsPrecision(vtk.vtkAlgorithm.DOUBLE_PRECISION)
    f.Update()
    return f.GetPolyDataOutput()


single = sphere(False)
double = sphere(True)
mass = vtk.vtkMassProperties()
mass.SetInputData(double)
mass.Update()
print("points", double.GetNumberOfPoints())
print("triangles", double.GetNumberOfPolys())
print("area", repr(mass.GetSurfaceArea()))


def legacy(pd, name, version, binary, kind):
    w = vtk.vtkPolyDataWriter()
    w.SetInputData(pd)
    w.SetFileName(os.path.join(out, name))
    w.SetFileVersion(version)
    if binary:
        w.SetFileTypeToBinary()
    else:
        w.SetFileTypeToASCII()
    assert w.Write() == 1, name
    print("file", name, kind)


def xml(pd, name, mode, kind, compressor=None, header64=False):
    w = vtk.vtkXMLPolyDataWriter()
    w.SetInputData(pd)
    w.SetFileName(os.path.join(out, name))
    {"ascii": w.SetDataModeToAscii, "binary": w.SetDataModeToBinary,
     "appended": w.SetDataModeToAppended}[mode]()
    if mode == "appended":
        w.EncodeAppendedDataOff()
    if compressor is None:
        w.SetCompressorTypeToNone()
    elif compressor == "zlib":
        w.SetCompressorTypeToZLib()
    elif compressor == "lz4":
        w.SetCompressorTypeToLZ4()
    if header64:
        w.SetHeaderTypeToUInt64()
    else:
        w.SetHeaderTypeToUInt32()
    assert w.Write() == 1, name
    print("file", name, kind)


for pd, suffix, kind in [(single, "32", "surface32"), (double, "64", "surface")]:
    # Legacy: the classic layout (file version 4.2: `POLYGONS n size` and one list of
    # counts and ids) and the 5.1 layout (`OFFSETS` / `CONNECTIVITY`), ASCII and binary.
    legacy(pd, f"classic_binary_{suffix}.vtk", 42, True, kind)
    legacy(pd, f"classic_ascii_{suffix}.vtk", 42, False, kind)
    legacy(pd, f"v51_binary_{suffix}.vtk", 51, True, kind)
    legacy(pd, f"v51_ascii_{suffix}.vtk", 51, False, kind)
    xml(pd, f"ascii_{suffix}.vtp", "ascii", kind)
    xml(pd, f"base64_{suffix}.vtp", "binary", kind)
    xml(pd, f"base64_zlib_{suffix}.vtp", "binary", kind, "zlib")
    xml(pd, f"appended_{suffix}.vtp", "appended", kind, header64=True)
    xml(pd, f"appended_zlib_{suffix}.vtp", "appended", kind, "zlib", header64=True)

# Quadrilaterals (a cube: 6 quads, 24 points as VTK gives each face its own corners).
cube = vtk.vtkCubeSource()
cube.SetXLength(0.03)
cube.SetYLength(0.02)
cube.SetZLength(0.01)
cube.Update()
legacy(cube.GetOutput(), "cube_classic_binary.vtk", 42, True, "quads")
xml(cube.GetOutput(), "cube.vtp", "appended", "quads")

# What lop refuses with a message: triangle strips, and a compressor it does not read.
strips = vtk.vtkStripper()
strips.SetInputData(double)
strips.Update()
legacy(strips.GetOutput(), "strips_classic_binary.vtk", 42, True, "refused_strips")
xml(double, "lz4.vtp", "appended", "refused_lz4", "lz4")
