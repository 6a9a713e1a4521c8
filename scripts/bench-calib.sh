#!/usr/bin/env bash
# bench-calib.sh: accuracy and speed of calib's optimisers (OpenCV's LM, Ceres LM, the Nelder-Mead
# simplex with Jacobian or diagonal scaling) and of detect's board corners, on the real OpenCV
# photos and on a synth scene. Prints markdown tables (the figures of docs/calib.md) with the
# machine's load, since the machine may be shared.
#
#   scripts/bench-calib.sh [--build DIR] [--data DIR] [--synth DIR] [--no-synth] [--diagonal]
#
# --synth DIR reuses a folder written by synth (else a default scene is rendered, ~1-2 min);
# --diagonal also times the simplex with diagonal scaling (minutes per data set).
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
build="$root/build"
data="$root/../shared/data"
synth_dir=""
with_synth=1
with_diagonal=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --data) data=$2; shift 2 ;;
    --synth) synth_dir=$2; shift 2 ;;
    --no-synth) with_synth=0; shift ;;
    --diagonal) with_diagonal=1; shift ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) echo "bench-calib.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
build=$(cd "$build" && pwd)
data=$(cd "$data" && pwd)
[[ -z "$synth_dir" ]] || synth_dir=$(cd "$synth_dir" && pwd)
bin="$build/bin"
tools="$build/tools/bin"
for tool in detect calib; do
  [[ -x "$bin/$tool" ]] || { echo "bench-calib.sh: $bin/$tool not built" >&2; exit 1; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "# calib benchmark, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores"
echo "load before: $(uptime)"
echo

# row NAME OBS ARGS...: one calib run, one table row from its JSON report.
row() {
  local name=$1 obs=$2
  shift 2
  local t0 t1
  t0=$(date +%s.%N)
  "$bin/calib" -q "$@" --report "$work/r.json" -o "$work/cam.yaml" "$obs"
  t1=$(date +%s.%N)
  python3 - "$name" "$work/r.json" "$t0" "$t1" <<'EOF'
import json, sys
name, path, t0, t1 = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
r = json.load(open(path))
s = r["optimizer_stats"]
c = r["camera_all_views"]
it = s["iterations"] if s["iterations"] >= 0 else "-"
ev = s["evaluations"] if s["evaluations"] >= 0 else "-"
print(f"| {name} | {r['rms_all_views_px']:.5f} | {c['fx_px']:.3f} | {c['fy_px']:.3f} | {c['cx_px']:.3f} | "
      f"{c['cy_px']:.3f} | {it} | {ev} | {s['seconds']:.3f} | {t1 - t0:.2f} |")
EOF
}

header() {
  echo "| run | RMS px (all views) | fx | fy | cx | cy | iterations | evaluations | optimiser s | calib wall s |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
}

optimisers() {  # optimisers NAME OBS ARGS...
  local name=$1 obs=$2
  shift 2
  row "$name opencv" "$obs" "$@" --optimizer opencv
  row "$name lm" "$obs" "$@" --optimizer lm
  row "$name simplex (jacobian)" "$obs" "$@" --optimizer simplex
  if [[ $with_diagonal == 1 ]]; then
    row "$name simplex (diagonal)" "$obs" "$@" --optimizer simplex --simplex-scaling diagonal
  fi
}

echo "## Real photos (every view kept: --reject-factor 0)"
echo
"$bin/detect" -q --chessboard 9x6 --chessboard-window-check 0 "$data"/opencv-chessboard/left*.jpg > "$work/left.csv"  # OpenCV's corners, as the reference
"$bin/detect" -q --chessboard 9x6 --chessboard-window-check 0 "$data"/opencv-chessboard/right*.jpg > "$work/right.csv"
"$bin/detect" -q --charuco 5x7 --square-mm 40 --marker-mm 20 "$data"/opencv-aruco/img_0[0-3].jpg > "$work/charuco.csv"
header
optimisers "left" "$work/left.csv" --chessboard 9x6 --reject-factor 0
optimisers "right" "$work/right.csv" --chessboard 9x6 --reject-factor 0
optimisers "charuco img_00-03" "$work/charuco.csv" --charuco 5x7 --square-mm 40 --reject-factor 0
echo
echo "Reference (README, Debian OpenCV 4.6): left RMS 0.40877, fx 536.074, fy 536.017; right RMS 0.45872,"
echo "fx 542.356, fy 541.616; ChArUco RMS 0.188 (calibrateCameraCharuco on OpenCV's shifted corners)."
echo

echo "## Default rejection (factor 3, floor 0.5 px)"
echo
for set in left right; do
  "$bin/calib" --chessboard 9x6 -o "$work/cam.yaml" "$work/$set.csv" 2>&1 | grep -E "REJECTED|^calib: RMS|fx =" || true
done
echo

if [[ $with_synth == 1 ]]; then
  if [[ -z "$synth_dir" ]]; then
    [[ -x "$tools/synth" ]] || { echo "bench-calib.sh: $tools/synth not built (or pass --no-synth)" >&2; exit 1; }
    synth_dir="$work/synth"
    echo "rendering the default synth scene into $synth_dir ..."
    "$tools/synth" -q -o "$synth_dir"
  fi
  echo "## synth scene ($synth_dir)"
  echo
  grep -A4 "camera_matrix" "$synth_dir/camera.yaml" | grep data | sed 's/^ */truth: /'
  read -r sx sy sq mk dict < <(awk '/^squares_x/{x=$2}/^squares_y/{y=$2}/^square_mm/{s=$2}/^marker_mm/{m=$2}
    /^dictionary/{d=$2}END{print x, y, s, m, d}' "$synth_dir/board.txt")
  (cd "$synth_dir" && "$bin/detect" -q --charuco "${sx}x${sy}" --square-mm "$sq" --marker-mm "$mk" --dict "$dict" \
    board_*.jpg > "$work/board.csv" && "$bin/detect" -q --no-charuco-refine --charuco "${sx}x${sy}" \
    --square-mm "$sq" --marker-mm "$mk" --dict "$dict" board_*.jpg > "$work/board_raw.csv")
  python3 - "$synth_dir/board_observations.csv" "$work/board_raw.csv" "$work/board.csv" <<'EOF'
import csv, math, sys
def load(p):
    return {(r["image"], int(r["point_id"])): (float(r["u_px"]), float(r["v_px"])) for r in csv.DictReader(open(p))}
truth = load(sys.argv[1])
for label, path in (("OpenCV 4.6 interpolated", sys.argv[2]), ("detect (re-refined)", sys.argv[3])):
    d = load(path)
    e = [(d[k][0] - truth[k][0], d[k][1] - truth[k][1]) for k in d if k in truth]
    n = len(e)
    mx, my = sum(a for a, _ in e) / n, sum(b for _, b in e) / n
    rms = math.sqrt(sum(a * a + b * b for a, b in e) / n)
    print(f"ChArUco corners, {label}: {n} of {len(truth)}, mean error ({mx:+.4f}, {my:+.4f}) px, RMS {rms:.4f} px")
EOF
  echo
  header
  (cd "$synth_dir" && optimisers "synth board views" "$work/board.csv" --charuco "${sx}x${sy}" --square-mm "$sq" \
    --reject-factor 0)
  # Part views: non-coplanar control (plate + part marker corners), true projections + 0.1 px noise.
  python3 - "$synth_dir/observations.csv" "$work/part.csv" <<'EOF'
import csv, random, sys
random.seed(1)
with open(sys.argv[2], "w") as out:
    out.write("image,point_id,u_px,v_px\n")
    for r in csv.DictReader(open(sys.argv[1])):
        out.write(f"{r['image']},{r['point_id']},{float(r['u_px']) + random.gauss(0, 0.1)!r},"
                  f"{float(r['v_px']) + random.gauss(0, 0.1)!r}\n")
EOF
  (cd "$synth_dir" && optimisers "synth part views (DLT)" "$work/part.csv" --control control_points.csv \
    --control part_points.csv --reject-factor 0)
fi
echo
echo "load after: $(uptime)"
