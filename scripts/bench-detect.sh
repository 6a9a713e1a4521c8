#!/usr/bin/env bash
# Speed and accuracy of detect (ArUco markers, SIFT features) and match on the demo set
# (data/demo: 12 photos of 2000 x 1500), against the demo's truth. Usage:
#   scripts/bench-detect.sh [build-dir]        (default: build; builds what it needs)
# Wall times depend on what else runs on the machine: the load average is printed with them, and
# the CPU time (user + sys) beside each wall time.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${PHOTOMILL_BENCH_RUNS:-3}
cmake --build "$build" --target detect match detect_marker_check detect_marker_bench detect_marker_stability detect_marker_board_check match_track_check -j"$(nproc)" >/dev/null
bin=$build/bin
tools=$build/tools/bin
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
photos=(data/demo/part_*.jpg)
dict=DICT_4X4_100  # the demo's part and plate markers (data/demo/scene.txt)

# timed LABEL CMD...: runs CMD $runs times, prints the fastest wall time and its CPU time.
timed() {
  local label=$1 best="" cpu=""
  shift
  for _ in $(seq "$runs"); do
    local start end
    start=$(date +%s.%N)
    /usr/bin/time -f "%U %S" -o "$work/time" "$@" 2>"$work/stderr" >/dev/null
    end=$(date +%s.%N)
    local wall
    wall=$(echo "$end - $start" | bc)
    if [ -z "$best" ] || [ "$(echo "$wall < $best" | bc)" = 1 ]; then
      best=$wall
      cpu=$(awk '{ print $1 + $2 }' "$work/time")
    fi
  done
  printf '%-58s wall %6.2f s   cpu %6.2f s\n' "$label" "$best" "$cpu"
}

echo "machine: $(nproc) cores; load before: $(uptime | sed 's/.*load average/load average/')"
echo
echo "== speed (fastest of $runs runs, ${#photos[@]} photos of 2000 x 1500) =="
timed "detect --aruco (markers, edge fit)" "$bin/detect" --aruco "$dict" "${photos[@]}" -o "$work/obs.csv"
timed "detect --aruco --corner-refine subpix (OpenCV's)" "$bin/detect" --aruco "$dict" --corner-refine subpix \
  "${photos[@]}" -o "$work/obs_subpix.csv"
timed "detect --features (SIFT, 8000 per image)" "$bin/detect" --features "$work/feat_only" "${photos[@]}"
timed "detect --aruco --features --mask-markers (one pass)" "$bin/detect" --aruco "$dict" --features "$work/feat" \
  --mask-markers "${photos[@]}" -o "$work/obs.csv"
timed "match (coded points only)" "$bin/match" "$work/obs.csv" --camera data/demo/camera.yaml -o "$work/tracks_coded.csv"
timed "match (coded points + SIFT features)" "$bin/match" "$work/obs.csv" --features "$work/feat" \
  --camera data/demo/camera.yaml -o "$work/tracks.csv"
echo "load after: $(uptime | sed 's/.*load average/load average/')"

echo
echo "== marker corners against the true projections =="
echo "-- edge fit (detect's default):"
"$tools/detect_marker_check" "$work/obs.csv" --set data/demo
echo "-- OpenCV's CORNER_REFINE_SUBPIX on the same photos:"
"$tools/detect_marker_check" "$work/obs_subpix.csv" --set data/demo

echo
echo "== tracks against the true geometry =="
"$bin/match" "$work/obs.csv" --features "$work/feat" --camera data/demo/camera.yaml -o /dev/null 2>&1 | sed 's/^/  /'
"$tools/match_track_check" "$work/tracks.csv" --set data/demo

echo
echo "== markers, one thread each: photomill's edge fit against OpenCV's detectMarkers + CORNER_REFINE_SUBPIX =="
"$tools/detect_marker_bench" "${photos[@]}" --set data/demo --runs 7

echo
echo "== markers: how far the edge fit's corners move when OpenCV's start corners move by 0.3 px =="
"$tools/detect_marker_stability" "${photos[@]}"
aruco=../shared/data/opencv-aruco
if [ -d "$aruco" ]; then
  echo "-- OpenCV's real ArUco photos (DICT_6X6_250, sRGB JPEGs):"
  "$tools/detect_marker_stability" "$aruco"/singlemarkersoriginal.jpg "$aruco"/img_0[0-3].jpg \
    --dictionary DICT_6X6_250 --gamma 2.2
  echo "-- the same without the code cells (--edge-ignore-code):"
  "$tools/detect_marker_stability" "$aruco"/singlemarkersoriginal.jpg "$aruco"/img_0[0-3].jpg \
    --dictionary DICT_6X6_250 --gamma 2.2 --no-code-model
  echo
  echo "== markers on OpenCV's real ChArUco photos against the board's geometry (published calibration) =="
  "$tools/detect_marker_board_check" "$aruco"/img_0[0-3].jpg --camera "$aruco"/tutorial_camera_charuco.yml
fi
