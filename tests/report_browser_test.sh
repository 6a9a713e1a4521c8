#!/usr/bin/env bash
# ctest report_browser (issue 27): the demo's markers-only job (Makefile.example FEATURES=0, a few
# seconds) with its report.html, opened in Debian's headless Chromium through playwright-core
# (tests/browser/check_report.mjs): no console error, no request beyond the page, every picture
# decoded, the headline figures equal to the job's JSON reports. Skipped (exit 77) without
# Chromium or playwright-core (scripts/install-deps.sh --tests installs both), unless CI is set.
# Usage: report_browser_test.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -euo pipefail
src=$1 build=$2 work=$3
fail() { echo "report_browser_test: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
command -v node >/dev/null || {
  [ -z "${CI:-}" ] || fail "no node (CI is set: the browser check must run)"
  echo "report_browser_test: skipped: no node (scripts/install-deps.sh --tests installs it)" >&2
  exit 77
}
job=$work/job
make -s -f "$src/Makefile.example" BIN="$build/bin" FEATURES=0 OUT="$job" report >"$work/make.log" 2>&1 ||
  { tail -20 "$work/make.log" >&2; fail "the markers-only demo job failed (its log above)"; }
[ -s "$job/report.html" ] || fail "make report wrote no $job/report.html"
node "$src/tests/browser/check_report.mjs" "$job/report.html" "$job"
