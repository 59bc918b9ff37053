#!/usr/bin/env bash
# The test command: install dependencies, build, run every test (unit, golden-file,
# end-to-end on simulated data with known truth).  Exit code 0 only if all pass.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Everything: the program, the tests, the benchmarks (compiled, not run).  Extra
# arguments go to CMake's configure step after these, so they can override them.
LPVID_DEPS="${LPVID_DEPS-tests}" bash "$root/scripts/build.sh" -DLPVID_BUILD_TESTS=ON -DLPVID_BUILD_BENCH=ON "$@"
build="${LPVID_BUILD_DIR:-$root/build}"
cd "$build"
ctest --output-on-failure -j"$(nproc)"
