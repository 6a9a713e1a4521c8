#!/usr/bin/env bash
# Installs photomill's build dependencies from Debian 12 packages; with --tests also what only
# the test suite runs (scripts/test.sh passes it; scripts/demo.sh does not).
# Idempotent: packages already present are left alone. Runs apt-get as root, or through sudo.
set -euo pipefail

packages=(
  build-essential cmake pkg-config python3 clang libclang-rt-14-dev
  libopencv-dev libopencv-contrib-dev
  libeigen3-dev libcli11-dev libgtest-dev libgmock-dev
  libceres-dev
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
  libocct-data-exchange-dev
)
if [ "${1:-}" = "--tests" ]; then
  packages+=(
    poppler-utils  # pdftoppm renders the targets' PDF (targets/targets_test.cpp)
    cloudcompare   # loads the walkthrough's cloud.ply (tests/walkthrough_test.sh)
    chromium       # opens the job's report.html headless (tests/report_browser_test.sh, walkthrough_test.sh)
    linuxcnc-uspace  # rs274, LinuxCNC's G-code interpreter standalone: runs clpost's linuxcnc dialect
                     # (toolpath/cli_test.cpp ClpostRs274; ~100 packages with their dependencies)
  )
  # npm installs playwright-core, which drives that Chromium (tests/browser; it downloads no
  # browser): Debian's nodejs and npm, unless a node with npm is there already.
  command -v npm >/dev/null || packages+=(nodejs npm)
fi

# playwright-core for the browser tests, pinned by tests/browser/package-lock.json.
browser_modules() {
  if [ "${1:-}" = "--tests" ] && [ ! -d "$browser_dir/node_modules/playwright-core" ]; then
    echo "install-deps: npm ci in tests/browser (playwright-core)" >&2
    (cd "$browser_dir" && npm ci --no-audit --no-fund --loglevel=error >&2)
  fi
}
browser_dir=$(cd "$(dirname "$0")/../tests/browser" && pwd)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed" >&2
  browser_modules "${1:-}"
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then sudo=(); else sudo=(sudo); fi
echo "install-deps: installing ${missing[*]}" >&2
"${sudo[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
browser_modules "${1:-}"
