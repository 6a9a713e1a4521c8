#!/usr/bin/env bash
# clpost's dialects and arc fitting, measured (docs/measurements/toolpath.md): the lines of each
# dialect's program of the docs/formats.md example surface's finishing path (toolpath defaults),
# each read back by toolpath/gcode_check.py with its controller's word set; the same path and a
# z-level style CL (concentric circles at one Z, points spaced for a 0.005 mm chord error) with
# --arc-tol-mm: lines before and after, every CL point within the tolerance of the posted path;
# LinuxCNC's rs274 on the linuxcnc programs (when installed), with its run time.
# Usage: scripts/bench-clpost.sh [build-dir]
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
bin=$(cd "${1:-$src/build}" && pwd)/bin
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
check="python3 $src/toolpath/gcode_check.py"

sed -n '/^photomill-surface v1/,/^end$/p' "$src/docs/formats.md" >part.surf
"$bin/toolpath" -q --spindle-rpm 12000 part.surf -o part.cl
"$bin/toolpath" -q --format csv part.surf -o part.csv
# Circles r = 5, 10, ..., 40 mm about (0, 0) at Z -1, counter-clockwise, each point 2 sqrt(e (2 r - e))
# apart (chord error e = 0.005 mm), linked by straight feeds: the shape of a z-level contour.
python3 - >rings.csv <<'PY'
import math
e = 0.005
print("move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min")
print("rapid,5,0,10,,,,0")
print("feed,5,0,-1,,,,300")
for r in range(5, 45, 5):
    n = math.ceil(2 * math.pi / (2 * math.asin(math.sqrt(e * (2 * r - e)) / r)))
    print("feed,%.6f,0,-1,,,,1000" % r)
    for k in range(1, n + 1):
        a = 2 * math.pi * k / n
        print("feed,%.6f,%.6f,-1,,,,1000" % (r * math.cos(a), r * math.sin(a)))
print("rapid,40,0,10,,,,0")
PY
printf 'T1 P1 D6 Z0\n' >tool.tbl

echo "input            dialect   arc-tol  lines  arcs  est.min  gcode_check          rs274"
for input in part rings; do
  cl=$input.csv
  [ $input = part ] && cl=part.cl
  for dialect in generic linuxcnc grbl fanuc mach3; do
    for tol in off 0.005 0.01; do
      [ $tol != off ] && [ $dialect != linuxcnc ] && continue
      args=(--dialect $dialect --spindle-rpm 12000)
      [ $tol != off ] && args+=(--arc-tol-mm $tol)
      stats=$("$bin/clpost" -v "${args[@]}" "$cl" -o $input.ngc 2>&1 | tail -1)
      lines=$(wc -l <$input.ngc)
      arcs=$(grep -c '^G[23] ' $input.ngc || true)
      est=$(sed -n 's/.*estimated \([0-9.]*\) min.*/\1/p' <<<"$stats")
      read_tol=0.0001
      [ $dialect = fanuc ] && read_tol=0.0006
      check_args=(--dialect $dialect --tol $read_tol)
      [ $tol != off ] && check_args+=(--path-tol $tol)
      ok=$($check $input.ngc $input.csv "${check_args[@]}" | sed -n 's/.*at most \([0-9.]*\) mm.*/ok, max \1 mm/p; s/.*ok: .* word set$/ok/p')
      [ -n "$ok" ] || ok=FAIL
      rs=-
      if [ $dialect = linuxcnc ] && command -v rs274 >/dev/null; then
        t0=$(date +%s.%N)
        rs=$(rs274 -t tool.tbl -g $input.ngc canon.txt </dev/null >/dev/null 2>&1 && echo ok || echo FAIL)
        rs="$rs $(python3 -c "import sys; print('%.2f s' % (float(sys.argv[2]) - float(sys.argv[1])))" "$t0" "$(date +%s.%N)")"
      fi
      printf '%-16s %-9s %-8s %6s %5s %8s  %-19s  %s\n' $input $dialect $tol "$lines" "$arcs" "${est:--}" "$ok" "$rs"
    done
  done
done
