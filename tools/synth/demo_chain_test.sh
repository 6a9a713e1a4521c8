#!/usr/bin/env bash
# ctest demo_scan_chain (and by hand any goal): runs Makefile.example's goal on data/demo with the
# binaries of this build into a fresh folder, then synth_accuracy against the demo's truth. Fails
# when make fails or a figure is out of bounds (e.g. a tool-path gouge), unless the figure is
# given with --expect-fail (a known failure of an open issue; it then fails when within bounds).
#   demo_chain_test.sh SOURCE_DIR BIN_DIR WORK_DIR scan|all [--synth_accuracy-option VALUE...] [VAR=value...]
set -euo pipefail
src=$1 bin=$2 work=$3 goal=$4
tools=$(dirname "$bin")/tools/bin  # synth_accuracy: a test tool, in the build's tools/
shift 4
accuracy=() make_vars=()
while [ $# -gt 0 ]; do
  case $1 in
    --*) accuracy+=("$1" "$2"); shift 2 ;;  # synth_accuracy's options all take a value
    *) make_vars+=("$1"); shift ;;
  esac
done
rm -rf "$work"
mkdir -p "$work"
start=$SECONDS
make -s -C "$src" -f Makefile.example -j2 BIN="$bin" OUT="$work" "$goal" ${make_vars[@]+"${make_vars[@]}"} >&2
echo "demo_chain_test: make $goal took $((SECONDS - start)) s" >&2
outputs=$work
[ "$goal" = scan ] && outputs=$work/scan
"$tools/synth_accuracy" -q --truth "$src/data/demo" --outputs "$outputs" ${accuracy[@]+"${accuracy[@]}"}
