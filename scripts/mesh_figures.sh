#!/usr/bin/env bash
# The figures of docs/benchmarks.md, "Meshing — `lopd mesh tetrahedralize`": each built surface
# (scripts/mesh_surfaces.py) meshed by each mesher to each size; one line per run with the
# tetrahedra asked and made, the smallest dihedral angle, its 5th percentile over the
# tetrahedra, the meshings it took and the seconds (repair included). With STEPS=N, also the
# touched step on the result: the mesh made into a scene (`lopd scene new`, liver tissue, its
# generated poke) and run offline for N steps (`lopd simulate`); the median and p99 wall time,
# µs, of the FEM steps taken in contact (a release `lopd` for these; meshes over 25,000
# tetrahedra are not stepped).
#   usage: [MESHERS="gmsh ftetwild tetgen"] [STEPS=N] scripts/mesh_figures.sh [LOPD] [SIZES...]
#   (LOPD default target/release/lopd; SIZES default 2000 5000 10000 20000)
set -euo pipefail
lopd=${1:-target/release/lopd}
shift || true
sizes=${*:-2000 5000 10000 20000}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 "$(dirname "$0")/mesh_surfaces.py" "$dir" >/dev/null
printf '%-16s %-9s %6s %6s %7s %6s %5s %8s %9s %9s\n' surface mesher asked made min_deg p5_deg tries seconds step_p50 step_p99
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
print(f"{s:16} {m:9} {n:>6} {made:>6} {float(lo):7.1f} {float(p5):6.1f} {len(tries):5} {secs:8.1f}", end="")
' "$s" "$m" "$n"
      made=$(sed -n 2p "$dir/mesh.ele" | awk '{print $1}')
      if [[ -n ${STEPS:-} && $made -le 25000 ]]; then
        "$lopd" scene new figure --mesh "$dir/mesh" --force --out "$dir/figure.toml" >/dev/null
        "$lopd" simulate --scene "$dir/figure.toml" --script "$dir/figure-poke.toml" \
          --steps "$STEPS" --out "$dir/sim" >/dev/null
        python3 -c '
import csv, sys
t = sorted(float(r["step_us"]) for r in csv.DictReader(open(sys.argv[1]))
           if r["model"] == "Fem" and float(r["contact_force_n"]) > 0)
q = lambda f: t[min(len(t) - 1, max(0, int(f * len(t) + 0.999999) - 1))] if t else float("nan")
print(f" {q(0.5):9.0f} {q(0.99):9.0f}")
' "$dir/sim/steps.csv"
      else
        echo
      fi
    done
  done
done
