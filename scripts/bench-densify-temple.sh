#!/usr/bin/env bash
# densify on the Middlebury temple (../shared/data/middlebury-temple: 16 real 640 x 480 views,
# true K, R, t): detect's features, match, triangulate with the true cameras held fixed, then
# densify with its defaults and with the settings for small photos of fine detail (a point per
# pixel, no bend check, correlation 0.9, convergence 0.02 px, reprojection error at most 0.4 px:
# docs/densify.md, Limits), each timed. Prints per run the points, the share inside the published
# bounding box, the median sigma and the reprojection error's median and 90th percentile.
# The temple stands on a dark cloth that every photo shows (left): points on it are real but
# outside the model's box.
# Usage: scripts/bench-densify-temple.sh [BUILD_DIR] (default build)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build}/bin
data=../shared/data/middlebury-temple
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 scripts/temple_cameras.py "$data/templeSR_par.txt" "$work"
"$bin"/detect -q --features "$work/feat" "$data"/templeSR00*.png
"$bin"/match -q --features "$work/feat" --camera "$work/camera.yaml" -o "$work/tracks.csv"
"$bin"/triangulate -q "$work/tracks.csv" -c "$work/camera.yaml" --known-poses "$work/poses.csv" \
  --poses "$work/poses-out.csv" -o "$work/cloud.ply"
figures() {
  python3 - "$1" <<'PY'
import struct, sys
f = open(sys.argv[1], 'rb'); props = []; n = 0
types = {'double': 'd', 'float': 'f', 'uchar': 'B', 'ushort': 'H', 'uint': 'I'}
while True:
    l = f.readline().decode().strip()
    if l.startswith('element vertex'): n = int(l.split()[2])
    if l.startswith('property'): props.append((l.split()[2], types[l.split()[1]]))
    if l == 'end_header': break
fmt = '<' + ''.join(t for _, t in props); size = struct.calcsize(fmt); names = [p for p, _ in props]
lo = (-73.568, 21.728, -12.445); hi = (28.855, 181.892, 62.736)
inside = 0; sigma = []; rep = []
for k in range(n):
    v = dict(zip(names, struct.unpack(fmt, f.read(size))))
    inside += all(lo[i] <= (v['x'], v['y'], v['z'])[i] <= hi[i] for i in range(3))
    if 'scalar_sigma_mm' in v: sigma.append(v['scalar_sigma_mm'])
    if 'scalar_reprojection_px' in v: rep.append(v['scalar_reprojection_px'])
sigma.sort(); rep.sort()
print('%d points, %.1f %% inside the published box%s%s' % (n, 100.0 * inside / max(n, 1),
      ', median sigma %.3f mm' % sigma[len(sigma) // 2] if sigma else '',
      ', reprojection error median %.3f px, p90 %.3f px' % (rep[len(rep) // 2], rep[len(rep) * 9 // 10]) if rep else ''))
PY
}
echo "sparse (triangulate, true cameras fixed): $(figures "$work/cloud.ply")"
for opts in "" "--spacing-px 1 --max-bend-deg 180 --min-correlation 0.9 --converged-px 0.02 --max-reprojection-px 0.4"; do
  /usr/bin/time -f '%e %U %M' -o "$work/time" "$bin"/densify -q "$work/cloud.ply" --camera "$work/camera.yaml" \
    --poses "$work/poses-out.csv" $opts -o "$work/dense.ply"
  read -r wall cpu kb < "$work/time"
  echo "densify ${opts:-(defaults)}: $(figures "$work/dense.ply"); ${wall} s wall, ${cpu} s CPU, $((kb / 1024)) MB"
done
