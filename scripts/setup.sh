#!/usr/bin/env bash
# Installs what lop's builds, tests and benchmarks need beyond the Rust toolchain, on Debian or
# Ubuntu. Idempotent: it only calls apt-get / pip when something is missing.
#   tetgen    regenerates and checks the shipped meshes (assets/generate.py --check)
#   gmsh      meshes the graded test blocks of `lop-bench haptics` (bench/src/haptics/block.rs)
#   rt-tests  cyclictest, the machine's own wake-up latency floor in `lop-bench latency`
#   python3-meshio  writes the VTK, STL, OBJ and PLY files that the mesh readers are tested on
#             (sim/tests/mesh/mesh_meshio.rs); an independent writer, with numpy
#   chromium  headless browser for the web viewer's screenshot test (view/tests/browser.rs)
#   vtk       PyPI package: VTK's own writers make the legacy and XML surfaces that the
#             surface readers are tested on (sim/tests/mesh/mesh_vtk_writers.rs)
#   pytetwild PyPI package (fTetWild), with pyvista which it imports: the robust mesher of
#             `lopd mesh tetrahedralize` for surfaces with defects (daemon/src/tetrahedralize)
#   iceoryx2  the Python binding, at exactly the daemon's iceoryx2 version, for the renderer
#             contract's Python consumer example (examples/python/consumer.py)
set -euo pipefail

# Must equal the workspace's `iceoryx2 = "=…"` pin: every process sharing a service runs the
# same iceoryx2 version.
ICEORYX2_VERSION=0.10.0

need=()
command -v tetgen >/dev/null 2>&1 || need+=(tetgen)
command -v gmsh >/dev/null 2>&1 || need+=(gmsh)
command -v cyclictest >/dev/null 2>&1 || need+=(rt-tests)
command -v python3 >/dev/null 2>&1 || need+=(python3)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
# Debian's package installs for /usr/bin/python3, which the tests fall back to.
# (`-s`: without the user's site, where a NumPy 2 that pip installs below for other packages
# would break Debian's meshio; the tests fall back the same way.)
python3 -c 'import meshio' >/dev/null 2>&1 || /usr/bin/python3 -c 'import meshio' >/dev/null 2>&1 \
  || /usr/bin/python3 -s -c 'import meshio' >/dev/null 2>&1 || need+=(python3-meshio)

if [ ${#need[@]} -gt 0 ]; then
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "setup: please install: ${need[*]} (no apt-get here)" >&2
    exit 1
  fi
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${need[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${need[@]}" >/dev/null
fi

# pip install --user of the given requirements, installing pip first when it is missing.
pip_user() {
  if ! python3 -m pip --version >/dev/null 2>&1; then
    echo "setup: installing python3-pip" >&2
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq python3-pip >/dev/null
  fi
  echo "setup: installing Python $*" >&2
  # --user keeps the system interpreter untouched; Debian's externally-managed marker needs
  # --break-system-packages for a user install too.
  python3 -m pip install -q --user "$@" 2>/dev/null \
    || python3 -m pip install -q --user --break-system-packages "$@"
}

have=$(python3 -c 'import importlib.metadata as m; print(m.version("iceoryx2"))' 2>/dev/null || true)
if [ "$have" != "$ICEORYX2_VERSION" ]; then
  pip_user "iceoryx2==$ICEORYX2_VERSION"
fi
python3 -c 'import vtk' >/dev/null 2>&1 || pip_user vtk
# pytetwild 0.4 imports pyvista without declaring it.
python3 -c 'import pytetwild' >/dev/null 2>&1 || pip_user pytetwild pyvista

