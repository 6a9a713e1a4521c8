#!/usr/bin/env bash
# rough beside FreeCAD 0.20 Path Adaptive (issue 26; docs/measurements/roughing.md): both clear
# the same stock box with the same 6 mm flat end mill (step-down 2 mm, step-over 40 % = 2.4 mm,
# allowance 0.5 mm, feed 1000 and plunge/ramp/helix feed 300 mm/min) down to the same surface.
# photomill: `rough` on the surface text. FreeCAD: scripts/freecad_adaptive.py under freecadcmd on
# the same surface as STEP (one Adaptive operation per level, see that script for why), posted by
# FreeCAD's LinuxCNC post and read back into CL CSV. Both CL CSVs are measured by
# scripts/bench_rough_table.py: CL moves, feed and rapid lengths, cycle time with the rapids at
# RAPID_MM_PER_MIN (5000, an assumption), the wall time of the program that makes the path; and,
# when the build has `cutsim`, what is left of the stock (cutsim on each CL with the same tool);
# with python3 + numpy, the vertical cut into the allowance and below the surface from
# scripts/zmap_crosscheck.py (a rough cross-check, not cutsim: cutsim reports no such figure).
# FreeCAD runs twice: the allowance under the tool as rough has it, and StockToLeave 0.5 alone.
# About 80 s on 2 cores.
#
# FreeCAD is a peer for this benchmark, never a dependency of photomill: without `freecadcmd` the
# script says so and exits 0 (Debian 12: apt-get install freecad; 0.20.2). Not a ctest.
#   scripts/bench-rough.sh [BIN_DIR] [SURFACE.txt] [SURFACE.step] [KEEP_DIR]
# BIN_DIR holds rough (and cutsim, when built; CUTSIM=path overrides); default build/bin. SURFACE
# defaults to the demo's out/demo/surface.{txt,step}. KEEP_DIR, when given, keeps the CL files,
# G-code, logs and reports.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
bin=$(cd "${1:-$root/build/bin}" && pwd)
surf_txt=$(realpath "${2:-$root/out/demo/surface.txt}")
surf_step=$(realpath "${3:-$root/out/demo/surface.step}")
keep=${4:-}
tool_d=6 step_down=2 step_over_pct=40 allowance=0.5 feed=1000 plunge=300
rapid=${RAPID_MM_PER_MIN:-5000}

if ! command -v freecadcmd >/dev/null 2>&1; then
  echo "bench-rough: skipped: freecadcmd (FreeCAD) is not installed; it is only a peer for this" \
    "comparison (Debian: apt-get install freecad)" >&2
  exit 0
fi
if [ -n "$keep" ]; then
  mkdir -p "$keep"
  work=$(cd "$keep" && pwd)
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi
cd "$work"

now() { date +%s.%N; }
echo "== machine: $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo "== rough: $bin/rough"
echo "== surface: $surf_txt (and $surf_step)"

# photomill: rough with its default stock (the surface's box + 2 mm), which the stderr states, and
# its default step-over (0: 40 % of the diameter)
rough_args=(--tool-diameter-mm $tool_d --step-down-mm $step_down
  --allowance-mm $allowance --feed-mm-per-min $feed --plunge-feed-mm-per-min $plunge)
t0=$(now)
"$bin/rough" "${rough_args[@]}" --format csv "$surf_txt" -o rough.csv 2>rough.err
t1=$(now)
rough_s=$(python3 -c "print('%.2f' % ($t1 - $t0))")
stock=$(sed -n 's/^rough: stock \([-0-9.]*\),\([-0-9.]*\),\([-0-9.]*\) to \([-0-9.]*\),\([-0-9.]*\),\([-0-9.]*\) mm.*/\1,\2,\3,\4,\5,\6/p' rough.err)
[ -n "$stock" ] || { echo "bench-rough: no stock line in rough's stderr:" >&2; cat rough.err >&2; exit 1; }
echo "== stock box: $stock mm"
echo "== rough: $(grep -m1 ' levels ' rough.err | sed 's/^rough: //')"

# FreeCAD: Path Adaptive, one operation per level, on the same stock. Two settings of the
# allowance: `adaptive` keeps the tool radius off the part's section at z - 0.5 (the allowance
# under the tool, as rough: the same free region), StockToLeave 0; `adaptive-stl` is the literal
# reading, the section at z and StockToLeave 0.5 (the allowance only sideways).
fc_run() {  # NAME ISLAND_ALLOWANCE STOCK_TO_LEAVE
  local t0 t1
  t0=$(now)
  FC_STEP="$surf_step" FC_STOCK="$stock" FC_OUT="$work/$1" FC_TOOL_D=$tool_d \
    FC_STEP_DOWN=$step_down FC_STEP_OVER=$step_over_pct FC_ALLOWANCE=$allowance \
    FC_ISLAND_ALLOWANCE=$2 FC_STOCK_TO_LEAVE=$3 FC_FEED=$feed FC_PLUNGE_FEED=$plunge \
    freecadcmd "$root/scripts/freecad_adaptive.py" >$1.log 2>&1 || true
  t1=$(now)
  if ! grep -q '^RESULT cl_moves' $1.log; then
    echo "bench-rough: FreeCAD's Adaptive run failed ($1.log):" >&2
    grep -v '%)' $1.log | tail -30 >&2
    exit 1
  fi
  result() { sed -n "s/^RESULT $1 //p" $2.log; }
  fc_s[$1]=$(python3 -c "print('%.2f' % ($t1 - $t0))")
  ad_s[$1]=$(python3 -c "print('%.2f' % $(result adaptive_s $1))")
  echo "== $1: FreeCAD $(result freecad_version $1), $(result levels $1) Adaptive operations," \
    "levels $(result first_level $1) to $(result last_level $1) mm, $(result regions $1) regions," \
    "$(result helix_entries $1) helix entries; Adaptive's recompute ${ad_s[$1]} s of the whole" \
    "freecadcmd run ${fc_s[$1]} s (start, import, sections, job, post, read-back)"
}
declare -A fc_s ad_s
fc_run adaptive $allowance 0
fc_run adaptive-stl 0 $allowance

# remaining stock: cutsim, when built, on each program with the same tool (a CSV has no tool)
declare -A rep
table_args=()
cutsim=${CUTSIM:-$bin/cutsim}
if [ -x "$cutsim" ]; then
  for p in rough adaptive adaptive-stl; do
    "$cutsim" "$surf_txt" $p.csv --stock-box-mm "$stock" --allowance-mm $allowance \
      --tool-diameter-mm $tool_d --corner-radius-mm 0 --report $p-cutsim.json >$p-cutsim.txt 2>&1 || true
    [ -s $p-cutsim.json ] && rep[$p]=:$p-cutsim.json
    sed 's/^/== /' $p-cutsim.txt | grep -v 'cutting the stock'
  done
  table_args+=(--cutsim)
else
  echo "== no $cutsim: the remaining stock is not measured by cutsim"
fi
# the cross-check (vertical, a rough numpy z-map; not cutsim): needs python3 with numpy
py=""
for c in python3 /usr/bin/python3; do
  if command -v $c >/dev/null && $c -c 'import numpy' 2>/dev/null; then py=$c; break; fi
done
if [ -n "$py" ]; then
  $py "$root/scripts/zmap_crosscheck.py" "$surf_txt" "$stock" $tool_d $allowance 0.2 \
    rough.csv adaptive.csv adaptive-stl.csv >xcheck.txt
  table_args+=(--crosscheck xcheck.txt)
else
  echo "== no python3 with numpy: no z-map cross-check"
fi

echo "== cycle time: each feed move at its feed rate, rapids at $rapid mm/min (assumed)"
python3 "$root/scripts/bench_rough_table.py" --rapid-mm-per-min "$rapid" --plunge-feed $plunge \
  "${table_args[@]}" \
  "photomill rough:rough.csv:$rough_s${rep[rough]:-}" \
  "FreeCAD Adaptive, section at z - 0.5:adaptive.csv:${fc_s[adaptive]} (Adaptive ${ad_s[adaptive]})${rep[adaptive]:-}" \
  "FreeCAD Adaptive, StockToLeave 0.5:adaptive-stl.csv:${fc_s[adaptive-stl]} (Adaptive ${ad_s[adaptive-stl]})${rep[adaptive-stl]:-}"
