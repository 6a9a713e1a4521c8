#!/usr/bin/env bash
# ctest walkthrough_installed: photomill installed by `cmake --install` into a fresh prefix, then
# every command block of docs/walkthrough.md run as written, in empty folders outside the
# repository, with the installed tools only (issue 27):
#   - the blocks that print the targets (targets charuco / plate) in a print folder;
#   - the pipeline's make in a job folder holding board/, part/ and control_points.csv (the demo's
#     photos and plate), then synth_accuracy (a test tool of the build) against the demo's truth,
#     the surface held to 0.05 mm RMS and every other figure to its bound (the tool-path gouge
#     included);
#   - the job's report.html opened in headless Chromium (tests/browser/check_report.mjs; when
#     Chromium and playwright-core are installed, always in CI);
#   - CloudCompare (when installed: scripts/install-deps.sh --tests) loads every per-point value of
#     the cloud as a scalar field;
#   - the installed Makefile's own demo data: the scan and cad goals from an empty folder write
#     their G-code.
# The walkthrough writes the default prefix /usr/local; the test puts its prefix there.
# Usage: walkthrough_test.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -euo pipefail
src=$1 build=$2 work=$3
fail() { echo "walkthrough_test: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix

# --- the install ------------------------------------------------------------------------------
cmake --install "$build" --prefix "$prefix" >/dev/null
tools=(calib clpost cutsim densify detect fitsurf match pick report rough targets toolpath triangulate)
installed=$(cd "$prefix/bin" && ls | sort | tr '\n' ' ')
[ "$installed" = "${tools[*]} " ] || fail "$prefix/bin holds '$installed', not the user tools '${tools[*]}'"
for f in share/photomill/Makefile.example share/photomill/data/demo/part_00.jpg \
         share/photomill/data/demo/control_points.csv share/doc/photomill/README.md \
         share/doc/photomill/walkthrough.md; do
  [ -s "$prefix/$f" ] || fail "the install has no $f"
done
[ ! -e "$prefix/share/doc/photomill/measurements" ] || fail "the install holds the measurements notebook"
for t in "${tools[@]}"; do
  grep -q -- "--help" "$prefix/share/doc/photomill/help/$t.txt" || fail "no --help text installed for $t"
done
export PATH=$prefix/bin:$PATH

# --- the walkthrough's command blocks, as written ------------------------------------------------
blocks=$work/blocks
mkdir -p "$blocks"
awk -v dir="$blocks" '
  /^ *```sh *$/ { n++; inside = 1; next }
  /^ *```/ { inside = 0; next }
  inside { sub(/^  /, ""); print > (dir "/" n ".sh") }' "$src/docs/walkthrough.md"
n_blocks=$(ls "$blocks" | wc -l)
[ "$n_blocks" -ge 3 ] || fail "expected at least 3 command blocks in docs/walkthrough.md, found $n_blocks"
sed -i "s#/usr/local#$prefix#g" "$blocks"/*.sh

mkdir -p "$work/print" "$work/job/board" "$work/job/part"
cp "$src"/data/demo/board_*.jpg "$work/job/board/"
cp "$src"/data/demo/part_*.jpg "$work/job/part/"
cp "$src/data/demo/control_points.csv" "$work/job/"
ran_make=0
for b in $(ls "$blocks" | sort -n); do
  script=$blocks/$b
  if grep -q "^make " "$script"; then
    echo "walkthrough_test: block $b (the pipeline) in the job folder:" >&2
    sed 's/^/  /' "$script" >&2
    start=$SECONDS
    (cd "$work/job" && bash -euo pipefail "$script" >/dev/null 2>"$work/job/make.log") ||
      { tail -20 "$work/job/make.log" >&2; fail "block $b failed (its make log above)"; }
    echo "walkthrough_test: block $b took $((SECONDS - start)) s" >&2
    ran_make=1
  else
    echo "walkthrough_test: block $b in the print folder: $(head -1 "$script")" >&2
    (cd "$work/print" && bash -euo pipefail "$script" 2>"$work/print/block$b.log") ||
      { cat "$work/print/block$b.log" >&2; fail "block $b failed"; }
  fi
done
[ $ran_make = 1 ] || fail "no block of docs/walkthrough.md runs make"
for f in board.pdf plate.pdf control_points.csv; do
  [ -s "$work/print/$f" ] || fail "the walkthrough's targets blocks wrote no $f"
done
out=$(sed -n 's/.*OUT=\([^ ]*\).*/\1/p' "$blocks"/*.sh | head -1)
[ -n "$out" ] && [ -s "$work/job/$out/part.ngc" ] || fail "the walkthrough's make wrote no part.ngc (OUT=$out)"
"$build/tools/bin/synth_accuracy" -q --truth "$src/data/demo" --outputs "$work/job/$out" --surface-rms-bound-mm 0.05
# The program as a controller reads it (issue 26): the generic word set, the spindle on before every feed.
python3 "$src/toolpath/gcode_check.py" "$work/job/$out/part.ngc" >&2 || fail "$out/part.ngc: see gcode_check above"

# --- the job's report page (issue 27): every picture and the headline figures, in headless Chromium -----
[ -s "$work/job/$out/report.html" ] || fail "the walkthrough's make wrote no $out/report.html"
for d in "$work/job/$out"/drawings/*; do
  case $(basename "$d") in *.jpg.jpg|*.jpg.png) fail "a drawing named $(basename "$d"): the photo's stem and one extension expected";; esac
done
if command -v node >/dev/null; then
  rc=0
  node "$src/tests/browser/check_report.mjs" "$work/job/$out/report.html" "$work/job/$out" || rc=$?
  [ $rc = 0 ] || [ $rc = 77 ] || fail "the job's report.html does not pass the browser check (above)"
elif [ -n "${CI:-}" ]; then
  fail "node is not installed (scripts/install-deps.sh --tests installs it)"
else
  echo "walkthrough_test: node is not installed (scripts/install-deps.sh --tests): report.html not opened" >&2
fi

# --- a neighbour reads the cloud: CloudCompare loads every per-point value as a scalar field -------
if command -v CloudCompare >/dev/null; then
  (cd "$work/job" && QT_QPA_PLATFORM=offscreen timeout 300 CloudCompare -SILENT -AUTO_SAVE OFF -O "$out/cloud.ply" \
     -C_EXPORT_FMT ASC -ADD_HEADER -SAVE_CLOUDS FILE cloud_cc.asc >cloudcompare.log 2>&1) ||
    { tail -5 "$work/job/cloudcompare.log" >&2; fail "CloudCompare could not load $out/cloud.ply"; }
  header=$(head -1 "$work/job/cloud_cc.asc")
  for field in track_id views reproj_rms_px sigma_mm control; do
    grep -qw "$field" <<<"$header" || fail "CloudCompare loaded no scalar field $field from cloud.ply (its columns: $header)"
  done
  echo "walkthrough_test: CloudCompare loads cloud.ply's scalar fields: ${header#//}" >&2
elif [ -n "${CI:-}" ]; then
  fail "CloudCompare is not installed (scripts/install-deps.sh --tests installs it)"
else
  echo "walkthrough_test: CloudCompare is not installed (scripts/install-deps.sh --tests): cloud.ply's fields not checked" >&2
fi

# --- the installed Makefile's own demo data, from an empty folder ----------------------------------
mkdir -p "$work/empty"
# (scan first: cad's input is the STEP surface the scan goal writes)
(cd "$work/empty" && make -s -f "$prefix/share/photomill/Makefile.example" -j2 OUT=demo scan >/dev/null 2>"$work/empty/make.log" &&
   make -s -f "$prefix/share/photomill/Makefile.example" -j2 OUT=demo cad >/dev/null 2>>"$work/empty/make.log") ||
  { tail -20 "$work/empty/make.log" >&2; fail "the installed Makefile's scan and cad goals failed"; }
for f in demo/scan/part.ngc demo/cad/part.ngc; do
  [ -s "$work/empty/$f" ] || fail "the installed demo wrote no $f"
  python3 "$src/toolpath/gcode_check.py" "$work/empty/$f" >&2 || fail "$f: see gcode_check above"
done
# (their accuracy: ctest demo_scan_chain, the same goal from the source tree)
echo "walkthrough_test: installed into $prefix; the walkthrough's $n_blocks blocks and the installed demo's scan and cad goals ran" >&2
