#!/usr/bin/env bash
# fitsurf beside FreeCAD's approxSurface on a real range scan (issue #24): the Stanford bunny's
# bun000 body patch (../shared/data/README.md: x in [-0.07, 0.03], y in [0.06, 0.13] m, 19 661
# points, scaled to mm), nets of 8, 12, 20 (and 36, fitsurf only: FreeCAD takes minutes) poles per
# axis, both with their default options but the net. Both surfaces are judged by one piece of code:
# Open CASCADE's point projection in FreeCAD (scripts/fitsurf_freecad.py) gives the orthogonal
# distance of every point, rejected ones included. Prints one line per net: fitsurf's wall and
# CPU seconds, plane, rounds and RMS; FreeCAD's wall and CPU seconds and RMS; the CPU ratio.
#
# FreeCAD is a peer, never a dependency: without `freecadcmd` only fitsurf's side is printed.
#   scripts/bench-fitsurf-bunny.sh [BUILD_DIR]     (NETS="8 12 20 36" to choose the nets)
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
scan=${PHOTOMILL_SHARED_DIR:-$root/../shared}/data/stanford-bunny/bun000.ply
nets=${NETS:-8 12 20 36}
if [ ! -f "$scan" ]; then
  echo "bench-fitsurf-bunny: $scan not found" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The body patch in mm (the file's vertices, after its header, in metres; CRLF line ends).
tr -d '\r' <"$scan" | awk 'body && NF == 3 { if ($1 >= -0.07 && $1 <= 0.03 && $2 >= 0.06 && $2 <= 0.13)
  printf "%.6f %.6f %.6f\n", $1 * 1000, $2 * 1000, $3 * 1000 } /^end_header/ { body = 1 }' >"$work/patch.xyz"
points=$(wc -l <"$work/patch.xyz")
echo "== machine: $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
echo "== bun000 body patch: $points points; $(date -u +%Y-%m-%d)"
have_fc=1
command -v freecadcmd >/dev/null 2>&1 || { have_fc=0; echo "== freecadcmd not installed: fitsurf only"; }
printf '%-5s | %-9s %-8s %-6s %-7s %-11s | %-9s %-8s %-11s | %s\n' net fs_wall_s fs_cpu_s plane rounds fs_rms_mm \
  fc_wall_s fc_cpu_s fc_rms_mm cpu_fc/fs
for net in $nets; do
  t=$( { TIMEFORMAT='%R %U %S'; time "$build/bin/fitsurf" -q "$work/patch.xyz" --net "$net" -o "$work/s.surf" \
         --step "$work/s.step" --report "$work/s.json" 2>"$work/fs.log"; } 2>&1 ) || { cat "$work/fs.log" >&2; exit 1; }
  read -r fs_wall fs_user fs_sys <<<"$t"
  fs_cpu=$(echo "$fs_user + $fs_sys" | bc)
  read -r plane rounds own_rms <<<"$(python3 -c "import json,sys; d=json.load(open(sys.argv[1]))
print(d['surface']['parameter_plane'], len(d['fit']['round_rms_mm']), '%.5f' % d['residuals']['rms_mm'])" "$work/s.json")"
  fc_wall=- fc_cpu=- fc_rms=- ratio=- fs_rms=$own_rms
  if [ "$have_fc" = 1 ]; then
    net_fc=$net
    [ "$net" -gt 20 ] && net_fc=0  # FreeCAD at 36 takes many minutes: only fitsurf's STEP is judged
    FC_POINTS=$work/patch.xyz FC_OUT=$work/fc.xyz FC_STEP=$work/s.step FC_STEP_OUT=$work/fs.xyz \
      FC_NET=$([ "$net_fc" = 0 ] && echo 4 || echo "$net") FC_DEGREE=3 FC_RESIDUALS=$points FC_SAMPLES=2 \
      QT_QPA_PLATFORM=offscreen freecadcmd "$root/scripts/fitsurf_freecad.py" >"$work/fc.log" 2>&1 || true
    result() { tr '\r\t' '\n\n' <"$work/fc.log" | sed -n "s/^.*RESULT $1 //p" | head -1; }
    fs_rms=$(result fitsurf_residual_rms_mm)
    if [ "$net_fc" != 0 ]; then
      fc_wall=$(result freecad_wall_s)
      fc_cpu=$(result freecad_cpu_s)
      fc_rms=$(result freecad_residual_rms_mm)
      ratio=$(echo "scale=1; $fc_cpu / $fs_cpu" | bc)
    fi
  fi
  printf '%-5s | %-9s %-8s %-6s %-7s %-11s | %-9s %-8s %-11s | %s\n' "$net" "$fs_wall" "$fs_cpu" "$plane" "$rounds" \
    "$fs_rms" "$fc_wall" "$fc_cpu" "$fc_rms" "$ratio"
done
