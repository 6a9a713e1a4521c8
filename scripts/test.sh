#!/usr/bin/env bash
# Installs the dependencies (Debian 12), builds photomill and runs the whole test suite.
#   scripts/test.sh              Release build in build/ (the README's test command)
#   scripts/test.sh --sanitize   the suite without its `slow` tests, built with ASan + UBSan in build-asan/
# CI (.ci/run) runs both, the Release suite first. The sanitizer pass leaves out the tests labelled
# `slow` (real sets, whole chains, peers, the heaviest cases: CMakeLists.txt, photomill_add_test),
# which run in the Release pass. Its build keeps NDEBUG and -O2 with line tables only (-g1),
# enough for symbolised reports and faster to build than full debug information.
set -euo pipefail
cd "$(dirname "$0")/.."

mode=release
if [ "${1:-}" = "--sanitize" ]; then mode=sanitize; fi

bash scripts/install-deps.sh --tests

jobs=${PHOTOMILL_JOBS:-$(nproc)}
werror=OFF
if [ "${CI:-}" = "true" ]; then werror=ON; fi

if [ $mode = sanitize ]; then
  build=${PHOTOMILL_BUILD_DIR:-build-asan}
  select=(-LE slow)
  # clang builds the sanitized suite in about half of GCC's time on this code (Ceres' and Eigen's
  # templates) and ships the sanitizer runtimes photomill's fuzzers use too.
  export CC=${CC:-clang} CXX=${CXX:-clang++}
  # Warnings fail the Release pass (GCC); clang's own are shown here but do not stop the pass.
  werror=OFF
  # The benchmark programs no test runs are not built here (PHOTOMILL_BENCH_TOOLS; the Release
  # pass builds them), nor the test programs whose every case is slow (PHOTOMILL_SLOW_TESTS,
  # tests/slow.txt).
  # Without the precompiled header (CMakeLists.txt, PHOTOMILL_PCH): every unit then parses its
  # own includes, so one that forgets an #include fails here instead of compiling on the header.
  extra=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG"
         "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" -DPHOTOMILL_SANITIZE=ON -DPHOTOMILL_PCH=OFF
         -DPHOTOMILL_BENCH_TOOLS=OFF -DPHOTOMILL_SLOW_TESTS=OFF)
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
  export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/tests/lsan.supp:print_suppressions=0}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
else
  build=${PHOTOMILL_BUILD_DIR:-build}
  select=()
  extra=(-DCMAKE_BUILD_TYPE=Release)
  # The Release pass is GCC's (with -Werror in CI): a folder the demo command configured with
  # clang (scripts/demo.sh) is configured anew, unless CXX asks for clang.
  if [ -z "${CXX:-}" ] && grep -qs '^CMAKE_CXX_COMPILER:.*clang' "$build/CMakeCache.txt"; then
    echo "test.sh: $build was configured with clang (scripts/demo.sh); configuring it with the default compiler" >&2
    cmake --build "$build" --target clean >/dev/null 2>&1 || true  # no clang object stays
    rm -rf "$build/CMakeCache.txt" "$build/CMakeFiles"
  fi
fi

start=$(date +%s)
cmake -S . -B "$build" "${extra[@]}" -DPHOTOMILL_WERROR="$werror" >&2
cmake --build "$build" -j"$jobs"
built=$(date +%s)
ctest --test-dir "$build" -j"$jobs" --output-on-failure --timeout 900 "${select[@]}"
echo "test.sh ($mode): build $((built - start)) s, tests $(( $(date +%s) - built )) s" >&2
