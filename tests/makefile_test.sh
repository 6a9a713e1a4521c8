#!/usr/bin/env bash
# Makefile.example run as the walkthrough writes it, from a job folder outside the repository
# (dry runs, make -n): photo globs quoted or not give the same commands; a glob that matches no
# file stops make with its name; BIN defaults to the build beside the Makefile.
# Usage: makefile_test.sh SOURCE_DIR
set -euo pipefail
src=$1
mk=$src/Makefile.example
demo=$src/data/demo
job=$(mktemp -d)
trap 'rm -rf "$job"' EXIT
cd "$job"
fail() { echo "makefile_test: $*" >&2; exit 1; }

quoted=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$demo/part_*.jpg" CALIB_PHOTOS="$demo/board_*.jpg" OUT=job1)
unquoted=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$(echo "$demo"/part_*.jpg)" CALIB_PHOTOS="$(echo "$demo"/board_*.jpg)" OUT=job1)
[ "$quoted" = "$unquoted" ] || fail "quoted and unquoted globs give different commands"
# One detect for all the photos (DETECT_BATCH=1, the default), a detect per photo with DETECT_BATCH=0.
n=$(grep -c "^/opt/pm/bin/detect --aruco .*part_00\.jpg .*part_11\.jpg -o job1/obs/all\.csv$" <<<"$quoted" || true)
[ "$n" -eq 1 ] || fail "expected one detect for the 12 demo photos, got $n: $(grep -c '/detect --aruco' <<<"$quoted") detect runs"
per_photo=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$demo/part_*.jpg" CALIB_PHOTOS="$demo/board_*.jpg" OUT=job1 DETECT_BATCH=0)
n=$(grep -c "^/opt/pm/bin/detect --aruco .*part_[0-9]*\.jpg -o job1/obs/part_[0-9]*\.csv$" <<<"$per_photo" || true)
[ "$n" -eq 12 ] || fail "DETECT_BATCH=0: expected one detect per demo photo (12), got $n"
grep -q "^awk .* job1/obs/part_00.csv .* job1/obs/part_11.csv > job1/observations.csv" <<<"$per_photo" ||
  fail "DETECT_BATCH=0: the photos' observations are not joined: $(grep '^awk' <<<"$per_photo")"
grep -q "board_09.jpg" <<<"$quoted" || fail "the calibration photos were not expanded"

# Extra fitsurf options (the walkthrough's FITSURF+=...) keep the part box.
fit=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$demo/part_*.jpg" CALIB_PHOTOS="$demo/board_*.jpg" OUT=job1 \
      PART_BOX=-85,-60,-5,85,60,100 FITSURF+="--robust huber" | grep "^/opt/pm/bin/fitsurf" | head -1)
grep -q -- "--keep-box -85,-60,-5,85,60,100 --robust huber" <<<"$fit" || fail "FITSURF+= lost the part box: $fit"

if out=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="nowhere/*.jpg" OUT=job1 2>&1); then
  fail "a glob that matches nothing must stop make"
fi
grep -q "PHOTOS: 'nowhere/\*.jpg' matches no file" <<<"$out" || fail "unexpected message: $out"

# Photos named .JPG (as many cameras write them) work alike; two extensions in one PHOTOS stop make.
mkdir -p upper && for f in "$demo"/part_0[0-2].jpg; do n=$(basename "$f" .jpg); ln -s "$f" "upper/$n.JPG"; done
ln -s "$demo/part_03.jpg" upper/part_03.jpg
jpg=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*.JPG" CALIB_PHOTOS="$demo/board_*.jpg" OUT=job3 DETECT_BATCH=0)
n=$(grep -c "^/opt/pm/bin/detect --aruco .*upper/part_0[0-2]\.JPG -o job3/obs/part_0[0-2]\.csv" <<<"$jpg" || true)
[ "$n" -eq 3 ] || fail "expected one detect per .JPG photo (3), got $n"
grep -q "job3/feat/part_00.JPG.feat" <<<"$jpg" || fail "the .JPG photos' features are not matched"
if out=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*" OUT=job3 2>&1); then
  fail "photos of two extensions must stop make"
fi
grep -q "PHOTOS: one extension for all" <<<"$out" || fail "unexpected message: $out"

# BIN: the build beside the Makefile (a copy of it with a build/bin/detect of its own).
mkdir -p repo/build/bin && cp "$mk" repo/ && touch repo/build/bin/detect
cmds=$(make -n -f repo/Makefile.example PHOTOS="$demo/part_00.jpg" CALIB_PHOTOS="$demo/board_00.jpg" CONTROL="$demo/control_points.csv" OUT=job2)
grep -q "^repo/build/bin/detect " <<<"$cmds" || fail "BIN is not the build beside the Makefile: $(head -3 <<<"$cmds")"
# Photos only (MARKERS=0) with a camera given (CAMERA=): no calibration, no markers, no control
# points, every pair's features matched, an arbitrary scale, no part box, and no tool path.
touch given.yaml
free=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*.JPG" CALIB_PHOTOS="nowhere/*.jpg" CAMERA=given.yaml MARKERS=0 OUT=job4)
grep -q "^cp given.yaml job4/camera.yaml" <<<"$free" || fail "CAMERA= is not copied as the job's camera"
! grep -q -e "/calib " -e "--charuco" -e "--aruco" -e "--control-points" -e "--keep-box" -e "/toolpath " -e "/clpost " -e "/rough " <<<"$free" ||
  fail "MARKERS=0 still runs a step that needs markers, control points or mm: $(grep -e /calib -e --aruco -e --control-points -e --keep-box -e /toolpath -e /clpost -e /rough <<<"$free" | head -2)"
n=$(grep -c "^/opt/pm/bin/detect  --features job4/feat .*upper/part_00\.JPG upper/part_01\.JPG upper/part_02\.JPG *$" <<<"$free" || true)
[ "$n" -eq 1 ] || fail "expected one features-only detect for the 3 photos, got $n: $(grep detect <<<"$free" | head -1)"
grep -q "^/opt/pm/bin/match job4/feat/part_00.JPG.feat job4/feat/part_01.JPG.feat job4/feat/part_02.JPG.feat --camera job4/camera.yaml --root-sift -o job4/tracks.csv" <<<"$free" ||
  fail "MARKERS=0: match is not given every photo's features without poses (and --root-sift): $(grep /match <<<"$free")"
# ... and detect the cap by scale (the largest features, as COLMAP keeps them).
grep -q "^/opt/pm/bin/detect  --features job4/feat --max-features 11000 --cap-order scale .*upper/part_00\.JPG" <<<"$free" ||
  fail "MARKERS=0: detect without --max-features 11000 --cap-order scale: $(grep detect <<<"$free" | head -1)"
grep -q "^/opt/pm/bin/triangulate job4/tracks.csv --camera job4/camera.yaml --arbitrary-scale" <<<"$free" || fail "MARKERS=0: triangulate without --arbitrary-scale"
grep -q "^/opt/pm/bin/fitsurf job4/cloud.ply" <<<"$free" && grep -q "^/opt/pm/bin/report job4" <<<"$free" || fail "MARKERS=0: no surface or report"
if out=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*.JPG" CAMERA=given.yaml MARKERS=0 FEATURES=0 OUT=job4 2>&1); then
  fail "MARKERS=0 FEATURES=0 (nothing to match) must stop make"
fi
grep -q "MARKERS=0 needs FEATURES=1" <<<"$out" || fail "unexpected message: $out"
# Points clicked with pick (CLICKED=) join the markers' observations; not without markers.
touch clicked.csv
clicked=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$demo/part_*.jpg" CALIB_PHOTOS="$demo/board_*.jpg" CLICKED=clicked.csv OUT=job5)
grep -q "^awk .* job5/obs/all.csv clicked.csv > job5/observations.csv" <<<"$clicked" || fail "CLICKED= is not joined to the observations: $(grep '^awk' <<<"$clicked")"
if out=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*.JPG" CAMERA=given.yaml MARKERS=0 CLICKED=clicked.csv OUT=job5 2>&1); then
  fail "CLICKED= with MARKERS=0 must stop make"
fi
grep -q "CLICKED= joins the markers' observations: it needs MARKERS=1" <<<"$out" || fail "unexpected message: $out"
# make -n prints a recipe's continued lines as written: joined here.
join_lines() { sed -e ':a' -e '/\\$/N; s/\\\n//; ta'; }
# DENSE=1: densify between triangulate and fitsurf, with the job's refined camera, poses, markers
# and PART_BOX; fitsurf fits its dense.ply. Without markers: camera.yaml, no mask, no box.
dense=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="$demo/part_*.jpg" CALIB_PHOTOS="$demo/board_*.jpg" DENSE=1 DENSIFY="--spacing-px 3" OUT=job6)
grep -q "^/opt/pm/bin/densify job6/cloud.ply --camera job6/camera-refined.yaml --poses job6/poses.csv.*--observations job6/observations.csv --box -85,-60,-5,85,60,100 --spacing-px 3 -o job6/dense.ply" <<<"$(join_lines <<<"$dense")" ||
  fail "DENSE=1: densify is not run as expected: $(grep -A1 densify <<<"$dense" | head -2)"
grep -q "^/opt/pm/bin/fitsurf job6/dense.ply" <<<"$dense" || fail "DENSE=1: fitsurf does not fit dense.ply"
free_dense=$(make -n -f "$mk" BIN=/opt/pm/bin PHOTOS="upper/*.JPG" CAMERA=given.yaml MARKERS=0 DENSE=1 OUT=job7)
grep -q "^/opt/pm/bin/densify job7/cloud.ply --camera job7/camera.yaml --poses job7/poses.csv *-o job7/dense.ply" <<<"$(join_lines <<<"$free_dense")" ||
  fail "DENSE=1 MARKERS=0: densify is not run as expected: $(grep -A1 densify <<<"$free_dense" | head -2)"
echo "makefile_test: globs quoted or not, FITSURF+= keeps PART_BOX, an unmatched glob, .JPG photos, one extension, BIN beside the Makefile, MARKERS=0 with CAMERA=, CLICKED=, DENSE=1: ok"
