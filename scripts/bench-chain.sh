#!/usr/bin/env bash
# The demo's full chain (Makefile.example all, make -j2, from scratch) timed for several
# configurations in turn, so that they are compared on the same machine in the same minutes
# (issue #30: the chain's wall time). A configuration is LABEL=BIN_DIR[,make arguments...];
# each of its runs prints the chain's wall time and the load average before it, then per tool:
# runs, wall, CPU (user + sys) and peak resident memory summed over the run (GNU time).
# Usage: scripts/bench-chain.sh ROUNDS CONFIG...
#   e.g. scripts/bench-chain.sh 2 now=build/bin before=/work/old/bin,DETECT_BATCH=0
# PHOTOMILL_BENCH_PAUSE=S waits S seconds before each run (the load of the last one to decay).
# Not a test: about 40 s a run.
set -euo pipefail
rounds=$1
shift
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d /tmp/bench-chain.XXXXXX)
trap 'rm -rf "$work"' EXIT
cd "$repo"
for r in $(seq "$rounds"); do
  for config in "$@"; do
    label=${config%%=*}
    rest=${config#*=}
    IFS=, read -r -a parts <<<"$rest"
    bin=$(cd "${parts[0]}" && pwd)
    args=("${parts[@]:1}")
    # Every tool behind a wrapper appending "tool wall user sys max_rss_kb" per run.
    wrap=$work/wrap-$label
    rm -rf "$wrap" && mkdir -p "$wrap"
    for t in "$bin"/*; do
      n=$(basename "$t")
      printf '#!/bin/sh\nexec /usr/bin/time -a -o %s/times -f "%s %%e %%U %%S %%M" %s "$@"\n' "$wrap" "$n" "$t" >"$wrap/$n"
      chmod +x "$wrap/$n"
    done
    out=$work/out-$label
    rm -rf "$out"
    sleep "${PHOTOMILL_BENCH_PAUSE:-0}"
    load=$(cut -d' ' -f1-3 /proc/loadavg)
    start=$(date +%s.%N)
    make -s -f Makefile.example -j2 BIN="$wrap" OUT="$out" "${args[@]}" all >"$work/log" 2>&1 ||
      { echo "bench-chain: $label failed (round $r):" >&2; tail -5 "$work/log" >&2; exit 1; }
    end=$(date +%s.%N)
    printf '%s round %d: %.1f s wall (load before %s)\n' "$label" "$r" "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')" "$load"
    awk '{ n[$1]++; w[$1] += $2; c[$1] += $3 + $4; if ($5 > m[$1]) m[$1] = $5 }
         END { for (t in n) printf "  %-12s %2d runs %6.2f s wall %6.2f s CPU %5d MB\n", t, n[t], w[t], c[t], m[t] / 1024 }' \
      "$wrap/times" | sort -k4 -n -r
  done
done
