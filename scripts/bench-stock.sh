#!/usr/bin/env bash
# The uncertainty-aware stock (issue #24) on finished runs of the default chain: for each SET (a
# synth set, its run in SET-out, or data/demo with its run given as SET=RUN), the chain is rerun
# from fitsurf on (Makefile.example, hard links to the run's earlier outputs) with the stock off and
# at STOCK_K = each K, and judged by synth_accuracy: surface RMS, gouge, excess material p95 / max.
# Usage: scripts/bench-stock.sh WORK "K1 K2 ..." SET[=RUN]...   (BUILD=build by default; DENSE=1
# fits the run's dense.ply, which a DENSE=1 run or scripts/bench-densify.sh left there)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD:-$here/build}
work=$1 ks=$2
shift 2
mkdir -p "$work"
printf '%-28s %-4s %9s %9s %9s %9s %9s\n' set k surf_rms gouge left_p95 left_max sigma_max
for arg in "$@"; do
  set_dir=${arg%%=*}
  run=${arg#*=}
  [ "$run" != "$arg" ] || run=$set_dir-out
  name=$(basename "$set_dir")
  for k in off $ks; do
    out=$work/$name-k$k
    rm -rf "$out"
    cp -al "$run" "$out"
    rm -f "$out"/{surface.txt,surface.step,surface.png,fitsurf.json,uncertainty.csv,path.cl,path.png,toolpath.json,part.ngc}
    make -s -f "$here/Makefile.example" BIN="$build/bin" DEMO="$set_dir" OUT="$out" DENSE="${DENSE:-0}" \
      STOCK_K="$([ "$k" = off ] || echo "$k")" "$out/part.ngc" >"$out.log" 2>&1 || { echo "$name k=$k: make failed ($out.log)"; continue; }
    acc=$("$build/tools/bin/synth_accuracy" --truth "$set_dir" --outputs "$out" 2>&1 || true)
    fig() { grep -m1 "^$1:" <<<"$acc" | sed -E 's/^[^:]*: (-?inf|nan|[-0-9.e]+) .*/\1/' | xargs printf '%.4f'; }
    smax=$(grep -o '"sigma_max_mm": *[0-9.e-]*' "$out/toolpath.json" | sed 's/.*: *//' || true)
    printf '%-28s %-4s %9s %9s %9s %9s %9s\n' "$name" "$k" "$(fig 'surface deviation RMS')" "$(fig 'tool path gouge max')" \
      "$(fig 'tool path excess material p95')" "$(fig 'tool path excess material max')" "${smax:--}"
  done
done
