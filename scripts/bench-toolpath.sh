#!/bin/sh
# Benchmark of toolpath (issue 8): the finishing path on the 150 x 100 mm test surfaces with
# R = 3 mm, h = 0.01 mm, e = 0.005 mm. Prints the machine's load (the figures mean little on a
# busy machine), the library time (toolpath_bench: best and median of 5 runs, CPU time of the
# best), then the whole CLI per surface (read, path, write APT) with its point count and path
# length, and the z-map verification's scallop and gouge.
# Usage: scripts/bench-toolpath.sh [build-dir]   (default: build; builds the needed targets)
set -eu

root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-"$root/build"}
case $build in /*) ;; *) build="$root/$build" ;; esac

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target toolpath toolpath_bench -j2 >/dev/null

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM

echo "== machine"
echo "cores: $(nproc)   $(uptime)"
grep -m1 'model name' /proc/cpuinfo 2>/dev/null || true

echo
echo "== library: generate_toolpath (R 3, h 0.01, e 0.005, gouge tol 0.0005 mm; all cores)"
"$build/tools/bin/toolpath_bench" --runs 5 --write-surfaces "$work" bumps wave groove

echo
echo "== CLI: toolpath SURFACE > part.cl (wall and CPU of the whole process), then --verify"
printf '%-8s %8s %8s %10s %12s %12s %12s\n' surface wall_s cpu_s cl_points feed_mm scallop_mm gouge_mm
for s in bumps wave groove; do
  /usr/bin/time -f '%e %U %S' -o "$work/time" "$build/bin/toolpath" -q --report "$work/$s.json" \
    "$work/$s.surf" >"$work/$s.cl"
  "$build/bin/toolpath" -q --verify --report "$work/$s.verify.json" "$work/$s.surf" >/dev/null
  python3 - "$work/time" "$work/$s.json" "$work/$s.verify.json" "$s" <<'EOF'
import json, sys
wall, user, system = (float(x) for x in open(sys.argv[1]).read().split()[-3:])
path = json.load(open(sys.argv[2]))["path"]
verify = json.load(open(sys.argv[3]))["verify"]
print("%-8s %8.3f %8.3f %10d %12.1f %12.5f %12.5f" % (sys.argv[4], wall, user + system, path["cl_points"],
      path["feed_length_mm"], verify["max_scallop_mm"], verify["max_gouge_mm"]))
EOF
done
echo
echo "load after: $(uptime)"
