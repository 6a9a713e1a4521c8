#!/usr/bin/env bash
# fitsurf against FreeCAD's approxSurface (ReverseEngineering module) on the same points (issue
# #7): 30 000 points on fitsurf's `bumps` test shape (fitsurf/test_shapes.hpp, 150 x 100 mm) with
# 0.01 mm Gaussian noise, a 20 x 20 bicubic net for both, parameter correction on for both.
# Prints each fitter's time, the RMS and max of its residuals (orthogonal distances of the points,
# projected by Open CASCADE in FreeCAD, a subsample of 2000 points), and the RMS and max deviation
# of its surface from the true surface (200 x 200 samples in (u,v) whose (x, y) lies inside the
# data's rectangle, measured by fitsurf_bench --truth). fitsurf's surface reaches FreeCAD as STEP,
# so both are sampled by the same code.
#
# FreeCAD is a peer for this benchmark, never a dependency of photomill: without `freecadcmd`
# the script says so and exits 0 (Debian 12: apt-get install freecad; 0.20.2).
#   scripts/bench-fitsurf-freecad.sh [BUILD_DIR] [POINTS] [NET]
# Options of approxSurface through the environment: FC_SMOOTH (1), FC_WEIGHT (0.1), FC_GRAD (1.0),
# FC_BEND (0.0), FC_ITERATIONS (5) - its defaults; FC_SMOOTH=0 turns its smoothing off.
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build-fitsurf}
points=${2:-30000}
net=${3:-20}

if ! command -v freecadcmd >/dev/null 2>&1; then
  echo "bench-fitsurf-freecad: skipped: freecadcmd (FreeCAD) is not installed; it is only a peer" \
    "for this comparison (Debian: apt-get install freecad)" >&2
  exit 0
fi
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" --target fitsurf fitsurf_bench -j2 >/dev/null

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bench=$build/tools/bin/fitsurf_bench
"$bench" --write-cloud "$work/points.xyz" --points "$points" --shape bumps

echo "== machine: $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo "== load before: $(uptime)"
echo "== $points points, bumps, 0.01 mm noise, ${net}x${net} bicubic"

# fitsurf: its defaults (thin-plate smoothing 0.01 mm^4, parameter correction, outline) but the net.
t=$( { TIMEFORMAT='%R %U %S'; time "$build/bin/fitsurf" -q "$work/points.xyz" --net "${net}x${net}" \
       -o "$work/fitsurf.surf" --step "$work/fitsurf.step" --report "$work/fitsurf.json" 2>/dev/null; } 2>&1 )
read -r fs_wall fs_user fs_sys <<<"$t"

# FreeCAD: approxSurface with the same degree, net and points (centred, see fitsurf_freecad.py).
t0=$(date +%s.%N)
FC_POINTS=$work/points.xyz FC_OUT=$work/freecad.xyz FC_STEP=$work/fitsurf.step FC_STEP_OUT=$work/fitsurf.xyz \
  FC_NET=$net FC_DEGREE=3 QT_QPA_PLATFORM=offscreen \
  freecadcmd "$root/scripts/fitsurf_freecad.py" >"$work/freecad.log" 2>&1 || true
t1=$(date +%s.%N)
if ! grep -q '^RESULT freecad_wall_s' <(tr '\r\t' '\n\n' <"$work/freecad.log"); then
  echo "bench-fitsurf-freecad: FreeCAD failed:" >&2
  tail -20 "$work/freecad.log" >&2
  exit 1
fi
result() { tr '\r\t' '\n\n' <"$work/freecad.log" | sed -n "s/^.*RESULT $1 //p" | head -1; }

read -r fc_n fc_rms fc_max <<<"$("$bench" --truth "$work/freecad.xyz" --shape bumps)"
read -r fs_n fs_rms fs_max <<<"$("$bench" --truth "$work/fitsurf.xyz" --shape bumps)"
fs_res_rms=$(sed -n 's/.*"rms_mm": *\([0-9.eE+-]*\).*/\1/p' "$work/fitsurf.json" | head -1)

printf '%-34s %9s %9s %12s %12s %11s %11s\n' "fitter" "wall s" "cpu s" "resid RMS mm" "resid max mm" \
  "truth RMS" "truth max"
printf '%-34s %9s %9s %12s %12s %11s %11s\n' "fitsurf (defaults, --net ${net}x${net})" "$fs_wall" \
  "$(awk -v u="$fs_user" -v s="$fs_sys" 'BEGIN { print u + s }')" "$(result fitsurf_residual_rms_mm)" \
  "$(result fitsurf_residual_max_mm)" "$fs_rms" "$fs_max"
printf '%-34s %9s %9s %12s %12s %11s %11s\n' "FreeCAD approxSurface" "$(result freecad_wall_s)" \
  "$(result freecad_cpu_s)" "$(result freecad_residual_rms_mm)" "$(result freecad_residual_max_mm)" "$fc_rms" \
  "$fc_max"
echo "(fitsurf's own residual RMS over all points: $fs_res_rms mm; residuals in FreeCAD over" \
  "$(result residual_points) points; truth over $fs_n / $fc_n samples; FreeCAD's net" \
  "$(result freecad_poles), freecadcmd total $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s" \
  "with its start, sampling and projections)"
echo "== load after: $(uptime)"
