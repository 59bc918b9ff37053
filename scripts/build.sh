#!/usr/bin/env bash
# Installs the dependencies (idempotent) and builds lpvid into build/ (program: build/lpvid).
# Extra arguments go to CMake's configure step, e.g. -DLPVID_SANITIZE=ON.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/install-deps.sh"
build="${LPVID_BUILD_DIR:-$root/build}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$build" -j"$(nproc)"
