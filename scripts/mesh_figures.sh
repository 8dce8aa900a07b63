#!/usr/bin/env bash
# The figures of docs/benchmarks.md, "Meshing — `lopd mesh tetrahedralize`": each built surface
# (scripts/mesh_surfaces.py) meshed by each mesher to each size; one line per run with the
# tetrahedra asked and made, the smallest dihedral angle, its 5th percentile over the
# tetrahedra, the meshings it took and the seconds (repair included).
#   usage: [MESHERS="gmsh ftetwild tetgen"] scripts/mesh_figures.sh [LOPD] [SIZES...]
#   (LOPD default target/release/lopd; SIZES default 2000 5000 10000 20000)
set -euo pipefail
lopd=${1:-target/release/lopd}
shift || true
sizes=${*:-2000 5000 10000 20000}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 "$(dirname "$0")/mesh_surfaces.py" "$dir" >/dev/null
printf '%-16s %-9s %6s %6s %7s %6s %5s %8s\n' surface mesher asked made min_deg p5_deg tries seconds
for s in liver ellipsoid kidney liver_crossing liver_holes; do
  extra=()
  case $s in *_*) extra=(--repair) ;; esac
  for m in ${MESHERS:-gmsh ftetwild tetgen}; do
    for n in $sizes; do
      if ! out=$("$lopd" mesh tetrahedralize "$dir/$s.stl" --units mm --mesher "$m" --tets "$n" \
        "${extra[@]}" --out "$dir/mesh" 2>&1); then
        printf '%-16s %-9s %6s  failed: %s\n' "$s" "$m" "$n" "$(echo "$out" | grep -v '^ *$' | tail -1)"
        continue
      fi
      echo "$out" | python3 -c '
import re, sys
s, m, n = sys.argv[1:4]
out = sys.stdin.read()
secs = sum(float(x) for x in re.findall(r"repaired by fTetWild in ([0-9.]+) s", out))
tries = re.findall(r"^  meshing \d+: .*?, (\d+) tetrahedra, .*?, ([0-9.]+) s(.*)$", out, re.M)
secs += sum(float(t[1]) for t in tries)
made = next(t[0] for t in tries if "kept" in t[2])
lo = re.search(r"dihedral angles: +([0-9.]+) \.\.", out).group(1)
p5 = re.search(r"5 % under ([0-9.]+)", out).group(1)
print(f"{s:16} {m:9} {n:>6} {made:>6} {float(lo):7.1f} {float(p5):6.1f} {len(tries):5} {secs:8.1f}")
' "$s" "$m" "$n"
    done
  done
done
