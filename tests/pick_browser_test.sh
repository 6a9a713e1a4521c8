#!/usr/bin/env bash
# ctest pick_browser (issue 29): pick on three demo photos with their true camera and poses, driven
# in headless Chromium (tests/browser/check_pick.mjs): the true projections of 10 part-marker
# corners (data/demo/part_points.csv, ids 56-65) clicked at zoom 8 in each photo, the epipolar
# curves and predictions checked on the way, a screenshot, Finish. Then the file pick saved,
# triangulated by triangulate with the true poses held fixed: every corner within 0.02 mm of the
# truth. Skipped (exit 77) without Chromium or playwright-core, unless CI is set.
# Usage: pick_browser_test.sh SOURCE_DIR BUILD_DIR WORK_DIR [REFINE]   (REFINE: pick's --refine, default auto)
set -euo pipefail
src=$1 build=$2 work=$3 refine=${4:-auto}
fail() { echo "pick_browser_test: $*" >&2; exit 1; }
command -v node >/dev/null || {
  [ -z "${CI:-}" ] || fail "no node (CI is set: the browser check must run)"
  echo "pick_browser_test: skipped: no node (scripts/install-deps.sh --tests installs it)" >&2
  exit 77
}
demo=$src/data/demo
rm -rf "$work"
mkdir -p "$work/job"
photos=(part_00.jpg part_01.jpg part_02.jpg)
for p in "${photos[@]}"; do cp "$demo/$p" "$work/job/"; done
cp "$demo/camera.yaml" "$work/job/"
grep -E '^(image|part_0[012]\.jpg),' "$demo/poses.csv" > "$work/job/poses.csv"
cd "$work/job"
"$build/bin/pick" "${photos[@]}" --camera camera.yaml --poses poses.csv --refine "$refine" -o clicked.csv \
  > url.txt 2> pick.log &
pick_pid=$!
trap 'kill $pick_pid 2>/dev/null || true' EXIT
for _ in $(seq 300); do [ -s url.txt ] && break; kill -0 $pick_pid 2>/dev/null || break; sleep 0.1; done
[ -s url.txt ] || { cat pick.log >&2; fail "pick printed no address"; }
url=$(head -1 url.txt)
rc=0
node "$src/tests/browser/check_pick.mjs" "$url" "$demo/observations.csv" 56,57,58,59,60,61,62,63,64,65 \
  "$(IFS=,; echo "${photos[*]}")" 8 "$work/pick.png" || rc=$?
[ $rc -eq 77 ] && exit 77
[ $rc -eq 0 ] || { cat pick.log >&2; fail "the browser check failed"; }
wait $pick_pid || fail "pick exited with status $? after Finish (its log: $work/job/pick.log)"
trap - EXIT
# The saved marks as tracks (point_id -> track_id), triangulated with the true poses held fixed.
awk -F, '/^#/ || /^image,/ { next } { print $2 "," $1 "," $3 "," $4 }' clicked.csv | sort -t, -k1,1n |
  { echo "track_id,image,u_px,v_px"; cat; } > tracks.csv
[ "$(($(wc -l < tracks.csv) - 1))" -eq 30 ] || fail "clicked.csv holds $(($(wc -l < tracks.csv) - 1)) marks, not 30"
"$build/bin/triangulate" tracks.csv -c camera.yaml --known-poses poses.csv -o cloud.ply -q ||
  fail "triangulate refused pick's file"
python3 "$src/tests/read_ply.py" cloud.ply | python3 -c '
import sys
truth = {}
for line in open(sys.argv[1]):
    f = line.strip().split(",")
    if f[0].isdigit(): truth[int(f[0])] = tuple(map(float, f[1:4]))
errors = []
for line in sys.stdin:
    v = line.split()
    x, y, z, track = float(v[0]), float(v[1]), float(v[2]), int(v[3])
    t = truth[track]
    errors.append(((x - t[0]) ** 2 + (y - t[1]) ** 2 + (z - t[2]) ** 2) ** 0.5)
rms = (sum(e * e for e in errors) / len(errors)) ** 0.5
print("pick_browser_test: %d corners triangulated from the clicks: error max %.4f mm, RMS %.4f mm (bound 0.02 mm)"
      % (len(errors), max(errors), rms), file=sys.stderr)
sys.exit(0 if len(errors) == 10 and max(errors) <= 0.02 else 1)
' "$demo/part_points.csv" || fail "the clicked corners are not within 0.02 mm of the truth"
