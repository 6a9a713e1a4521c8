#!/usr/bin/env bash
# The default chain (Makefile.example, its documented PART_BOX) on synth parts other than the
# demo: for each seed, a blended part and a walled one (--edge-blend-mm 0), rendered with the
# demo's own synth command but the seed and shape, then judged by synth_accuracy against the
# truth. Prints one table row per scene (docs/measurements/parts.md); fitsurf writes its residual
# cloud (residuals.ply) so that `far_fit` can count the cloud points more than 1 mm off the true
# surface that reached the fit (issue 24's bound: 0).
# Usage: scripts/bench-parts.sh [BUILD_DIR] [WORK_DIR] [SEED:SHAPE ...]
#   default scenes: 2025:bumps 2026:saddle 2027:wave 2028:dome 2029:bumps
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-build}" && pwd)
work=${2:-/tmp/photomill-parts}
shift $(( $# > 2 ? 2 : $# ))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(2025:bumps 2026:saddle 2027:wave 2028:dome 2029:bumps)
kinds=${PHOTOMILL_PART_KINDS:-"walled blended"}
mkdir -p "$work"
printf '%-6s %-7s %-8s %-9s %-9s %-9s %-9s %-9s %-9s %-7s %7s  %s\n' seed shape kind top_rms top_max edge_max gouge left_p95 left_max far_fit "time" "fitsurf's walls"
for scene in "${scenes[@]}"; do
  seed=${scene%%:*} shape=${scene#*:}
  for kind in $kinds; do
    blend=20
    [ "$kind" = walled ] && blend=0
    set_dir="$work/$seed-$shape-$kind" out="$work/$seed-$shape-$kind-out"
    if [ ! -f "$set_dir/scene.txt" ]; then
      "$build/tools/bin/synth" -o "$set_dir" --shape "$shape" --edge-blend-mm "$blend" --views 12 --calib-views 10 \
        --width 2000 --height 1500 --fx 2400 --supersampling 2 --noise-sigma 1.0 --jpeg-quality 85 \
        --speckle-mm 1.6 --surface-step-mm 2 --seed "$seed" -q
    fi
    rm -rf "$out"
    start=$SECONDS
    status=ok
    make -s -f "$here/Makefile.example" -j2 BIN="$build/bin" DEMO="$set_dir" OUT="$out" \
      FITSURF="--residuals $out/residuals.ply" all >"$out.log" 2>&1 || status="make failed"
    took=$((SECONDS - start))
    acc=$("$build/tools/bin/synth_accuracy" -v --truth "$set_dir" --outputs "$out" 2>&1 || true)
    fig() { sed -n "s/^$1: \([^ ]*\) .*/\1/p" <<<"$acc" | head -1; }
    edge=$(sed -n 's/.*up to the walls: \([^ ]*\) mm.*/\1/p' <<<"$acc")
    walls=$(grep -o 'the part stands on walls[^:]*' "$out.log" | head -1 || true)
    [ "$status" = ok ] || walls="$status (see $out.log)"
    printf '%-6s %-7s %-8s %-9.8s %-9.8s %-9.8s %-9.8s %-9.8s %-9.8s %-7s %6ss  %s\n' "$seed" "$shape" "$kind" \
      "$(fig 'surface deviation RMS')" "$(fig 'surface deviation max')" "${edge:--}" \
      "$(fig 'tool path gouge max')" "$(fig 'tool path excess material p95')" "$(fig 'tool path excess material max')" \
      "$(fig 'cloud points over 1 mm off the truth in the fit')" "$took" "${walls:-none}"
  done
done
