#!/usr/bin/env bash
# match's speed against a baseline build of match (issue #30: f50b565), side by side on the same
# inputs in one run: the demo and two other synth scenes (by default seed 2026's blended saddle
# and seed 2025's walled bumps, rendered as scripts/bench-parts.sh renders them), each through
# Makefile.example's chain up to match's inputs (markers, SIFT features, the markers' poses).
# Both binaries run Makefile.example's feature match with the options the baseline's
# Makefile.example gave (`--min-track-length 2 --flann-checks 16 --lsm-quadratic`, which
# `--preset features` now sets), alternately, `runs` times each; printed per scene: CPU (user +
# sys) of the faster run, peak RSS, track counts and the tracks' median and p99 error against
# the synth truth in the image (match_track_check).
# Usage: scripts/bench-match.sh [BUILD_DIR] [WORK_DIR] [BASELINE_COMMIT]
#   defaults: build, /tmp/photomill-bench-match, f50b565 (built once in WORK_DIR/baseline).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-build}" && pwd)
work=${2:-/tmp/photomill-bench-match}
baseline=${3:-f50b565}
runs=${PHOTOMILL_BENCH_RUNS:-2}
mkdir -p "$work"
work=$(cd "$work" && pwd)
cmake --build "$build" --target demo_tools synth match_track_check -j"$(nproc)" >/dev/null

# The baseline's match, built alone from a worktree of that commit.
base_src=$work/baseline
if [ ! -x "$base_src/build/bin/match" ]; then
  rm -rf "$base_src"
  git -C "$here" worktree add --force --detach "$base_src" "$baseline" >/dev/null 2>&1
  cmake -S "$base_src" -B "$base_src/build" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$base_src/build" --target match -j"$(nproc)" >/dev/null
fi
base_bin=$base_src/build/bin/match
[ "$(git -C "$base_src" rev-parse --short HEAD)" = "$(git -C "$here" rev-parse --short "$baseline")" ] ||
  { echo "bench-match: $base_src is not at $baseline" >&2; exit 1; }

# The scenes: name, synth folder, chain output folder.
scenes=("demo:$here/data/demo")
for s in ${PHOTOMILL_BENCH_SCENES:-2026:saddle:20 2025:bumps:0}; do
  IFS=: read -r seed shape blend <<<"$s"
  dir=$work/$seed-$shape-blend$blend
  if [ ! -f "$dir/scene.txt" ]; then
    "$build/tools/bin/synth" -o "$dir" --shape "$shape" --edge-blend-mm "$blend" --views 12 --calib-views 10 \
      --width 2000 --height 1500 --fx 2400 --supersampling 2 --noise-sigma 1.0 --jpeg-quality 85 \
      --speckle-mm 1.6 --surface-step-mm 2 --seed "$seed" -q
  fi
  scenes+=("$seed-$shape-blend$blend:$dir")
done

echo "machine: $(nproc) cores; load before: $(uptime | sed 's/.*load average/load average/')"
echo "baseline: $baseline ($base_bin); now: $(git -C "$here" rev-parse --short HEAD) ($build/bin/match)"
printf '%-22s %-9s %9s %9s %8s %8s %9s %9s\n' scene build "CPU s" "wall s" "RSS MB" tracks "median px" "p99 px"
for entry in "${scenes[@]}"; do
  name=${entry%%:*} dir=${entry#*:}
  out=$work/$name-out
  make -s -f "$here/Makefile.example" -j"$(nproc)" BIN="$build/bin" DEMO="$dir" OUT="$out" \
    "$out/observations.csv" "$out/markers/cloud.ply" >"$out.log" 2>&1 ||
    { echo "bench-match: the chain failed on $name (see $out.log)" >&2; exit 1; }
  declare -A cpu=() wall=() rss=()
  for _ in $(seq "$runs"); do
    for which in baseline now; do
      bin=$build/bin/match
      [ "$which" = baseline ] && bin=$base_bin
      /usr/bin/time -f '%U %S %e %M' -o "$work/time" "$bin" -q "$out/observations.csv" "$out"/feat/*.feat \
        --camera "$out/camera.yaml" --poses "$out/markers/poses.csv" --min-track-length 2 --flann-checks 16 \
        --lsm-quadratic -o "$work/$name-$which.csv"
      read -r u s w m < "$work/time"
      c=$(awk -v u="$u" -v s="$s" 'BEGIN { print u + s }')
      if [ -z "${cpu[$which]:-}" ] || awk -v a="$c" -v b="${cpu[$which]}" 'BEGIN { exit !(a < b) }'; then
        cpu[$which]=$c wall[$which]=$w rss[$which]=$((m / 1024))
      fi
    done
  done
  for which in baseline now; do
    check=$("$build/tools/bin/match_track_check" "$work/$name-$which.csv" --set "$dir" 2>&1)
    tracks=$(grep -v '^#' "$work/$name-$which.csv" | tail -n +2 | cut -d, -f1 | sort -u | wc -l)
    median=$(sed -n 's/^feature track error px: median \([^,]*\), .*/\1/p' <<<"$check")
    p99=$(sed -n 's/^feature track error px: .* p99 \(.*\)$/\1/p' <<<"$check")
    printf '%-22s %-9s %9.2f %9.2f %8s %8s %9.4f %9.4f\n' "$name" "$which" "${cpu[$which]}" "${wall[$which]}" \
      "${rss[$which]}" "$tracks" "$median" "$p99"
  done
  awk -v a="${cpu[now]}" -v b="${cpu[baseline]}" -v n="$name" 'BEGIN { printf "%-22s CPU now / baseline: %.3f\n", n, a / b }'
done
echo "load after: $(uptime | sed 's/.*load average/load average/')"
