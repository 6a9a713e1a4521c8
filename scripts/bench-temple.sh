#!/usr/bin/env bash
# The Middlebury temple (../shared/data/middlebury-temple, 16 real views, true K, R, t) through
# detect, match and triangulate, and COLMAP 3.8 beside it when installed:
#   1. the true cameras held fixed (triangulate --known-poses; COLMAP point_triangulator):
#      points, reprojection median over the kept observations, share inside the published box;
#   2. no markers, no poses, the true K (triangulate --arbitrary-scale; COLMAP mapper with the
#      intrinsics fixed): views oriented and camera-centre RMS after a similarity.
# Prints one line per run. Usage: scripts/bench-temple.sh [BUILD_DIR] (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build}/bin
data=../shared/data/middlebury-temple
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The true cameras as photomill's camera.yaml and poses CSV (metres -> mm).
python3 scripts/temple_cameras.py "$data/templeSR_par.txt" "$work"

# Reprojection median (kept observations), points and share inside the box of a COLMAP text model.
model_figures() {
  python3 - "$@" <<'EOF'
import math, sys
d = sys.argv[1]
cam = [l.split() for l in open(d + '/cameras.txt') if l.strip() and l[0] != '#'][0]
fx, fy, cx, cy = map(float, cam[4:8])
lines = [l.rstrip('\n') for l in open(d + '/images.txt') if not l.startswith('#')]
images = {}
for k in range(0, len(lines) - 1, 2):
    f = lines[k].split()
    if not f: continue
    w, x, y, z = map(float, f[1:5]); t = list(map(float, f[5:8]))
    R = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    p = lines[k + 1].split()
    images[f[0]] = (R, t, [(float(p[i]), float(p[i + 1])) for i in range(0, len(p), 3)])
lo = (-0.073568, 0.021728, -0.012445); hi = (0.028855, 0.181892, 0.062736)
scale = float(sys.argv[2]) if len(sys.argv) > 2 else 1000.0
errors = []; points = inside = 0
for l in open(d + '/points3D.txt'):
    if l[0] == '#' or not l.strip(): continue
    f = l.split(); X = list(map(float, f[1:4])); points += 1
    inside += all(lo[i] * scale <= X[i] <= hi[i] * scale for i in range(3))
    for i in range(8, len(f), 2):
        R, t, xy = images[f[i]]
        c = [sum(R[r][j] * X[j] for j in range(3)) + t[r] for r in range(3)]
        u, v = fx * c[0] / c[2] + cx, fy * c[1] / c[2] + cy
        ox, oy = xy[int(f[i + 1])]
        errors.append(math.hypot(u - ox, v - oy))
errors.sort()
print('%d points, reprojection median %.3f px over %d observations, %.1f %% inside the box' %
      (points, errors[len(errors) // 2], len(errors), 100.0 * inside / max(points, 1)))
EOF
}

photos=("$data"/templeSR00*.png)
for setting in default makefile; do
  feat=(); match_opts=()
  if [ $setting = makefile ]; then
    feat=(--sift-contrast-threshold 0.01 --max-features 20000); match_opts=(--min-track-length 2 --lsm-quadratic)
  fi
  s=$(date +%s.%N)
  "$bin"/detect -q --features "$work/feat-$setting" "${feat[@]}" "${photos[@]}"
  "$bin"/match -q --features "$work/feat-$setting" --camera "$work/camera.yaml" "${match_opts[@]}" -o "$work/tracks-$setting.csv"
  "$bin"/triangulate -q "$work/tracks-$setting.csv" -c "$work/camera.yaml" --known-poses "$work/poses.csv" \
      --colmap "$work/model-$setting" -o /dev/null
  e=$(date +%s.%N)
  echo "photomill, true cameras fixed, $setting feature settings: $(model_figures "$work/model-$setting"), $(echo "$e - $s" | bc) s"
  for pnp in 8 6; do
    for refine in lsm none; do
      "$bin"/match -q --features "$work/feat-$setting" --camera "$work/camera.yaml" "${match_opts[@]}" \
          --refine $refine -o "$work/t.csv"
      "$bin"/triangulate -q "$work/t.csv" -c "$work/camera.yaml" --arbitrary-scale --pnp-min-inliers $pnp \
          --poses "$work/p.csv" -o /dev/null 2>/dev/null || true
      echo "photomill, no poses, $setting feature settings, match --refine $refine, --pnp-min-inliers $pnp:" \
           "$(python3 scripts/compare-poses.py "$work/poses.csv" "$work/p.csv" --similarity 2>&1 || true)"
    done
  done
done

if command -v colmap > /dev/null; then
  c=$work/colmap
  mkdir -p "$c/sparse" "$c/known"
  colmap feature_extractor --database_path "$c/db.db" --image_path "$data" --ImageReader.camera_model PINHOLE \
      --ImageReader.single_camera 1 --ImageReader.camera_params 1520.4,1525.9,302.82,247.37 --SiftExtraction.use_gpu 0 > /dev/null 2>&1
  colmap exhaustive_matcher --database_path "$c/db.db" --SiftMatching.use_gpu 0 > /dev/null 2>&1
  colmap mapper --database_path "$c/db.db" --image_path "$data" --output_path "$c/sparse" \
      --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 > /dev/null 2>&1 || true
  best=$(ls -d "$c"/sparse/*/ 2>/dev/null | head -1)
  if [ -n "$best" ]; then
    colmap model_converter --input_path "$best" --output_path "$best" --output_type TXT > /dev/null 2>&1
    echo "COLMAP mapper, no poses, intrinsics fixed: $(python3 scripts/compare-poses.py "$work/poses.csv" "$best/images.txt" --similarity)"
  fi
  # point_triangulator with the true cameras (COLMAP's convention: principal point + 0.5 px).
  python3 - "$work/poses.csv" "$c" <<'EOF'
import csv, sqlite3, sys
db = sqlite3.connect(sys.argv[2] + '/db.db')
ids = {name: i for i, name in db.execute('SELECT image_id, name FROM images')}
with open(sys.argv[2] + '/known/cameras.txt', 'w') as f:
    f.write('1 PINHOLE 640 480 1520.4 1525.9 302.82 247.37\n')
with open(sys.argv[2] + '/known/images.txt', 'w') as f:
    for r in csv.DictReader(open(sys.argv[1])):
        t = [float(r[k]) / 1000 for k in ('tx_mm', 'ty_mm', 'tz_mm')]
        f.write('%d %s %s %s %s %r %r %r 1 %s\n\n' % (ids[r['image']], r['qw'], r['qx'], r['qy'], r['qz'], t[0], t[1], t[2], r['image']))
open(sys.argv[2] + '/known/points3D.txt', 'w').close()
EOF
  mkdir -p "$c/triangulated"
  colmap point_triangulator --database_path "$c/db.db" --image_path "$data" --input_path "$c/known" \
      --output_path "$c/triangulated" > /dev/null 2>&1
  colmap model_converter --input_path "$c/triangulated" --output_path "$c/triangulated" --output_type TXT > /dev/null 2>&1
  echo "COLMAP point_triangulator, true cameras fixed: $(model_figures "$c/triangulated" 1)"
else
  echo "COLMAP not installed: its figures are in ../shared/data/README.md"
fi
