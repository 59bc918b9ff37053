#!/usr/bin/env bash
# The test command: install dependencies, build, run every test (unit, golden-file,
# end-to-end on simulated data with known truth).  Exit code 0 only if all pass.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/build.sh" "$@"
build="${LPVID_BUILD_DIR:-$root/build}"
cd "$build"
ctest --output-on-failure -j"$(nproc)"
