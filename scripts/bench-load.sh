#!/usr/bin/env bash
# Load benchmark (issue #25, deliver 5): a job of N synthetic photos of 2000 x 1500 px (default
# 100) through the whole chain of Makefile.example (calibration, markers and SIFT features, tracks,
# cloud, surface, finishing and roughing paths, G-code, report), each stage's wall time and peak
# resident memory (GNU time) per tool (wall and CPU seconds summed over its runs); then two jobs
# at once from one folder (below).
# Usage: scripts/bench-load.sh [BUILD_DIR] [VIEWS]     (default: build 100). Not a test: minutes.
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
views=${2:-100}
repo=$(cd "$(dirname "$0")/.." && pwd)
for t in "$build/bin/detect" "$build/tools/bin/synth" /usr/bin/time; do
  [ -x "$t" ] || { echo "bench-load: $t not found (build the project; apt-get install time)" >&2; exit 1; }
done
work=$(mktemp -d /tmp/bench-load.XXXXXX)
trap 'rm -rf "$work"' EXIT
# Every tool behind a wrapper that appends "tool wall_s max_rss_kb" for each run.
mkdir -p "$work/bin"
for t in "$build"/bin/*; do
  n=$(basename "$t")
  printf '#!/bin/sh\nexec /usr/bin/time -a -o %s -f "%s %%e %%M %%U %%S" %s "$@"\n' "$work/times.txt" "$n" "$t" > "$work/bin/$n"
  chmod +x "$work/bin/$n"
done
TIMEFORMAT='%R'
echo "bench-load: rendering $views views of 2000 x 1500 px and 10 board views ..." >&2
render=$( { time "$build/tools/bin/synth" -o "$work/set" --shape bumps --views "$views" --calib-views 10 --width 2000 \
             --height 1500 --fx 2400 --supersampling 2 --noise-sigma 1.0 --jpeg-quality 85 --speckle-mm 1.6 \
             --surface-step-mm 2 --seed 2025 -q >/dev/null; } 2>&1 )  # as scripts/make-demo.sh, 100 views
echo "bench-load: rendered in $render s; running the chain (make -j$(nproc)) ..." >&2
job() {  # job OUT: the whole chain into OUT
  make -s -f "$repo/Makefile.example" -j"$(nproc)" BIN="$work/bin" DEMO="$work/set" PHOTOS="$work/set/part_*.jpg" \
       CALIB_PHOTOS="$work/set/board_*.jpg" CONTROL="$work/set/control_points.csv" OUT="$1" all
}
all=$( { time job "$work/job" > "$work/job.log" 2>&1; } 2>&1 ) || { tail -20 "$work/job.log" >&2; exit 1; }
echo "one job of $views photos: $all s wall, $(nproc) cores, load average before $(cut -d' ' -f1 /proc/loadavg)"
printf '%-12s %6s %10s %10s %12s\n' tool runs wall_s cpu_s peak_rss_MB
awk '{ n[$1]++; w[$1] += $2; c[$1] += $4 + $5; if ($3 > m[$1]) m[$1] = $3 }
     END { for (t in n) printf "%-12s %6d %10.1f %10.1f %12.0f\n", t, n[t], w[t], c[t], m[t] / 1024 }' "$work/times.txt" | sort
awk '{ if ($3 > m) m = $3 } END { printf "peak resident memory of any stage: %.0f MB (limit 24 GB)\n", m / 1024 }' "$work/times.txt"
# Two jobs at once from one folder, on the bundled demo: into two OUTs (both must finish and
# their reports be accepted), then into one OUT (every output is one run's complete file; where
# the two runs' outputs meet, the next stage refuses the mix by name instead of reading it).
demo() {  # demo OUT LOG
  (cd "$work" && make -s -f "$repo/Makefile.example" -j1 BIN="$work/bin" OUT="$1" all > "$2" 2>&1)
}
ra=0; rb=0
demo two/a "$work/a.log" & a=$!; demo two/b "$work/b.log" & b=$!
wait $a || ra=$?; wait $b || rb=$?
echo "two demo jobs at once from one folder, OUT=two/a and two/b: exit $ra and $rb"
for j in a b; do
  "$build/bin/report" "$work/two/$j" -o "$work/two/$j/report-check.html" 2>&1 | sed "s/^/  $j: /" || true
done
ra=0; rb=0
demo same "$work/c.log" & a=$!; demo same "$work/d.log" & b=$!
wait $a || ra=$?; wait $b || rb=$?
echo "two demo jobs at once into one OUT: exit $ra and $rb"
grep -h "another run\|run was interrupted" "$work/c.log" "$work/d.log" | sed 's/^/  refused: /' || true
echo "  temporary files left: $(find "$work/same" -name '.*.tmp.*' | wc -l)"
if "$build/bin/report" "$work/same" -o "$work/same/report-check.html" 2> "$work/report.err"; then
  echo "  report of the shared OUT: accepted (each stage's outputs are one run's)"
else
  echo "  report of the shared OUT: refused: $(cat "$work/report.err")"
fi
