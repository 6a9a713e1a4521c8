#!/bin/sh
# Benchmark of triangulate (issue #6): accuracy on synthetic ground truth (synth's default scene
# and triangulate's own scenes), command-line timing, and bundle adjustment against COLMAP 3.8's
# bundle_adjuster on the same tracks from the same start. Prints figures; asserts nothing (the
# bounds are checked by ctest). Timings depend on the machine's load: `uptime` is printed with them.
#
# Usage: scripts/bench-triangulate.sh [BUILD_DIR] [--quick]
#   BUILD_DIR  a configured build folder (default: build-tri); its triangulate targets are built.
#   --quick    skip the 100k-point runs.
set -eu

root=$(cd "$(dirname "$0")/.." && pwd)
build=$root/build-tri
quick=0
for arg in "$@"; do
  case $arg in
    --quick) quick=1 ;;
    *) build=$arg ;;
  esac
done
bin=$build/bin
tools=$build/tools/bin
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cmake --build "$build" --target triangulate triangulate_bench -j2 >/dev/null
synth_bench=""
if cmake --build "$build" --target triangulate_synth_bench -j2 >/dev/null 2>&1; then
  synth_bench=$tools/triangulate_synth_bench
fi

now() { date +%s.%N; }
elapsed() { echo "$1 $2" | awk '{printf "%.3f", $2 - $1}'; }

echo "== machine: $(nproc) cores; $(uptime)"

if [ -n "$synth_bench" ]; then
  echo "== accuracy on synth's default scene (12 views, 2000x1500 px; marker-corner noise added to synth's true projections)"
  for noise in 0.05 0.1; do
    for datum in control marker-side scale-bars; do
      "$synth_bench" --noise-px $noise --datum $datum --repeat 10 | tail -n 1
    done
  done
  echo "-- with 2500 simulated natural features on the part (0.2 px), marker corners 0.05 px"
  for datum in control marker-side; do
    "$synth_bench" --noise-px 0.05 --datum $datum --repeat 5 --natural-features 2500 | grep -E "natural features|^datum" | tail -n 2
  done
else
  echo "== synth not built: synth-scene accuracy skipped"
fi

echo "== accuracy on triangulate's own scene (12 views, 96 part points, 0.05 px)"
for datum in control control-sigma scale-bars marker-side; do
  "$tools/triangulate_bench" --datum $datum | head -n 3
done
echo "-- with 2 % outliers of 8 px"
"$tools/triangulate_bench" --datum control --outlier-fraction 0.02 | sed -n '1,2p;4p'

echo "== command line, 12 views (tracks.csv -> cloud.ply, poses, report, COLMAP model)"
"$tools/triangulate_bench" --write "$work/cli"
start=$(now)
"$bin/triangulate" "$work/cli/tracks.csv" -c "$work/cli/camera.yaml" --control-points "$work/cli/control_points.csv" \
  -o "$work/cli/cloud.ply" --poses "$work/cli/poses.csv" --report "$work/cli/report.json" --colmap "$work/cli/model" -q
echo "triangulate (control points): $(elapsed "$start" "$(now)") s wall"
start=$(now)
"$bin/triangulate" "$work/cli/tracks.csv" -c "$work/cli/camera.yaml" --scale-bars "$work/cli/scale_bars.csv" \
  -o "$work/cli/cloud2.ply" -q
echo "triangulate (scale bars, incremental): $(elapsed "$start" "$(now)") s wall"

if [ $quick -eq 0 ]; then
  echo "== full pipeline at scale: 200 views, 100000 points, tracks of 6 views"
  start=$(now)
  "$tools/triangulate_bench" --views 200 --random-points 100000 --max-track-length 6 --datum control | head -n 3
  echo "wall $(elapsed "$start" "$(now)") s; $(uptime)"
fi

echo "== bundle adjustment against COLMAP 3.8 (same tracks, same start: true poses rotated ~0.1 deg and"
echo "   shifted ~0.5 mm, points triangulated; same gauge and trivial loss; intrinsics fixed)"
colmap=$(command -v colmap || true)
sizes="12:0:0 100:20000:6"
[ $quick -eq 0 ] && sizes="$sizes 200:100000:6"
for size in $sizes; do
  views=${size%%:*}
  rest=${size#*:}
  points=${rest%%:*}
  track=${rest#*:}
  dir=$work/ba_$views
  echo "-- $views views, $([ "$points" = 0 ] && echo "grid of 96 part points + plate" || echo "$points points, tracks of $track views")"
  "$tools/triangulate_bench" --ba-compare "$dir" --views "$views" --random-points "$points" --max-track-length "$track" | grep "photomill BA"
  if [ -z "$colmap" ]; then
    echo "   colmap not installed: comparison skipped"
    continue
  fi
  for tol in default 1e-10; do
    out=$dir/colmap_$tol
    mkdir -p "$out"
    extra=""
    [ "$tol" != default ] && extra="--BundleAdjustment.function_tolerance $tol"
    start=$(now)
    # shellcheck disable=SC2086
    "$colmap" bundle_adjuster --input_path "$dir/initial" --output_path "$out" \
      --BundleAdjustment.refine_focal_length 0 --BundleAdjustment.refine_principal_point 0 \
      --BundleAdjustment.refine_extra_params 0 $extra >"$out.log" 2>&1
    wall=$(elapsed "$start" "$(now)")
    awk -v tol="$tol" -v wall="$wall" '
      /Iterations :/ {it = $3} /Time :/ {t = $3} /Initial cost :/ {i = $4} /Final cost :/ {f = $4}
      END {printf "COLMAP BA (function_tolerance %s): %d iterations; solver %.3f s, wall %s s; rms %.6f -> %.6f px (cost figure %s -> %s)\n", tol, it, t, wall, 2 * i, 2 * f, i, f}' "$out.log"
  done
done
echo "== $(uptime)"
