# Sourced by the benchmarks (bench-colmap-pipeline.sh, bench-sceaux.sh).
# timed CMD...: runs CMD, adds its wall and CPU (user + sys) seconds to $wall and $cpu (the
# caller's $work holds the time file). CPU time is the fairer figure when the machine is
# shared; both are printed. figures: the two so far, as text.
wall=0
cpu=0
timed() {
  /usr/bin/time -f '%e %U %S' -o "$work/time" "$@"
  read -r w u s < <(tail -n 1 "$work/time")
  wall=$(awk -v a="$wall" -v b="$w" 'BEGIN { print a + b }')
  cpu=$(awk -v a="$cpu" -v b="$u" -v c="$s" 'BEGIN { print a + b + c }')
}
figures() { printf 'wall %.1f s, CPU %.1f s' "$wall" "$cpu"; }
