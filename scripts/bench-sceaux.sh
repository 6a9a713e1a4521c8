#!/usr/bin/env bash
# Side-by-side benchmark for issue #23 on the Sceaux castle (../shared/data/sceaux-castle: 11 real
# photos, 2832 x 2128, the published K, no distortion given): COLMAP 3.8's CPU pipeline
# (feature_extractor, exhaustive_matcher, mapper; SIMPLE_RADIAL started from the K, refined as
# COLMAP does by default) and photomill's marker-free chain as Makefile.example's MARKERS=0 runs it
# (detect a process per photo, two at a time, then match and triangulate --arbitrary-scale), both
# timed in this one run. Both models are exported as COLMAP text models and their reprojection
# errors computed by one script (scripts/colmap_model_rms.py). Prints CPU (user + sys) and wall
# seconds of each, the CPU ratio, points and reprojection figures.
#   scripts/bench-sceaux.sh [build-dir] [photomill triangulate options...]
# e.g. scripts/bench-sceaux.sh build --refine-intrinsics all
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
bin=$build/bin
data=../shared/data/sceaux-castle
[ -f "$data/K.txt" ] || { echo "bench-sceaux: $data not found" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
threads=2
detect_opts="--max-features 11000 --cap-order scale"   # Makefile.example's DETECT_FEAT with MARKERS=0
cmake --build "$build" --target detect match triangulate -j"$threads" > /dev/null

# timed CMD... (scripts/timed.sh); the published K as a camera.yaml (scripts/camera-from-k.sh).
source scripts/timed.sh
scripts/camera-from-k.sh "$data/K.txt" 2832 2128 > "$work/camera.yaml"
read -r fx _ cx _ fy cy _ < <(tr -s ' \r\n' ' ' < "$data/K.txt"; echo)
echo "bench-sceaux: $(ls "$data"/*.JPG | wc -l) photos, load average $(cut -d' ' -f1-3 /proc/loadavg)"

if command -v colmap > /dev/null; then
  c=$work/colmap
  mkdir -p "$c/sparse" "$c/txt"
  wall=0 cpu=0
  # COLMAP's pixel centre is OpenCV's + 0.5 px: its principal point is K's + 0.5.
  timed colmap feature_extractor --database_path "$c/db.db" --image_path "$data" \
    --ImageReader.camera_model SIMPLE_RADIAL --ImageReader.single_camera 1 \
    --ImageReader.camera_params "$fx,$(awk -v a="$cx" 'BEGIN { print a + 0.5 }'),$(awk -v a="$cy" 'BEGIN { print a + 0.5 }'),0" \
    --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$threads" > "$c/log" 2>&1
  timed colmap exhaustive_matcher --database_path "$c/db.db" --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads "$threads" >> "$c/log" 2>&1
  timed colmap mapper --database_path "$c/db.db" --image_path "$data" --output_path "$c/sparse" \
    --Mapper.num_threads "$threads" >> "$c/log" 2>&1
  colmap_cpu=$cpu colmap_wall=$wall
  best=$(ls -d "$c"/sparse/*/ | head -1)
  colmap model_converter --input_path "$best" --output_path "$c/txt" --output_type TXT > /dev/null 2>&1
  echo "COLMAP 3.8: CPU ${colmap_cpu} s, wall ${colmap_wall} s, $(grep -c . <(grep -v '^#' "$c/txt/images.txt") | awk '{ print $1 / 2 }') of 11 images"
  python3 scripts/colmap_model_rms.py "$c/txt" --label "  COLMAP 3.8"
else
  echo "bench-sceaux: colmap not installed (apt-get install colmap): photomill alone" >&2
  colmap_cpu=
fi

p=$work/photomill
mkdir -p "$p/feat"
wall=0 cpu=0
# One detect per photo, two at a time, as make -j2 runs Makefile.example's rule.
timed bash -c "ls '$data'/*.JPG | xargs -P $threads -I{} '$bin/detect' --features '$p/feat' $detect_opts {} 2> '$p/detect.log'"
detect_cpu=$cpu
timed "$bin/match" "$p"/feat/*.feat --camera "$work/camera.yaml" --root-sift -o "$p/tracks.csv" 2> "$p/match.log"
match_cpu=$(awk -v a="$cpu" -v b="$detect_cpu" 'BEGIN { print a - b }')
timed "$bin/triangulate" "$p/tracks.csv" --camera "$work/camera.yaml" --arbitrary-scale "$@" \
  --poses "$p/poses.csv" --colmap "$p/model" -o "$p/cloud.ply" 2> "$p/triangulate.log"
tri_cpu=$(awk -v a="$cpu" -v b="$detect_cpu" -v c="$match_cpu" 'BEGIN { print a - b - c }')
echo "photomill (detect $detect_opts; match --root-sift; triangulate ${*:-defaults}): CPU ${cpu} s (detect ${detect_cpu}, match ${match_cpu}, triangulate ${tri_cpu}), wall ${wall} s, $(grep -c '\.JPG,' "$p/poses.csv") of 11 images"
python3 scripts/colmap_model_rms.py "$p/model" --label "  photomill"
if [ -n "$colmap_cpu" ]; then
  awk -v a="$cpu" -v b="$colmap_cpu" 'BEGIN { printf "CPU ratio photomill / COLMAP: %.3f (bound 1/3)\n", a / b }'
fi
