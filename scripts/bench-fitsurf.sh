#!/usr/bin/env bash
# Speed and accuracy figures of fitsurf (issue #7), for docs/fitsurf.md: the library benchmark
# (fitsurf_bench: 1M points 40x40 one pass, the default fit of 100k points, accuracy against the
# analytic shapes with and without parameter correction, sparse markers) and the executable end to
# end on 100k points (read, fit, write). Prints the machine load before and after: on a shared
# machine the wall times grow with it, the CPU times much less.
#   scripts/bench-fitsurf.sh [BUILD_DIR] [fitsurf_bench options, e.g. --quick --repeat 5]
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build-fitsurf}
[ $# -gt 0 ] && shift
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" --target fitsurf fitsurf_bench -j2 >/dev/null

echo "== machine: $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo "== load before: $(uptime)"
"$build/tools/bin/fitsurf_bench" "$@"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$build/tools/bin/fitsurf_bench" --write-cloud "$work/c100k.ply" --points 100000
"$build/tools/bin/fitsurf_bench" --write-cloud "$work/c100k.xyz" --points 100000
"$build/tools/bin/fitsurf_bench" --write-cloud "$work/c1m.ply" --points 1000000
echo
echo "== fitsurf executable, end to end (wall s, user+sys s)"
run() {
  local what=$1 t real user sys
  shift
  t=$( { TIMEFORMAT='%R %U %S'; time "$build/bin/fitsurf" -q "$@" -o "$work/out.surf" 2>/dev/null; } 2>&1 )
  read -r real user sys <<<"$t"
  printf '%-62s wall %s s  cpu %s s\n' "$what" "$real" "$(awk -v u="$user" -v s="$sys" 'BEGIN { print u + s }')"
}
run "100k points, binary PLY, default fit" "$work/c100k.ply"
run "100k points, x y z text, default fit" "$work/c100k.xyz"
run "100k points, binary PLY, default fit + STEP + IGES + mesh" "$work/c100k.ply" --step "$work/s.step" \
  --iges "$work/s.igs" --mesh "$work/m.stl"
run "1M points, binary PLY, 40x40, --no-correction --robust none" "$work/c1m.ply" --net 40x40 --no-correction \
  --robust none
run "1M points, binary PLY, default fit" "$work/c1m.ply"
echo "== load after: $(uptime)"
