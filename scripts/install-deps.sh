#!/usr/bin/env bash
# Installs lpvid's build and test dependencies from Debian 12 packages.
# Idempotent: does nothing (and needs no network) when everything is present.
# `install-deps.sh fuzz` also installs what the fuzz harnesses need (Debian's
# clang with its libFuzzer and sanitizer runtimes: scripts/fuzz.sh).
set -euo pipefail
pkgs=(
  build-essential cmake pkg-config
  libeigen3-dev libceres-dev libnlopt-cxx-dev libnlopt-dev
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libpng-dev
  libcli11-dev libfmt-dev nlohmann-json3-dev libfast-float-dev
  libfftw3-dev libmatio-dev zlib1g-dev libspectra-dev libopenblas-dev liblapacke-dev
  libgtest-dev libgmock-dev libbenchmark-dev fonts-dejavu-core
)
if [ "${1:-}" = "fuzz" ]; then
  pkgs+=(clang libclang-rt-14-dev)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
