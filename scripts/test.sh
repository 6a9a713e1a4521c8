#!/usr/bin/env bash
# Installs the dependencies (Debian 12), builds photomill in build/ and runs the whole test suite.
# This is the README's test command, and what CI (.ci/run) calls.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

build=${PHOTOMILL_BUILD_DIR:-build}
jobs=${PHOTOMILL_JOBS:-$(nproc)}
werror=OFF
if [ "${CI:-}" = "true" ]; then werror=ON; fi

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DPHOTOMILL_WERROR="$werror" >&2
cmake --build "$build" -j"$jobs"
ctest --test-dir "$build" -j"$jobs" --output-on-failure --timeout 600
