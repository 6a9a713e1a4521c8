#!/usr/bin/env bash
# Side-by-side benchmark for issue #6: COLMAP 3.8's CPU pipeline (SIFT extraction, exhaustive
# matching, incremental mapper) and photomill's detect -> match -> triangulate on the same 12 demo
# photos (data/demo/part_*.jpg, 2000 x 1500), both with the demo's known camera held fixed. Prints
# wall time and camera-centre error against the demo's true poses for each: after a similarity
# alignment for both (COLMAP has no datum), and in the control points' frame for photomill.
# COLMAP is a peer for benchmarks only; the script says so and stops if it is not installed.
# Another synth folder (synth's part_*.jpg, camera.yaml, poses.csv, control_points.csv, its
# plate markers 0-13 of 24 mm as the demo's) may be given instead of the demo.
#   scripts/bench-colmap-pipeline.sh [build-dir] [set-dir]      (defaults: build, data/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
bin=$build/bin
demo=${2:-data/demo}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
threads=$(nproc)
marker_mm=24        # the demo's plate markers, ids 0-13 (data/demo/scene.txt)
marker_ids=0-13

if ! command -v colmap >/dev/null; then
  echo "bench-colmap-pipeline: colmap not installed (apt-get install colmap); nothing to compare" >&2
  exit 0
fi
cmake --build "$build" --target detect match triangulate -j"$threads" >/dev/null

# timed CMD... and figures (scripts/timed.sh).
source scripts/timed.sh

# The demo camera in COLMAP's OPENCV model: fx fy cx cy k1 k2 p1 p2, principal point + 0.5 px
# (COLMAP puts the centre of the top-left pixel at (0.5, 0.5)). k3 is 0 in the demo.
read -r fx fy cx cy k1 k2 p1 p2 < <(python3 - "$demo/camera.yaml" <<'EOF'
import re, sys
text = open(sys.argv[1]).read()
def matrix(key):
    block = text[text.index(key):]
    return [float(v) for v in re.search(r"data:\s*\[([^\]]*)\]", block).group(1).replace(",", " ").split()]
K, d = matrix("camera_matrix"), matrix("distortion_coefficients")
assert abs(d[4]) < 1e-12, "k3 must be 0 for COLMAP's OPENCV model"
print(K[0], K[4], K[2] + 0.5, K[5] + 0.5, d[0], d[1], d[2], d[3])
EOF
)

echo "== machine: $threads cores; $(uptime | sed 's/.*load average/load average/')"
echo "== COLMAP $(colmap help 2>&1 | sed -n 's/^COLMAP \([0-9.]*\).*/\1/p') CPU pipeline, camera fixed (OPENCV $fx $fy $cx $cy $k1 $k2 $p1 $p2)"
mkdir -p "$work/colmap/sparse" "$work/colmap/txt"
(cd "$demo" && ls part_*.jpg) > "$work/colmap/images.txt"
wall=0 cpu=0
timed colmap feature_extractor --database_path "$work/colmap/db.db" --image_path "$demo" \
  --image_list_path "$work/colmap/images.txt" --ImageReader.camera_model OPENCV --ImageReader.single_camera 1 \
  --ImageReader.camera_params "$fx,$fy,$cx,$cy,$k1,$k2,$p1,$p2" \
  --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$threads" > "$work/colmap/log" 2>&1
t_extract=$(figures)
timed colmap exhaustive_matcher --database_path "$work/colmap/db.db" --SiftMatching.use_gpu 0 \
  --SiftMatching.num_threads "$threads" >> "$work/colmap/log" 2>&1
t_match=$(figures)
timed colmap mapper --database_path "$work/colmap/db.db" --image_path "$demo" --output_path "$work/colmap/sparse" \
  --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0 \
  --Mapper.num_threads "$threads" >> "$work/colmap/log" 2>&1
t_total=$(figures)
model=$(ls -d "$work"/colmap/sparse/*/ | head -n 1)
colmap model_converter --input_path "$model" --output_path "$work/colmap/txt" --output_type TXT >> "$work/colmap/log" 2>&1
points=$(grep -vc '^#' "$work/colmap/txt/points3D.txt" || true)
echo "COLMAP: extraction ${t_extract}; + matching ${t_match}; + mapper ${t_total} (total); $points points"
echo -n "COLMAP: "
python3 scripts/compare-poses.py "$demo/poses.csv" "$work/colmap/txt/images.txt" --similarity

echo "== photomill: detect (markers + SIFT) -> match -> triangulate, camera fixed ($demo/camera.yaml)"
wall=0 cpu=0
timed "$bin/detect" -q --aruco DICT_4X4_100 --features "$work/feat" --mask-markers "$demo"/part_*.jpg -o "$work/obs.csv"
t_detect=$(figures)
timed "$bin/match" -q "$work/obs.csv" --features "$work/feat" --camera "$demo/camera.yaml" -o "$work/tracks.csv"
t_match=$(figures)
timed "$bin/triangulate" -q "$work/tracks.csv" --camera "$demo/camera.yaml" --control-points "$demo/control_points.csv" \
  --poses "$work/poses.csv" -o "$work/cloud.ply"
t_total=$(figures)
points=$(awk '/^element vertex/ { print $3 }' "$work/cloud.ply")
echo "photomill (control points on the plate): detect ${t_detect}; + match ${t_match}; + triangulate ${t_total} (total); $points points"
echo -n "photomill, control frame:  "
python3 scripts/compare-poses.py "$demo/poses.csv" "$work/poses.csv"
echo -n "photomill, similarity:     "
python3 scripts/compare-poses.py "$demo/poses.csv" "$work/poses.csv" --similarity
wall=0 cpu=0
if ! timed "$bin/triangulate" -q "$work/tracks.csv" --camera "$demo/camera.yaml" --marker-side-mm "$marker_mm" --marker-ids "$marker_ids" \
  --poses "$work/poses_free.csv" -o "$work/cloud_free.ply" 2> "$work/free.err"; then
  echo "photomill without control: $(tail -n 1 "$work/free.err")"
  exit 0
fi
echo "photomill without control points (scale from the marker side): triangulate $(figures)"
echo -n "photomill, no control, similarity: "
python3 scripts/compare-poses.py "$demo/poses.csv" "$work/poses_free.csv" --similarity
echo "load after: $(uptime | sed 's/.*load average/load average/')"
