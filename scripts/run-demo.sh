#!/usr/bin/env bash
# Runs Makefile.example on the bundled demo data with the binaries in $1 (default build/bin),
# stage by stage as far as the stages are built, and says plainly which are not built yet.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/bin}
out=out/demo

built=()
missing=()
for stage in calib detect match triangulate fitsurf toolpath; do
  if "$bin/$stage" 2>&1 >/dev/null </dev/null | grep -q "not built yet"; then
    missing+=("$stage")
  else
    built+=("$stage")
  fi
done

echo "photomill demo: binaries in $bin, outputs in $out" >&2
if [ ${#built[@]} -eq 0 ]; then
  echo "photomill demo: no stage is built yet (${missing[*]}: see the issues); nothing to run." >&2
  echo "photomill demo: the build and the formats library are in place; 'scripts/test.sh' runs the tests." >&2
  exit 0
fi
make -f Makefile.example BIN="$bin" OUT="$out" demo
