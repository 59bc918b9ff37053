#!/usr/bin/env bash
# Installs the dependencies (idempotent) and builds lpvid into build/ (program: build/lpvid).
# Extra arguments go to CMake's configure step, e.g. -DLPVID_SANITIZE=ON.
#   LPVID_BUILD_DIR      the build tree (default build/)
#   LPVID_BUILD_TARGETS  what to build, space-separated (default: everything configured)
#   LPVID_DEPS           the install-deps.sh sets to install (default "tests"; "" for the program's own)
# A new tree is generated for Ninja when it is installed (the base set installs it);
# an existing tree keeps its generator.  ccache is used when present (CMakeLists.txt).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC2086  # the sets are words
bash "$root/scripts/install-deps.sh" ${LPVID_DEPS-tests}
build="${LPVID_BUILD_DIR:-$root/build}"
gen=()
if [ ! -f "$build/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
cmake -S "$root" -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
targets=()
for t in ${LPVID_BUILD_TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$build" -j"$(nproc)" "${targets[@]}"
