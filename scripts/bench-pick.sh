#!/usr/bin/env bash
# Benchmark for issue 29: pick on N synthetic photos of 2000 x 1500 px (default 30). Prints the
# time pick takes to read the photos and make their thumbnails (until it prints its address), then
# tests/browser/bench_pick.mjs's figures in headless Chromium: navigation to a usable page (both
# panes' full photos decoded), to every thumbnail shown, and a pane's switch to another photo.
# Needs node and playwright-core (scripts/install-deps.sh --tests). Not a test: a few minutes.
# Usage: scripts/bench-pick.sh [BUILD_DIR] [PHOTOS] [RUNS]   (default: build 30 3)
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
views=${2:-30}
runs=${3:-3}
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/bench-pick.XXXXXX)
trap 'rm -rf "$work"' EXIT
echo "bench-pick: rendering $views photos of 2000 x 1500 px ..." >&2
"$build/tools/bin/synth" -o "$work/set" --shape bumps --views "$views" --calib-views 0 --width 2000 --height 1500 \
  --fx 2400 --supersampling 1 --noise-sigma 1.0 --jpeg-quality 85 --speckle-mm 1.6 --seed 2029 -q >/dev/null
echo "$(nproc) cores, load average $(cut -d' ' -f1 /proc/loadavg)"
for run in $(seq "$runs"); do
  start=$(date +%s.%N)
  "$build/bin/pick" "$work"/set/part_*.jpg -o "$work/clicked.csv" -q > "$work/url.txt" &
  pid=$!
  while [ ! -s "$work/url.txt" ]; do kill -0 $pid 2>/dev/null || { echo "bench-pick: pick failed" >&2; exit 1; }; sleep 0.02; done
  made=$(echo "$(date +%s.%N) - $start" | bc)
  figures=$(node "$repo/tests/browser/bench_pick.mjs" "$(head -1 "$work/url.txt")" 10)
  kill $pid 2>/dev/null || true
  wait $pid 2>/dev/null || true
  printf 'run %d: thumbnails_made_s %.2f %s\n' "$run" "$made" "$figures"
  rm -f "$work/url.txt"
done
