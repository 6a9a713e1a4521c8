#!/usr/bin/env bash
# Installs the dependencies (Debian 12), builds photomill and runs the pipeline on the bundled
# demo photos in data/demo, as far as the stages are built. Outputs go to out/demo/.
# This is the README's demo command.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

build=${PHOTOMILL_BUILD_DIR:-build}
# A new build folder is configured with clang (installed by install-deps.sh, as the sanitizer
# pass uses it): it compiles photomill's Ceres and Eigen code in about 60 % of GCC's time
# (docs/measurements/walkthrough.md). A folder already configured keeps its compiler; CC and CXX
# given by the caller win. scripts/test.sh reconfigures a clang folder with GCC for its Release pass.
if [ ! -f "$build/CMakeCache.txt" ] && [ -z "${CXX:-}" ] && command -v clang++ >/dev/null; then
  export CC=clang CXX=clang++
fi
start=$SECONDS
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >&2
# Only what the demo runs: the tools of its chains and the accuracy check (CMakeLists.txt,
# demo_tools; not densify, targets, cutsim, pick, nor the test suite).
cmake --build "$build" -j"$(nproc)" --target demo_tools >&2
echo "photomill demo: configure and build took $((SECONDS - start)) s" >&2
echo "photomill demo: the other user tools (densify, targets, cutsim, pick): cmake --build $build --target user_tools" >&2

exec bash scripts/run-demo.sh "$build/bin"
