#!/usr/bin/env bash
# Remakes the bundled demo set data/demo/ with synth: 12 part views and 10 ChArUco board views at
# 2000x1500 with their truth (see data/demo/README.md). Deterministic: the same synth gives the
# same files (their stamps' run id is PHOTOMILL_RUN_ID, "demo" unless set). Usage: scripts/make-demo.sh [BUILD_DIR]   (default: build)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-build}
synth="$build/tools/bin/synth"
if [ ! -x "$synth" ]; then
  echo "make-demo: $synth not found; build it first: cmake --build $build --target synth" >&2
  exit 1
fi
out="$here/data/demo"
# Render into a fresh folder and swap it in only on success: a failed run leaves the old set.
tmp=$(mktemp -d "$here/data/.demo.XXXXXX")
chmod 755 "$tmp"
trap 'rm -rf "$tmp"' EXIT
PHOTOMILL_RUN_ID=${PHOTOMILL_RUN_ID:-demo} "$synth" -o "$tmp" \
  --shape bumps --views 12 --calib-views 10 \
  --width 2000 --height 1500 --fx 2400 \
  --supersampling 2 --noise-sigma 1.0 --jpeg-quality 85 --speckle-mm 1.6 \
  --surface-step-mm 2 --seed 2024
if [ -f "$out/README.md" ]; then cp "$out/README.md" "$tmp/README.md"; fi
rm -rf "$out"
mv "$tmp" "$out"
trap - EXIT
du -sh "$out" >&2
