#!/usr/bin/env bash
# ctest demo_scan_chain (and, with "all", demo_photo_chain): runs Makefile.example on data/demo
# with the binaries of this build into a fresh folder, then synth_accuracy against the demo's
# truth. Fails when make fails or any figure is out of bounds (e.g. a tool-path gouge).
#   demo_chain_test.sh SOURCE_DIR BIN_DIR WORK_DIR scan|all [make variables...]
set -euo pipefail
src=$1 bin=$2 work=$3 goal=$4
shift 4
rm -rf "$work"
mkdir -p "$work"
make -s -C "$src" -f Makefile.example -j2 BIN="$bin" OUT="$work" "$goal" "$@" >&2
outputs=$work
[ "$goal" = scan ] && outputs=$work/scan
"$bin/synth_accuracy" -q --truth "$src/data/demo" --outputs "$outputs"
