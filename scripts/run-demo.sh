#!/usr/bin/env bash
# Runs Makefile.example on the bundled demo data with the binaries in $1 (default build/bin), as
# far as the stages are built, then says where each output is and how accurate it is against the
# demo's truth (synth_accuracy, a test tool: from $2, default the build's tools/ beside $1).
# Stages not built yet are named, not faked.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/bin}
tools=${2:-$(dirname "$bin")/tools/bin}
out=${PHOTOMILL_DEMO_OUT:-out/demo}
jobs=${PHOTOMILL_JOBS:-$(nproc)}
# Other work on the machine slows the chains down; say how busy it was.
load=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown)

# (Captured, not piped: under pipefail an unbuilt stage's exit status 1 would decide the pipeline's.)
built() { local err; err=$("$bin/$1" 2>&1 >/dev/null </dev/null || true); [[ $err != *"not built yet"* ]]; }
has_option() { local help; help=$("$bin/$1" --help 2>/dev/null || true); [[ $help == *"$2"* ]]; }

markers_out=$out-markers
times=()
# make_demo LABEL OUT [make arguments]: one make, timed.
make_demo() {
  local label=$1 dir=$2 start=$SECONDS
  shift 2
  make -f Makefile.example -j"$jobs" BIN="$bin" OUT="$dir" "$@"
  times+=("$(printf '%-52s %3d s' "$label" $((SECONDS - start)))")
  echo "photomill demo: $label took $((SECONDS - start)) s" >&2
}

# Each chain from scratch, so the times printed are the whole chain's.
make -s -f Makefile.example OUT="$out" clean
make -s -f Makefile.example OUT="$markers_out" clean
pending=()
chain=0
if built calib && built detect; then
  if has_option detect --aruco && built match && built triangulate && built fitsurf && built toolpath; then
    chain=1
    make_demo "full chain (markers + features), calibration included" "$out" all
    make_demo "markers-only chain (FEATURES=0), calibration included" "$markers_out" all FEATURES=0
  else
    make_demo "calibration" "$out" calibration
  fi
else
  pending+=("calibration (calib/detect)")
fi
if [ $chain = 0 ]; then
  for s in match triangulate; do built "$s" || pending+=("$s"); done
  has_option detect --aruco || pending+=("detect --aruco (markers)")
fi
if built fitsurf && built toolpath; then
  # The swap-a-stage examples: the demo's true surface sample as "another scanner's" cloud, and
  # the STEP surface fitsurf wrote as "a CAD system's" surface.
  make_demo "scan chain (surface.ply -> fitsurf -> toolpath)" "$out" scan
  make_demo "cad chain (surface.step -> toolpath)" "$out" cad
fi

echo
echo "photomill demo outputs ($out):"
for f in camera.yaml calib.png drawings observations.csv markers/cloud.ply tracks.csv cloud.ply cloud.png \
         poses.csv camera-refined.yaml surface.txt surface.step surface.png \
         path.cl path.png part.ngc scan/surface.txt scan/surface.step scan/path.cl scan/path.png \
         scan/part.ngc cad/path.cl cad/part.ngc report.html; do
  [ -e "$out/$f" ] && printf '  %-22s %s\n' "$f" "$(du -h "$out/$f" | cut -f1)"
done
if [ ${#pending[@]} -gt 0 ]; then
  echo "photomill demo: not built yet, so not run: ${pending[*]}"
fi

echo
echo "Accuracy against the demo's truth (photos -> G-code, markers and features):"
# Figures out of bounds are reported (FAIL), not hidden; the demo itself has still run.
"$tools/synth_accuracy" -q --truth data/demo --outputs "$out" ||
  echo "photomill demo: some figures are out of bounds (FAIL above)"
if [ -e "$markers_out/surface.txt" ]; then
  echo
  echo "Accuracy of the markers-only chain ($markers_out; a quick check, not meant to meet the bounds):"
  "$tools/synth_accuracy" -q --truth data/demo --outputs "$markers_out" ||
    echo "photomill demo: some figures are out of bounds (FAIL above)"
fi
if [ -e "$out/scan/surface.txt" ]; then
  echo
  echo "Accuracy of the scanner-swap chain (true surface sample -> fitsurf -> toolpath):"
  { "$tools/synth_accuracy" -q --truth data/demo --outputs "$out/scan" ||
      echo "photomill demo: some figures are out of bounds (FAIL above)"; } | grep -v -E '^(calibration|marker)'
fi

echo
echo "Times (make -j$jobs on $(nproc) cores; load average before the run: $load):"
printf '  %s\n' "${times[@]}"
