#!/usr/bin/env bash
# Every command-line option of the user tools is named in at least one test (issue 22): the long
# names given to CLI11's add_option/add_flag in the tools' sources (not their tests), each looked
# for, quoted, in the test sources (*_test.cpp, tests/). An option added without a test fails here
# with its name and where it is declared.
# Usage: options_named_test.sh SOURCE_DIR
set -euo pipefail
cd "$1"
tools=(calib detect match triangulate densify fitsurf toolpath report targets pick formats geometry)
mapfile -t sources < <(git ls-files -- "${tools[@]/%//*.cpp}" 2>/dev/null | grep -v '_test\.cpp$' ||
  find "${tools[@]}" -name '*.cpp' ! -name '*_test.cpp')
mapfile -t tests < <(git ls-files -- '*_test.cpp' 'tests/*' 2>/dev/null ||
  find . -name '*_test.cpp' -o -path './tests/*' -type f)
[ "${#sources[@]}" -gt 10 ] || { echo "options_named_test: found only ${#sources[@]} tool sources" >&2; exit 1; }

# "FILE:LINE:--name,..." for each add_option/add_flag whose names are on its first line.
corpus=$(mktemp)
trap 'rm -f "$corpus"' EXIT
cat "${tests[@]}" >"$corpus"
declared=$(grep -noE 'add_(option|flag)\("[^"]+"' "${sources[@]}" | sed -E 's/add_(option|flag)\("//; s/"$//')
count=0
missing=0
while IFS= read -r row; do
  where=${row%:*}
  IFS=',' read -r -a names <<<"${row##*:}"
  for name in "${names[@]}"; do
    name=${name#!}
    [[ $name == --* ]] || continue
    count=$((count + 1))
    if ! grep -qF -e "\"$name" "$corpus"; then
      echo "options_named_test: $where: $name is named in no test" >&2
      missing=$((missing + 1))
    fi
  done
done <<<"$declared"
[ "$count" -gt 150 ] || { echo "options_named_test: found only $count options: the extraction is broken" >&2; exit 1; }
echo "options_named_test: $count options, $missing named in no test"
[ "$missing" -eq 0 ]
