#!/usr/bin/env bash
# densify against the sparse chain: for each scene, the default chain of Makefile.example (sparse:
# fitsurf fits cloud.ply), judged by synth_accuracy, then in the same output folder the DENSE=1
# chain (fitsurf fits densify's dense.ply; surface.txt and everything made after it removed first,
# so that only densify, fitsurf, toolpath, rough, clpost and report run again), judged again.
# Prints the load average at the start, then one table row per scene:
#   sparse_pts / dense_pts   densify_check's points_on_part of cloud.ply / dense.ply
#   cover%, d_rms, d_median  densify_check on dense.ply: coverage_percent (1 mm cells), rms_mm, median_mm
#   top%                     its top_coverage_percent: a walled part's 1 mm cells more than 2 mm inside its walls
#   dens_s, dens_cpu, dens_MB  densify alone (make's dense.ply target under /usr/bin/time):
#                            wall s, CPU s (user + system), peak resident MB
#   sp_*, dn_*               synth_accuracy on the sparse chain's and the dense chain's outputs:
#                            surface deviation RMS and max, tool path gouge max (mm)
#   sp_s, dn_s               wall s of the sparse chain and of the dense rerun (densify included)
# A chain whose make fails is noted (the figures then are those of what it left, "-" if none) and
# the script goes on; the logs are OUT.sparse.log, OUT.densify.log, OUT.dense.log beside OUT.
# Usage: scripts/bench-densify.sh [BUILD_DIR] [WORK_DIR] [SCENE ...]
#   BUILD_DIR: has bin/ (the tools) and tools/bin/ (synth, synth_accuracy, densify_check); default build
#   SCENE: demo (data/demo) or SEED:SHAPE:KIND, KIND blended (--edge-blend-mm 20) or walled (0),
#   rendered into WORK_DIR/SEED-SHAPE-KIND with scripts/bench-parts.sh's synth command (kept and
#   reused when its scene.txt exists); outputs in WORK_DIR/NAME-out (replaced).
#   default scenes: demo 2025:bumps:blended 2026:saddle:walled
#   e.g. scripts/bench-densify.sh build /tmp/photomill-densify demo 2027:wave:blended
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-build}" && pwd)
work=${2:-/tmp/photomill-densify}
shift $(( $# > 2 ? 2 : $# ))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(demo 2025:bumps:blended 2026:saddle:walled)
mkdir -p "$work"
work=$(cd "$work" && pwd)

echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg) ($(nproc) cores)"
fmt='%-22s %-10s %-10s %-7s %-7s %-8s %-8s %-7s %-8s %-7s %-8s %-8s %-8s %-8s %-8s %-8s %6s %6s  %s\n'
printf "$fmt" scene sparse_pts dense_pts cover% top% d_rms d_median dens_s dens_cpu dens_MB \
  sp_rms sp_max sp_gouge dn_rms dn_max dn_gouge sp_s dn_s notes

# One figure from densify_check's `name value` lines ("-" when absent).
check() { awk -v k="$1" '$1 == k { print $2; f = 1; exit } END { if (!f) print "-" }' <<<"$2"; }
# One figure from synth_accuracy's `name: value mm (bound ...)` lines ("-" when absent or not available).
acc_fig() { local v; v=$(sed -n "s/^$1: \([^ ]*\) .*/\1/p" <<<"$2" | head -1); [[ -z $v || $v == not ]] && v=-; echo "$v"; }
# The first error line of a make log: a tool's "error"/"failed" message, else make's own.
first_error() { { grep -iE 'error|fail|not built|cannot|No rule' "$1" || true; } | grep -v '^make.*Waiting' | head -1; }

for scene in "${scenes[@]}"; do
  if [ "$scene" = demo ]; then
    name=demo set_dir="$here/data/demo"
  else
    IFS=: read -r seed shape kind <<<"$scene"
    case "$kind" in
      blended) blend=20 ;;
      walled) blend=0 ;;
      *) echo "bench-densify: scene '$scene': KIND is blended or walled" >&2; exit 2 ;;
    esac
    name="$seed-$shape-$kind" set_dir="$work/$seed-$shape-$kind"
    if [ ! -f "$set_dir/scene.txt" ]; then
      "$build/tools/bin/synth" -o "$set_dir" --shape "$shape" --edge-blend-mm "$blend" --views 12 --calib-views 10 \
        --width 2000 --height 1500 --fx 2400 --supersampling 2 --noise-sigma 1.0 --jpeg-quality 85 \
        --speckle-mm 1.6 --surface-step-mm 2 --seed "$seed" -q
    fi
  fi
  out="$work/$name-out"
  mk=(make -s -f "$here/Makefile.example" -j2 BIN="$build/bin" DEMO="$set_dir" OUT="$out")
  notes=()
  rm -rf "$out"

  # 1. The sparse chain.
  start=$SECONDS
  "${mk[@]}" all >"$out.sparse.log" 2>&1 || notes+=("sparse: make failed: $(first_error "$out.sparse.log")")
  sp_s=$((SECONDS - start))
  sp_acc=$("$build/tools/bin/synth_accuracy" -v --truth "$set_dir" --outputs "$out" 2>&1 || true)
  sparse=$("$build/tools/bin/densify_check" --truth "$set_dir" "$out/cloud.ply" 2>/dev/null || true)

  # 2. The dense chain: what follows the cloud removed, densify timed alone, then the rest.
  rm -f "$out"/surface.* "$out"/path.* "$out/part.ngc" "$out"/rough.* "$out/report.html" \
    "$out/uncertainty.csv" "$out/fitsurf.json" "$out/toolpath.json"
  start=$SECONDS
  dens_s=- dens_cpu=- dens_mb=-
  if /usr/bin/time -f 'densify-time %e %U %S %M' -o "$out.densify.time" \
      "${mk[@]}" DENSE=1 "$out/dense.ply" >"$out.densify.log" 2>&1; then
    read -r _ e u s m <"$out.densify.time"
    dens_s=$e dens_cpu=$(awk -v u="$u" -v s="$s" 'BEGIN { printf "%.1f", u + s }') dens_mb=$((m / 1024))
    "${mk[@]}" DENSE=1 all >"$out.dense.log" 2>&1 || notes+=("dense: make failed: $(first_error "$out.dense.log")")
  else
    notes+=("densify failed: $(first_error "$out.densify.log")")
  fi
  dn_s=$((SECONDS - start))
  dn_acc=$("$build/tools/bin/synth_accuracy" -v --truth "$set_dir" --outputs "$out" 2>&1 || true)
  dense=$("$build/tools/bin/densify_check" --truth "$set_dir" "$out/dense.ply" 2>/dev/null || true)

  printf "$fmt" "$scene" "$(check points_on_part "$sparse")" "$(check points_on_part "$dense")" \
    "$(check coverage_percent "$dense" | cut -c1-6)" "$(check top_coverage_percent "$dense" | cut -c1-6)" "$(check rms_mm "$dense" | cut -c1-8)" \
    "$(check median_mm "$dense" | cut -c1-8)" "$dens_s" "$dens_cpu" "$dens_mb" \
    "$(acc_fig 'surface deviation RMS' "$sp_acc" | cut -c1-8)" "$(acc_fig 'surface deviation max' "$sp_acc" | cut -c1-8)" \
    "$(acc_fig 'tool path gouge max' "$sp_acc" | cut -c1-8)" \
    "$(acc_fig 'surface deviation RMS' "$dn_acc" | cut -c1-8)" "$(acc_fig 'surface deviation max' "$dn_acc" | cut -c1-8)" \
    "$(acc_fig 'tool path gouge max' "$dn_acc" | cut -c1-8)" "${sp_s}s" "${dn_s}s" \
    "$(IFS=';'; echo "${notes[*]:-ok}")"
done
