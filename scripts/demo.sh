#!/usr/bin/env bash
# Installs the dependencies (Debian 12), builds photomill and runs the pipeline on the bundled
# demo photos in data/demo, as far as the stages are built. Outputs go to out/demo/.
# This is the README's demo command.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

build=${PHOTOMILL_BUILD_DIR:-build}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >&2
cmake --build "$build" -j"$(nproc)" >&2

exec bash scripts/run-demo.sh "$build/bin"
