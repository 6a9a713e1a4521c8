#!/usr/bin/env bash
# Builds the libFuzzer harnesses with clang (ASan + UBSan) and runs each for a given time,
# then prints executions and coverage per harness. Crash inputs are copied to out/fuzz/crashes;
# commit them as tests/fuzz/corpus/TARGET/crash-* so ctest replays them from then on.
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
# With FUZZ_RUNS=N in the environment each harness stops after N executions or the time limit,
# whichever comes first (the campaign of issue 11: FUZZ_RUNS=10000000 scripts/fuzz.sh 1800).
# FUZZ_TIMEOUT=S (default 5) is the wall-clock limit per input; raise it when the campaign runs
# at low priority beside other work, where a starved process can exceed 5 s on any input.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
all=(observations control_points tracks poses scale_bars point_cloud surface cl_data camera_yaml features step iges known_poses json uncertainty_grid)
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${all[@]}")

build=${PHOTOMILL_FUZZ_BUILD_DIR:-build-fuzz}
CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPHOTOMILL_FUZZ=ON -DPHOTOMILL_TESTS=ON >&2
cmake --build "$build" -j"$(nproc)" --target $(printf 'fuzz_%s ' "${targets[@]}") >&2

work=out/fuzz
mkdir -p "$work/crashes"
printf '%-16s %12s %8s %8s %8s %s\n' target executions cov ft seconds result
status=0
for t in "${targets[@]}"; do
  corpus="$work/corpus/$t"
  mkdir -p "$corpus"
  cp -n tests/fuzz/corpus/"$t"/* "$corpus"/ 2>/dev/null || true
  log="$work/$t.log"
  set +e
  start=$(date +%s)
  # tests/lsan.supp: Open CASCADE's one-time static allocations (constant per process; a leak
  # that grows with the number of inputs would still be reported).
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp" \
  "$build/fuzz/fuzz_$t" "$corpus" -max_total_time="$seconds" -timeout="${FUZZ_TIMEOUT:-5}" -rss_limit_mb=2048 \
      -malloc_limit_mb=512 -max_len=65536 -print_final_stats=1 ${FUZZ_RUNS:+-runs="$FUZZ_RUNS"} -artifact_prefix="$work/crashes/$t-" \
      > "$log" 2>&1
  rc=$?
  set -e
  elapsed=$(( $(date +%s) - start ))
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*')
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*')
  result=ok
  if [ $rc -ne 0 ]; then result="FAILED (see $log)"; status=1; fi
  printf '%-16s %12s %8s %8s %8s %s\n' "$t" "${execs:-?}" "${cov:-?}" "${ft:-?}" "$elapsed" "$result"
done
exit $status
